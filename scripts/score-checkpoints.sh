#!/usr/bin/env bash
# Scores a training run's course: exports each kept checkpoint
# (train.py --keep-every N writes RUN_DIR/step-NNNNNN.pt), plus an optional
# starting checkpoint, and counts a phyllo-gen dataset with each, one table row
# per checkpoint. Use a calibration set (models/MODEL.md), never the withheld
# test set, to choose a checkpoint.
# Usage: scripts/score-checkpoints.sh RUN_DIR DATASET [START_CHECKPOINT]
# Checkpoints already scored are not exported again (RUN_DIR/scored/).
# THRESHOLDS="0.2 0.3" scores each checkpoint at each centre threshold (default:
# the contract's only). Fine-tuning lowers the centre peaks, so a checkpoint
# judged at the threshold calibrated for another model looks worse than it
# counts (models/EXPERIMENTS.md, "The centre loss and the count").
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
usage="usage: score-checkpoints.sh RUN_DIR DATASET [START_CHECKPOINT]"
run=$(cd "${1:?$usage}" && pwd)
data=${2:?$usage}
start=${3:-}
py=${PYTHON:-$root/models/.venv/bin/python}
bin=$root/target/release/phyllo
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
mkdir -p "$run/scored"
echo "| checkpoint | images | exact | within ±1 | RMSE | MAE | bias | R² |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for ck in $start "$run"/step-*.pt; do
  [ -e "$ck" ] || continue
  name=$(basename "$(dirname "$ck")")-$(basename "$ck" .pt)
  onnx=$run/scored/$name.onnx
  if [ ! -e "$onnx" ]; then
    (cd "$root/models" && "$py" -m phyllo_train.export --checkpoint "$ck" --out "$onnx" --name "$name" >/dev/null)
  fi
  for t in ${THRESHOLDS:-contract}; do
    if [ "$t" = contract ]; then args=(); label=$name; else args=(--center-threshold "$t"); label="$name @ $t"; fi
    "$bin" eval --threads "${THREADS:-2}" --model "$onnx" --dataset "$data" --split all --json "${args[@]}" 2>/dev/null |
      "$root/scripts/eval_json.py" row "$label"
  done
done
