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
row() { # label, key in models/eval-sets.tsv, then phyllo eval arguments
  local label=$1 key=$2
  shift 2
  local out got want check
  out=$("$bin" eval --threads "${THREADS:-2}" --model "$model" "$@" 2>/dev/null)
  got=$(echo "$out" | awk '/^data / {print $2; exit}')
  want=$(awk -F'\t' -v k="$key" '$1 == k {print $2; exit}' "$sets")
  if [ "$got" = "$want" ]; then check="$got (as recorded)"; else check="$got (DIFFERS from ${want:-nothing recorded}: not comparable with models/MODEL.md)"; fi
  echo "$out" | awk -v l="$label" -v c="$check" '/^\| images/ {getline; getline; sub(/^\|/, ""); print "| " l " |" $0 " " c " |"; exit}'
  intervals+=("$(echo "$out" | sed -n 's/^95 % intervals[^:]*: exact \([^;]*\); within ±1 \([^;]*\); RMSE \([^;]*\); MAE [^;]*; bias \(.*\)$/| '"$label"' | \1 | \2 | \3 | \4 |/p')")
}
intervals=()
echo "model: $("$bin" eval --threads 1 --model "$model" --counts "$dev/leaf_tips.csv" --images "$dev/images" 2>/dev/null | awk '/^model/ {print $2; exit}')"
echo
echo "| set | n | exact | within ±1 | RMSE | MAE | bias | R² | data (models/eval-sets.tsv) |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---|"
row "synthetic frames, $(basename "$test")" "$(basename "$test")/val" --dataset "$test" --split val
row "real full frames" real-frames --counts "$dev/leaf_tips.csv" --images "$dev/images"
row "real crops" real-crops --counts "$dev/crops_counts.csv" --images "$dev/crops"
echo
echo "95 % intervals (Wilson for exact and ±1; bootstrap over images for RMSE and bias; printed by phyllo eval):"
echo
echo "| set | exact | within ±1 | RMSE | bias |"
echo "|---|---|---|---|---|"
printf '%s\n' "${intervals[@]}"
