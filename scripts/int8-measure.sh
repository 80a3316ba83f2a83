#!/usr/bin/env bash
# int8 or float32 (issue 59): quantises the shipped side- and top-view models
# (ONNX Runtime's static quantisation, per-channel, calibrated on synthetic
# frames of seeds that measure nothing), then measures, side by side in one
# run:
#   - how many counts change, and each model's agreement with the truth, on
#     the synthetic calibration sets (calib-s700001 side views,
#     calib-top-s700301 top views) and the real dev sets split by experiment;
#   - CPU time per tile on x86 (count --json over the real frames, the two
#     models alternating), and under qemu-aarch64 with EMULATED=1 (the tree
#     scripts/build-aarch64.sh leaves in out/aarch64; slow: emulated).
#
#   scripts/int8-measure.sh [OUT]        (default out/int8: the int8 models)
#
# PYTHON: an interpreter with onnx, onnxruntime, numpy and pillow (default
# models/.venv/bin/python, which ./scripts/test.sh makes; a relative path is
# taken from the repository root). DATA_ROOT: where the quantisation's own
# calibration frames are rendered (default /work/data; the measurement sets go
# where models/eval-sets.tsv says). PHYLLO_DEV_DATA: the real sets (default
# ../shared/data/unl-maize-dev).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
out=$(realpath -m "${1:-out/int8}")
py=${PYTHON:-$root/models/.venv/bin/python}
# The quantiser runs from models/: a relative path must still lead to it.
[[ $py != */* || $py == /* ]] || py=$PWD/$py
data=${DATA_ROOT:-/work/data}
dev=${PHYLLO_DEV_DATA:-$root/../shared/data/unl-maize-dev}
presets=btx623,pawaga,rtx430,sc301,tx3197,maize:1.7
cargo build -q --release --locked -p phyllo -p phyllo-gen
bin=target/release/phyllo
gen=target/release/phyllo-gen
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "== synthetic sets"
render() { # dir, then phyllo-gen dataset arguments
  local dir=$1
  shift
  [ -e "$dir/manifest.jsonl" ] || "$gen" dataset --out "$dir" --val-fraction 1.0 --zoom 1 --quiet "$@"
}
render "$data/int8-calib-s700901" --plants 16 --seed 700901 --views 0,72 --full-frame --preset "$presets"
render "$data/int8-calib-top-s700902" --plants 32 --seed 700902 --views top --size 512 --preset "$presets,maize-whorl:1"
# The measurement sets, rendered as models/eval-sets.tsv records them and
# checked against their recorded fingerprints.
scripts/make-eval-sets.sh --check calib-s700001 calib-top-s700301

echo "== quantise (PYTHON=$py)"
for m in phyllo phyllo-top; do
  frames=$data/int8-calib-s700901/images
  [ "$m" = phyllo ] || frames=$data/int8-calib-top-s700902/images
  if ! (cd models && "$py" -m phyllo_train.tools.quantize "$m.onnx" --frames "$frames" --out "$out/$m-int8.onnx" >"$tmp/q.log" 2>&1); then
    cat "$tmp/q.log"
    exit 1
  fi
  grep '^wrote' "$tmp/q.log"
done

echo "== counts, float32 against int8"
ev() { "$bin" eval --per-image "$@" 2>/dev/null; }
side32=models/phyllo.onnx side8=$out/phyllo-int8.onnx
top32=models/phyllo-top.onnx top8=$out/phyllo-top-int8.onnx
ev --model $side32 --top-model none --dataset /work/data/calib-s700001 --split all >"$tmp/s32"
ev --model "$side8" --top-model none --dataset /work/data/calib-s700001 --split all >"$tmp/s8"
ev --model $side32 --top-model $top32 --dataset /work/data/calib-top-s700301 --split all >"$tmp/t32"
ev --model $side32 --top-model "$top8" --dataset /work/data/calib-top-s700301 --split all >"$tmp/t8"
for m in 32 8; do
  model=$side32
  [ $m = 32 ] || model=$side8
  ev --model "$model" --top-model none --counts "$dev/leaf_tips.csv" --images "$dev/images" >"$tmp/f$m"
  ev --model "$model" --top-model none --counts "$dev/crops_counts.csv" --images "$dev/crops" >"$tmp/c$m"
done
echo "| set | images | counts changed | float32: exact [95 %] / ±1 / RMSE / bias | int8: exact [95 %] / ±1 / RMSE / bias | closer to truth (f32 / int8), sign test |"
echo "|---|---:|---:|---|---|---|"
python3 scripts/compare_counts.py "calib-s700001 (side, synthetic)" "$tmp/s32" "$tmp/s8"
python3 scripts/compare_counts.py "calib-top-s700301 (top, synthetic)" "$tmp/t32" "$tmp/t8"
python3 scripts/compare_counts.py "real full frames" "$tmp/f32" "$tmp/f8" --split
python3 scripts/compare_counts.py "real crops" "$tmp/c32" "$tmp/c8" --split

echo
echo "== CPU time per tile, side-view model (count --json: inference ms / tiles; the two alternate)"
frames=("$dev"/images/*.jpg)
echo "| machine | model | tiles | inference per tile | pipeline per image | per tile vs float32 |"
echo "|---|---|---|---:|---:|---:|"
python3 scripts/time_models.py --label "x86-64 ($(nproc) cores)" --rounds 3 \
  --model float32=$side32 --model int8="$side8" -- "$bin" -- "${frames[@]}"
if [ "${EMULATED:-0}" = 1 ]; then
  python3 scripts/time_models.py --label "aarch64 under qemu-aarch64 (emulated)" --rounds 1 \
    --model float32=$side32 --model int8="$side8" -- qemu-aarch64 -L /usr/aarch64-linux-gnu out/aarch64/bin/phyllo -- \
    docs/samples/*.jpg
fi
