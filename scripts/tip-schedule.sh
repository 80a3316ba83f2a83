#!/usr/bin/env bash
# The tip network's one schedule (issue 58; models/EXPERIMENTS.md, "The tip
# network: one schedule from the ImageNet start"): EfficientNet-Lite0 from its
# ImageNet weights, every layer trainable, Panoptic-DeepLab heads plus a leaf-tip
# heatmap (CenterNet focal loss) on the tips a person would click, float32, one
# warm-up + cosine schedule with EMA, two processes of one thread. It is longer
# than a session: each session renders the same data (deterministic from the
# seeds), goes on from the committed resume point, and commits the new one.
#
# Usage (from the repository root):
#   scripts/tip-schedule.sh render          # training and calibration sets into $DATA (skips those present)
#   scripts/tip-schedule.sh train MINUTES   # resume, train for MINUTES of wall clock, pause, pack the resume point
#   scripts/tip-schedule.sh score [STEP...] # count kept checkpoints on calib-s700001 with phyllo eval, one row each
# Environment: DATA [/work/data], RUN [models/runs/tips-t1], STEPS (the schedule's
# length; fixed once started).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
data=${DATA:-/work/data}
run=${RUN:-$root/models/runs/tips-t1}
py=$root/models/.venv/bin/python
gen=$root/target/release/phyllo-gen
phyllo=$root/target/release/phyllo
resume=$root/models/schedule/tips-t1.pt
steps=${STEPS:-12000}
presets=btx623,pawaga,rtx430,sc301,tx3197,maize:1.7,maize-whorl:1

render() {
  cargo build -q --release -p phyllo-gen -p phyllo --manifest-path "$root/Cargo.toml"
  mkdir -p "$data"
  # name, then phyllo-gen's options; each set is rendered once per machine.
  while read -r name opts; do
    [ -f "$data/$name/manifest.jsonl" ] && continue
    echo "rendering $name"
    # shellcheck disable=SC2086
    "$gen" dataset --out "$data/$name.partial" $opts --quiet
    rm -rf "${data:?}/$name" && mv "$data/$name.partial" "$data/$name"
  done <<EOF
train-t1a --plants 1200 --seed 5801 --views 0,72,144 --full-frame --val-fraction 0 --preset $presets --zoom 1-2.2:0.5
train-t1b --plants 300 --seed 5802 --views 36,108 --full-frame --val-fraction 0 --preset $presets,maize-late:3 --max-age 84 --max-leaves 16 --zoom 1-2.2:0.5
calib-s700001 --plants 100 --seed 700001 --views 0,36,72,108,144 --full-frame --val-fraction 1.0 --preset btx623,pawaga,rtx430,sc301,tx3197,maize:1.7 --zoom 1
EOF
}

train() {
  local minutes=${1:?usage: tip-schedule.sh train MINUTES}
  mkdir -p "$run"
  if [ ! -f "$run/last.pt" ] && [ -f "$resume" ]; then
    (cd "$root/models" && "$py" -m phyllo_train.resume_state unpack "$resume" --out "$run/last.pt")
  fi
  (cd "$root/models" && "$py" -m phyllo_train.train \
    --data "$data/train-t1a" --data "$data/train-t1b" --out "$run" \
    --encoder efficientnet-lite0 --pretrained --encoder-lr-scale 0.25 --lr 1e-3 --warmup 500 \
    --steps "$steps" --crop 384 --batch 4 --procs 2 --threads 1 --workers 0 --photometric device \
    --tips --tip-rule person --center-sigma-min 2 --scale 0.6,1.7 \
    --val-limit 0 --ckpt-every 100 --keep-every 1000 --log-every 20 --seed 58 --stop-after "$minutes")
  (cd "$root/models" && "$py" -m phyllo_train.resume_state pack "$run/last.pt" --out "$resume")
}

score() {
  cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
  local cks=()
  if [ $# -gt 0 ]; then
    for s in "$@"; do cks+=("$(printf '%s/step-%06d.pt' "$run" "$s")"); done
  else
    cks=("$run"/step-*.pt)
  fi
  mkdir -p "$run/scored"
  echo "| checkpoint | rule | images | exact | within ±1 | RMSE | MAE | bias | R² |"
  echo "|---|---|---:|---:|---:|---:|---:|---:|---:|"
  for ck in "${cks[@]}"; do
    [ -e "$ck" ] || continue
    name=tips-t1-$(basename "$ck" .pt)
    onnx=$run/scored/$name.onnx
    [ -e "$onnx" ] || (cd "$root/models" && "$py" -m phyllo_train.export --checkpoint "$ck" --out "$onnx" --name "$name" >/dev/null)
    for rule in tips split centres; do
      "$phyllo" eval --threads "${THREADS:-2}" --model "$onnx" --dataset "$data/calib-s700001" --split all \
        --count-rule "$rule" --json 2>/dev/null | "$root/scripts/eval_json.py" row "$name | $rule"
    done
  done
}

cmd=${1:-}
shift || true
case $cmd in
  render) render ;;
  train) train "$@" ;;
  score) score "$@" ;;
  *) echo "usage: tip-schedule.sh render | train MINUTES | score [STEP...]" >&2; exit 2 ;;
esac
