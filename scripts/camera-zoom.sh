#!/usr/bin/env bash
# The camera zoom measured on the chamber's back panel (issue 41), and what
# it does to the counts.
#   1. every dev frame's panel width at the contract's frame scale (model px)
#      and the zoom phyllo takes from it;
#   2. synthetic whole frames at zoom 1 and 2 (phyllo-gen dataset --full-frame
#      --zoom Z, rendered when missing): how often the panel is found and how
#      near the measured zoom is to the true one, then the counts with the
#      contract's scale rule and with the measured zoom;
#   3. the real dev frames by experiment with either rule (crops carry no
#      panel: the measurement leaves them alone).
# Usage: scripts/camera-zoom.sh [MODEL.onnx]   (default models/phyllo.onnx)
# Environment: DATA [/work/data], PHYLLO_DEV_DATA [../shared/data/unl-maize-dev],
#   PHYLLO_BIN / PHYLLO_GEN_BIN [binaries to use instead of building them].
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
model=${1:-$root/models/phyllo.onnx}
data=${DATA:-/work/data}
dev=${PHYLLO_DEV_DATA:-$root/../shared/data/unl-maize-dev}
bin=${PHYLLO_BIN:-$root/target/release/phyllo}
gen=${PHYLLO_GEN_BIN:-$root/target/release/phyllo-gen}
[ -n "${PHYLLO_BIN:-}" ] || cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
[ -n "${PHYLLO_GEN_BIN:-}" ] || cargo build -q --release -p phyllo-gen --manifest-path "$root/Cargo.toml"
ej=$root/scripts/eval_json.py
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Prints "count  median  p10  p90  share within 5 % of TRUE" of the measured
# zooms in `phyllo count --json` lines, and how many fell back.
summarise() {
  python3 -c '
import json, sys
true = float(sys.argv[1])
zs, fell = [], 0
for line in sys.stdin:
    c = json.loads(line).get("camera") or {}
    if c.get("source") == "back-panel":
        zs.append(c["camera_zoom"])
    else:
        fell += 1
zs.sort()
n = len(zs)
if n:
    near = sum(abs(z / true - 1) < 0.05 for z in zs)
    print(f"| {true:g} | {n} of {n + fell} | {zs[n // 2]:.3f} | {zs[n // 10]:.3f} | {zs[9 * n // 10]:.3f} | {near} |")
else:
    print(f"| {true:g} | 0 of {fell} | | | | |")
' "$1"
}

echo "## Dev frames: back panel and zoom"
echo
echo "| frame | panel width (model px at the contract scale) | camera zoom |"
echo "|---|---:|---:|"
"$bin" count --json --threads 2 --model "$model" "$dev"/images/*.jpg 2>/dev/null | python3 -c '
import json, sys
for line in sys.stdin:
    v = json.loads(line)
    c = v.get("camera") or {}
    p = c.get("panel")
    h = v["image_size"][1]
    width = f"{(p['"'"'right'"'"'] - p['"'"'left'"'"']) * 514 / h:.1f}" if p else "not found"
    print(f"| {v['"'"'file'"'"'].rsplit('"'"'/'"'"', 1)[-1][:40]} | {width} | {c.get('"'"'camera_zoom'"'"', 1):.3f} |")
'
echo
echo "## Synthetic whole frames: the zoom measured"
echo
echo "| true zoom | panel found | median | 10th pct | 90th pct | within 5 % |"
echo "|---:|---|---:|---:|---:|---:|"
for z in 1 2; do
  set_dir=$data/zoom$z-s700201
  [ -f "$set_dir/manifest.jsonl" ] || "$gen" dataset --out "$set_dir" --plants 80 --seed 700201 --views 108 \
    --full-frame --val-fraction 1.0 --preset btx623,pawaga,rtx430,sc301,tx3197,maize:1.7 --zoom $z --quiet
  "$bin" count --json --threads 2 --model "$model" "$set_dir"/images/*.png 2>/dev/null | summarise $z
done
echo
echo "## Counts: the contract's scale rule against the measured zoom"
echo
echo "| set | images | exact | within ±1 | RMSE | MAE | bias | R² |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for z in 1 2; do
  for rule in contract measure; do
    "$bin" eval --model "$model" --dataset "$data/zoom$z-s700201" --split all --camera-zoom $rule --json 2>/dev/null \
      | python3 "$ej" row "synthetic zoom $z, $rule"
  done
done
for exp in 81 402; do
  for csv in leaf_tips crops_counts; do
    { head -1 "$dev/$csv.csv"; grep "^$exp-" "$dev/$csv.csv" || true; } >"$tmp/$csv-$exp.csv"
  done
  for rule in contract measure; do
    "$bin" eval --model "$model" --counts "$tmp/leaf_tips-$exp.csv" --images "$dev/images" --camera-zoom $rule \
      --json 2>/dev/null | python3 "$ej" row "real frames $exp-*, $rule"
  done
done
