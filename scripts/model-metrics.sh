#!/usr/bin/env bash
# The model card's headline table for one model: the withheld synthetic
# frames, the real full frames and the real crops, one row each, then the
# synthetic calibration sets that are on disk (calib-s700001,
# calib-s700003-late, the season-wide one, and whorl-s700005, young maize
# with crowded tops, under $CALIB_ROOT).
# Usage: scripts/model-metrics.sh [MODEL] [TEST_DATASET]
#   MODEL         default models/phyllo.onnx
#   TEST_DATASET  default /work/data/test-s900002 (scripts/make-eval-sets.sh
#                 renders it and the calibration sets); a set with top views
#                 (test-e40-s900301, the paper's protocol) also gets a side-view
#                 and a top-view row
# TOP_MODEL: the model that counts top views, default models/phyllo-top.onnx
#   (the shipped pair); `none` counts them with MODEL too.
# Real data: $PHYLLO_DEV_DATA, default ../shared/data/unl-maize-dev.
# CALIB_ROOT: default /work/data; CALIB_SETS="" leaves the calibration rows out.
# EXTRA: more phyllo eval arguments for every row (e.g. the settings before a
#   change: EXTRA="--zoom-height-measure all --zoom-height 480").
# The real rows come whole and split by experiment (81-* 2018, zoomed in;
#   402-* 2019), each with 95 % intervals; they are reported, never chosen by.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
model=${1:-$root/models/phyllo.onnx}
test=${2:-/work/data/test-s900002}
dev=${PHYLLO_DEV_DATA:-$root/../shared/data/unl-maize-dev}
bin=$root/target/release/phyllo
top=${TOP_MODEL:-$root/models/phyllo-top.onnx}
[ "$top" = none ] || [ -e "$top" ] || { echo "model-metrics: no top-view model $top (TOP_MODEL=none counts top views with $model)" >&2; exit 2; }
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
sets=$root/models/eval-sets.tsv
eval_json=$root/scripts/eval_json.py
rows=()
intervals=()
row() { # label, key in models/eval-sets.tsv, then phyllo eval arguments
  local label=$1 key=$2
  shift 2
  local out got want check
  # shellcheck disable=SC2086 # EXTRA is a list of arguments
  out=$("$bin" eval --threads "${THREADS:-2}" --model "$model" --top-model "$top" --json ${EXTRA:-} "$@" 2>/dev/null)
  got=$("$eval_json" field fingerprint <<<"$out")
  want=$(awk -F'\t' -v k="$key" '$1 == k {print $2; exit}' "$sets")
  if [ "$key" = - ]; then check="$got (part of the row above)"
  elif [ "$got" = "$want" ]; then check="$got (as recorded)"
  else check="$got (DIFFERS from ${want:-nothing recorded}: not comparable with models/MODEL.md)"; fi
  model_id=$("$eval_json" field model <<<"$out")
  rows+=("$("$eval_json" row "$label" "$check" <<<"$out")")
  intervals+=("$("$eval_json" intervals "$label" <<<"$out")")
  if [ "$key" = "$(basename "$test")/$test_split" ] && grep -q '"view":"top"' "$test/manifest.jsonl"; then
    for part in side top; do
      both=$("$eval_json" subset "  $part views" "$part" <<<"$out")
      rows+=("$(head -1 <<<"$both") |")
      intervals+=("$(tail -1 <<<"$both")")
    done
  fi
}
# The split models/eval-sets.tsv records for the set (`all` for sets rendered whole).
test_split=val
if grep -q "^$(basename "$test")/all"$'\t' "$sets"; then test_split=all; fi
row "synthetic frames, $(basename "$test")" "$(basename "$test")/$test_split" --dataset "$test" --split $test_split --per-image
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for csv in leaf_tips crops_counts; do
  for exp in 81 402; do
    { head -1 "$dev/$csv.csv"; grep "^$exp-" "$dev/$csv.csv" || true; } >"$tmp/$csv-$exp.csv"
  done
done
row "real full frames" real-frames --counts "$dev/leaf_tips.csv" --images "$dev/images"
for exp in 81 402; do row "  frames $exp-*" - --counts "$tmp/leaf_tips-$exp.csv" --images "$dev/images"; done
row "real crops" real-crops --counts "$dev/crops_counts.csv" --images "$dev/crops"
for exp in 81 402; do row "  crops $exp-*" - --counts "$tmp/crops_counts-$exp.csv" --images "$dev/crops"; done
for set in ${CALIB_SETS-calib-s700001 calib-s700003-late whorl-s700005}; do
  if [ -e "${CALIB_ROOT:-/work/data}/$set/manifest.jsonl" ]; then
    row "$set (calibration only)" "$set/all" --dataset "${CALIB_ROOT:-/work/data}/$set" --split all
  else
    echo "model-metrics: ${CALIB_ROOT:-/work/data}/$set not rendered (scripts/make-eval-sets.sh $set): row left out" >&2
  fi
done
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
