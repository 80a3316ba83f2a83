#!/usr/bin/env bash
# Counts of one or more models, side by side, on a synthetic set under the
# paper's protocol split into side and top views, and on the real dev frames
# and crops split by experiment (81-* 2018, zoomed in; 402-* 2019), each row
# with its 95 % intervals. Synthetic rows choose; real rows are reported only.
# Usage: scripts/score-by-group.sh DATASET MODEL.onnx [MODEL.onnx ...]
#   DATASET: a phyllo-gen dataset (every split is counted), e.g.
#            /work/data/calib-e40-s700101 (models/eval-sets.tsv)
# Environment: THREADS [2], PHYLLO_DEV_DATA [../shared/data/unl-maize-dev],
#   REAL [1; 0 leaves the real rows out], EXTRA [more phyllo eval arguments],
#   PHYLLO_BIN [a phyllo binary to use instead of building target/release/phyllo].
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
[ $# -ge 2 ] || { sed -n '2,12p' "$0"; exit 2; }
data=$(realpath "$1")
shift
dev=${PHYLLO_DEV_DATA:-$root/../shared/data/unl-maize-dev}
bin=${PHYLLO_BIN:-$root/target/release/phyllo}
[ -n "${PHYLLO_BIN:-}" ] || cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
ej=$root/scripts/eval_json.py
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# The real sets by experiment: the CSV's header and the rows of one plant-id prefix.
for exp in 81 402; do
  for csv in leaf_tips crops_counts; do
    { head -1 "$dev/$csv.csv"; grep "^$exp-" "$dev/$csv.csv" || true; } >"$tmp/$csv-$exp.csv"
  done
done

rows=() intervals=()
add() { # label, then phyllo eval arguments
  local label=$1 out
  shift
  out=$("$bin" eval --threads "${THREADS:-2}" --json ${EXTRA:-} "$@" 2>/dev/null) || { rows+=("| $label | failed |"); return; }
  rows+=("$("$ej" row "$label" <<<"$out")")
  intervals+=("$("$ej" intervals "$label" <<<"$out")")
}
for model in "$@"; do
  m=$(basename "$model" .onnx)
  # One run over the synthetic set; its side and top views are scored from the per-image counts.
  out=$("$bin" eval --threads "${THREADS:-2}" --json --per-image ${EXTRA:-} --model "$model" --dataset "$data" \
    --split all 2>/dev/null) || { rows+=("| $m: $(basename "$data") | failed |"); continue; }
  rows+=("$("$ej" row "$m: $(basename "$data") all" <<<"$out")")
  intervals+=("$("$ej" intervals "$m: $(basename "$data") all" <<<"$out")")
  for part in side top; do
    both=$("$ej" subset "$m: $part views" "$part" <<<"$out")
    rows+=("$(head -1 <<<"$both")")
    intervals+=("$(tail -1 <<<"$both")")
  done
  if [ "${REAL:-1}" = 1 ]; then
    for exp in 81 402; do
      add "$m: real frames $exp-*" --model "$model" --counts "$tmp/leaf_tips-$exp.csv" --images "$dev/images"
      add "$m: real crops $exp-*" --model "$model" --counts "$tmp/crops_counts-$exp.csv" --images "$dev/crops"
    done
  fi
done
echo "| set | n | exact | within ±1 | RMSE | MAE | bias | R² |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
printf '%s\n' "${rows[@]}"
echo
echo "95 % intervals (Wilson for exact and ±1; bootstrap over images for RMSE and bias):"
echo
echo "| set | exact | within ±1 | RMSE | bias |"
echo "|---|---|---|---|---|"
printf '%s\n' "${intervals[@]}"
