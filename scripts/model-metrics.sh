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
row() { # label, then phyllo eval arguments
  local label=$1
  shift
  local out
  out=$("$bin" eval --threads "${THREADS:-2}" --model "$model" "$@" 2>/dev/null)
  echo "$out" | awk -v l="$label" '/^\| images/ {getline; getline; sub(/^\|/, ""); print "| " l " |" $0; exit}'
}
echo "model: $("$bin" eval --threads 1 --model "$model" --counts "$dev/leaf_tips.csv" --images "$dev/images" 2>/dev/null | awk '/^model/ {print $2; exit}')"
echo
echo "| set | n | exact | within ±1 | RMSE | MAE | bias | R² |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
row "synthetic frames, $(basename "$test")" --dataset "$test" --split val
row "real full frames" --counts "$dev/leaf_tips.csv" --images "$dev/images"
row "real crops" --counts "$dev/crops_counts.csv" --images "$dev/crops"
