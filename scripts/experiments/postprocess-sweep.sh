#!/usr/bin/env bash
# Sweeps the counter's post-processing (centre threshold x attachment radius
# x minimum leaf area x small-plant zoom height)
# on a synthetic calibration dataset and prints one table row per setting:
# exact / within one / RMSE / MAE / bias / R². Calibrate on a dataset whose seed is used
# neither for training nor for the withheld test set (models/MODEL.md names
# the one used), never on the real dev images.
# Usage: scripts/experiments/postprocess-sweep.sh DATASET [MODEL] [THRESHOLDS] [RADII] [MIN_AREAS] [ZOOM_HEIGHTS]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
data=${1:?usage: postprocess-sweep.sh DATASET [MODEL] [THRESHOLDS] [RADII] [MIN_AREAS] [ZOOM_HEIGHTS]}
model=${2:-$root/models/phyllo.onnx}
thresholds=${3:-0.1 0.2 0.3 0.4}
radii=${4:-0 3}
areas=${5:-24}
zooms=${6:-320}
bin=$root/target/release/phyllo
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
echo "| centre threshold | attach radius | min leaf area | zoom height | images | exact | within ±1 | RMSE | MAE | bias | R² |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for t in $thresholds; do
  for r in $radii; do
    for a in $areas; do
      for z in $zooms; do
        "$bin" eval --threads "${THREADS:-2}" --model "$model" --dataset "$data" --json \
          --center-threshold "$t" --attach-radius "$r" --min-leaf-area "$a" --zoom-height "$z" 2>/dev/null |
          "$root/scripts/eval_json.py" row "$t | $r | $a | $z"
      done
    done
  done
done
