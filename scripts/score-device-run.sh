#!/usr/bin/env bash
# Scores what one device call brought back (scripts/device-train.sh's ONNX
# exports) against the shipped model, the way session 24 scored its run:
# each export on each calibration set, at each centre threshold (a
# fine-tune lowers the centre peaks, so a lower threshold may count better;
# models/EXPERIMENTS.md, "The centre loss and the count"), image by image
# against the shipped model at its own threshold (counted once per set), with
# the sign test.
# Then the real frames and crops for each export at each threshold.
# Usage: scripts/score-device-run.sh DIR_OR_ONNX...
# Environment: SETS ["/work/data/calib-s700001 /work/data/calib-s700003-late
#   /work/data/whorl-s700005";
#   scripts/make-eval-sets.sh renders them], THRESHOLDS ["0.3 0.2"],
#   BASE [models/phyllo.onnx], PHYLLO_DEV_DATA [../shared/data/unl-maize-dev].
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
(($#)) || { echo "usage: score-device-run.sh DIR_OR_ONNX..."; exit 2; }
base=${BASE:-$root/models/phyllo.onnx}
dev=${PHYLLO_DEV_DATA:-$root/../shared/data/unl-maize-dev}
models=()
for arg in "$@"; do
  if [ -d "$arg" ]; then
    models+=("$arg"/*.onnx)
  else
    models+=("$arg")
  fi
done
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
# The base model is counted once per set, not once per export and threshold.
cache=$(mktemp -d)
trap 'rm -rf "$cache"' EXIT
for set in ${SETS:-/work/data/calib-s700001 /work/data/calib-s700003-late /work/data/whorl-s700005}; do
  [ -e "$set/manifest.jsonl" ] || { echo "== $set: not on disk (scripts/make-eval-sets.sh NAME renders it)"; continue; }
  for m in "${models[@]}"; do
    for t in ${THRESHOLDS:-0.3 0.2}; do
      echo "== $(basename "$set"): $(basename "$base") against $(basename "$m") at centre threshold $t"
      A_CACHE="$cache/base-$(basename "$set").txt" ARGS_B="--center-threshold $t" \
        "$root/scripts/compare-models.sh" "$set" "$base" "$m" --split all
    done
  done
done
echo "== real images, columns: | images | exact | within ±1 | RMSE | MAE | bias | R² |"
for m in "${models[@]}"; do
  for t in ${THRESHOLDS:-0.3 0.2}; do
    for real in "leaf_tips.csv images" "crops_counts.csv crops"; do
      read -r csv images <<<"$real"
      [ -e "$dev/$csv" ] || continue
      echo "== $(basename "$m") at $t, real $images: $("$root/target/release/phyllo" eval --model "$m" \
        --counts "$dev/$csv" --images "$dev/$images" --center-threshold "$t" 2>/dev/null | grep -A2 '^| images' | tail -1)"
    done
  done
done
