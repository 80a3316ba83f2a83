#!/usr/bin/env bash
# The model card's headline table for one model: the withheld synthetic
# frames, the real full frames and the real crops, one row each.
# Usage: scripts/model-metrics.sh [MODEL] [TEST_DATASET]
#   MODEL         default models/phyllo.onnx
#   TEST_DATASET  default /work/data/test-s900002 (see models/MODEL.md for the
#                 phyllo-gen command that makes it)
# Real data: $PHYLLO_DEV_DATA, default ../shared/data/unl-maize-dev.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
model=${1:-$root/models/phyllo.onnx}
test=${2:-/work/data/test-s900002}
dev=${PHYLLO_DEV_DATA:-$root/../shared/data/unl-maize-dev}
bin=$root/target/release/phyllo
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
sets=$root/models/eval-sets.tsv
eval_json=$root/scripts/eval_json.py
rows=()
intervals=()
row() { # label, key in models/eval-sets.tsv, then phyllo eval arguments
  local label=$1 key=$2
  shift 2
  local out got want check
  out=$("$bin" eval --threads "${THREADS:-2}" --model "$model" --json "$@" 2>/dev/null)
  got=$("$eval_json" field fingerprint <<<"$out")
  want=$(awk -F'\t' -v k="$key" '$1 == k {print $2; exit}' "$sets")
  if [ "$got" = "$want" ]; then check="$got (as recorded)"; else check="$got (DIFFERS from ${want:-nothing recorded}: not comparable with models/MODEL.md)"; fi
  model_id=$("$eval_json" field model <<<"$out")
  rows+=("$("$eval_json" row "$label" "$check" <<<"$out")")
  intervals+=("$("$eval_json" intervals "$label" <<<"$out")")
}
row "synthetic frames, $(basename "$test")" "$(basename "$test")/val" --dataset "$test" --split val
row "real full frames" real-frames --counts "$dev/leaf_tips.csv" --images "$dev/images"
row "real crops" real-crops --counts "$dev/crops_counts.csv" --images "$dev/crops"
echo "model: $model_id"
echo
echo "| set | n | exact | within ±1 | RMSE | MAE | bias | R² | data (models/eval-sets.tsv) |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---|"
printf '%s\n' "${rows[@]}"
echo
echo "95 % intervals (Wilson for exact and ±1; bootstrap over images for RMSE and bias; printed by phyllo eval):"
echo
echo "| set | exact | within ±1 | RMSE | bias |"
echo "|---|---|---|---|---|"
printf '%s\n' "${intervals[@]}"
