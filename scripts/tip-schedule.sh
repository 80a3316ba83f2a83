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
#   scripts/tip-schedule.sh score [STEP|MODEL.onnx ...]  # count kept checkpoints (or ONNX files) on
#                                           # calib-s700001 (SET) with phyllo eval: rows per count rule and truth
# Environment: DATA [/work/data], RUN [models/runs/tips-t1], EXTRA (score: phyllo eval options), STEPS [6000] (the schedule's
# length; fixed once started), DEVICE [cpu; cuda on a lent GPU: render, then
# `DEVICE=cuda PYTHON=python3 scripts/tip-schedule.sh train 7`, and bring back
# models/schedule/tips-t1.pt through $OUT].
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
data=${DATA:-/work/data}
run=${RUN:-$root/models/runs/tips-t1}
py=${PYTHON:-$root/models/.venv/bin/python}
gen=$root/target/release/phyllo-gen
phyllo=$root/target/release/phyllo
resume=$root/models/schedule/tips-t1.pt
steps=${STEPS:-6000}
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
    (cd "$root/models" && "$py" -m phyllo_train.tools.resume_state unpack "$resume" --out "$run/last.pt")
  fi
  # A step is 8 crops: two processes of 4 on this CPU, or one batch of 8 on a lent GPU
  # (DEVICE=cuda; its loaders on the device machine's cores).
  local hw=(--procs 2 --batch 4 --threads 1 --workers 0)
  [ "${DEVICE:-cpu}" = cuda ] && hw=(--device cuda --batch 8 --workers "${WORKERS:-14}" --preload)
  (cd "$root/models" && "$py" -m phyllo_train.train \
    --data "$data/train-t1a" --data "$data/train-t1b" --out "$run" \
    --encoder efficientnet-lite0 --pretrained --encoder-lr-scale 0.25 --lr 1e-3 --warmup 500 \
    --steps "$steps" --crop 384 "${hw[@]}" --photometric device \
    --tips --tip-rule person --center-sigma-min 2 --scale 0.6,1.7 \
    --val-limit 0 --ckpt-every 100 --keep-every 1000 --log-every 20 --seed 58 --stop-after "$minutes")
  (cd "$root/models" && "$py" -m phyllo_train.tools.resume_state pack "$run/last.pt" --out "$resume")
}

score() {
  cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
  local cks=()
  if [ $# -gt 0 ]; then
    for s in "$@"; do
      case $s in *.onnx) cks+=("$s") ;; *) cks+=("$(printf '%s/step-%06d.pt' "$run" "$s")") ;; esac
    done
  else
    cks=("$run"/step-*.pt)
  fi
  mkdir -p "$run/scored"
  local set=${SET:-calib-s700001}
  # EXTRA (phyllo eval options, e.g. "--tip-threshold 0.2 --tip-reach 4") names its own files.
  local tag
  tag=$(printf '%s' "${EXTRA:-}" | tr -s ' -' '_' | sed 's/^_//')
  # One row per checkpoint, count rule and truth: every visible leaf (the contract's truth, as
  # phyllo eval scores) and the tips a person would click (phyllo_train.tip_truth).
  echo "| checkpoint | count rule | truth | images | exact | within ±1 | RMSE | MAE | bias |"
  echo "|---|---|---|---:|---:|---:|---:|---:|---:|"
  for ck in "${cks[@]}"; do
    [ -e "$ck" ] || continue
    name=tips-t1-$(basename "$ck" .pt)
    onnx=$run/scored/$name.onnx
    case $ck in *.onnx) name=$(basename "$ck" .onnx); onnx=$ck ;; esac
    [ -e "$onnx" ] || (cd "$root/models" && "$py" -m phyllo_train.export --checkpoint "$ck" --out "$onnx" --name "$name" >/dev/null)
    for rule in ${RULES:-tips split centres}; do
      per=$run/scored/$name-$set-$rule${tag:+-$tag}.txt
      # shellcheck disable=SC2086 # EXTRA is a list of phyllo eval options
      [ -s "$per" ] || "$phyllo" eval --threads "${THREADS:-2}" --model "$onnx" --dataset "$data/$set" --split all \
        --count-rule "$rule" ${EXTRA:-} --per-image >"$per" 2>/dev/null
      (cd "$root/models" && "$py" -m phyllo_train.tools.truth_rules --dataset "$data/$set" "$per" --person) |
        awk -F'|' -v ck="$name" -v rule="$rule${EXTRA:+ $EXTRA}" '/^\| (every visible leaf|tips a person)/ {
          sub(/ \(phyllo_train.tip_truth\)/, "", $2);
          printf "| %s | %s |%s|%s|%s|%s|%s|%s|%s|\n", ck, rule, $2, $3, $4, $5, $6, $7, $8 }'
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
