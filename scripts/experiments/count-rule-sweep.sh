#!/usr/bin/env bash
# Counts one evaluation set under each count rule (centres, split, tips) and
# tip threshold, one table row each: exact / within one / RMSE / MAE / bias / R².
# Only a model with a `tip` output counts differently under the rules.
# Calibrate on a synthetic set used neither for training nor for testing
# (models/MODEL.md names it), never on the real dev images.
# Usage: scripts/experiments/count-rule-sweep.sh MODEL "RULES" "TIP_THRESHOLDS" EVAL_ARGS...
#   e.g. scripts/experiments/count-rule-sweep.sh models/phyllo.onnx "centres split tips" "0.3 0.5" \
#          --dataset /work/data/calib-s700001 --split all
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
model=${1:?usage: count-rule-sweep.sh MODEL RULES TIP_THRESHOLDS EVAL_ARGS...}
rules=${2:?rules}
thresholds=${3:?tip thresholds}
shift 3
bin=$root/target/release/phyllo
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
echo "| count rule | tip threshold | images | exact | within ±1 | RMSE | MAE | bias | R² |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
for r in $rules; do
  for t in $thresholds; do
    "$bin" eval --threads "${THREADS:-2}" --model "$model" --json --count-rule "$r" --tip-threshold "$t" "$@" 2>/dev/null |
      "$root/scripts/eval_json.py" row "$r | $t"
    # The centres rule ignores the tip threshold: one row is enough.
    if [ "$r" = centres ]; then break; fi
  done
done
