#!/usr/bin/env bash
# Every count rule and the tip tables for one model with a tip output, on the
# calibration set, the real frames and crops, and the tip sets' val splits.
# Usage: scripts/experiments/score-tip-model.sh MODEL.onnx [TAG]
#   writes /tmp/{calib,frames,crops,val}-TAG.jsonl (phyllo count --json) and
#   prints count_rules (calibration, real frames, real crops) and tip_match
#   (real frames, tips-s31 and tips-s32 val) tables.
# Data: CALIB [/work/data/calib-s700001], TIPS_SETS ["/work/data/tips-s31 /work/data/tips-s32"],
#   PHYLLO_DEV_DATA [../shared/data/unl-maize-dev]; models/EXPERIMENTS.md ("Leaf tips") has the
#   phyllo-gen commands that make them.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
model=$(realpath "$1"); tag=${2:-$(basename "$1" .onnx)}
calib=${CALIB:-/work/data/calib-s700001}
tips_sets=${TIPS_SETS:-/work/data/tips-s31 /work/data/tips-s32}
dev=$(realpath "${PHYLLO_DEV_DATA:-$root/../shared/data/unl-maize-dev}")
bin=$root/target/release/phyllo
py=$root/models/.venv/bin/python
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
count() { "$bin" count --json --threads "${THREADS:-2}" --model "$model" --tip-threshold 0.3 "$@" 2>/dev/null; }
count "$calib"/images/*.png > "/tmp/calib-$tag.jsonl"
count "$dev"/images/*.jpg > "/tmp/frames-$tag.jsonl"
count "$dev"/crops/*.jpg > "/tmp/crops-$tag.jsonl"
# shellcheck disable=SC2086 # TIPS_SETS is a word list
mapfile -t val < <("$py" -c '
import json, sys
for d in sys.argv[1:]:
    for line in open(f"{d}/manifest.jsonl"):
        r = json.loads(line)
        if r["split"] == "val":
            print(d + "/" + r["image"])' $tips_sets)
count "${val[@]}" > "/tmp/val-$tag.jsonl"
cd "$root/models"
echo "## calibration set ($(basename "$calib"))"
"$py" -m phyllo_train.experiments.count_rules --counts "/tmp/calib-$tag.jsonl" --dataset "$calib" --thresholds 0.4,0.5,0.6,0.7 --caps 2,inf
echo "## real frames"
"$py" -m phyllo_train.experiments.count_rules --counts "/tmp/frames-$tag.jsonl" --truth "$dev/leaf_tips.csv" --thresholds 0.4,0.5,0.6,0.7 --caps inf
echo "## real crops"
"$py" -m phyllo_train.experiments.count_rules --counts "/tmp/crops-$tag.jsonl" --truth "$dev/crops_counts.csv" --thresholds 0.4,0.5,0.6,0.7 --caps inf
echo "## tips, real frames"
"$py" -m phyllo_train.experiments.tip_match --tips "$dev/leaf_tips.csv" --counts "/tmp/frames-$tag.jsonl"
for d in $tips_sets; do
  echo "## tips, $(basename "$d") val"
  "$py" -m phyllo_train.experiments.tip_match --dataset "$d" --split val --counts "/tmp/val-$tag.jsonl"
done
