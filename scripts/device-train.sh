#!/usr/bin/env bash
# One call of the device tool (a GPU machine lent to a session, see
# /work/.library/device/README.md): makes a fresh training set on that
# machine's cores, trains one or more networks side by side on its GPU (a
# network of this size leaves the GPU mostly idle; the data loaders share the
# cores), and leaves the exported ONNX files, slim checkpoints and logs under
# $OUT, to be scored here (scripts/compare-models.sh on the calibration sets,
# then scripts/model-metrics.sh). Nothing here is needed for CI.
#
# The tip network's schedule (issue 58) does not start afresh here: a lent GPU
# goes on with it through scripts/tip-schedule.sh (render its sets, then
# `DEVICE=cuda PYTHON=python3 scripts/tip-schedule.sh train MINUTES` with
# models/schedule/tips-t1.pt in the tree, and copy the repacked file to $OUT).
#
# Prepare on this machine with scripts/device-prepare.sh [INIT_ONNX]: it does
# what follows, proves it with a toy run of this script on the CPU, and prints
# the device call. By hand, from the repository root:
#   cargo build --release -p phyllo-gen
#   mkdir -p .device && strip -o .device/phyllo-gen target/release/phyllo-gen
#   (cd models && .venv/bin/python -m phyllo_train.tools.from_onnx phyllo.onnx \
#      --out ../.device/init.pt --calibrate DATA --batch 16 --crop 512)
# (DATA: a training set, e.g. a few plants from phyllo-gen dataset; not a calibration set)
# To go on from an earlier call's network instead of s10, give from_onnx that
# call's export (the wider layout comes from its phyllo.architecture metadata,
# and train takes it from init.pt, so the runs need no --width/--dec/--ins-width).
# Checkpoints left in models/runs are lost with this machine: commit an export
# worth continuing (models/candidates/, a few MB) so that the next lent GPU
# starts from it.
# then call the device tool's run with carry [".device"] and a command such as
#   MINUTES=5 PLANTS=1500 scripts/device-train.sh
# Budget: the machine's start counts, a call may run 10 minutes and a session
# has 15, so one call it is: set MINUTES (each run's wall-clock budget; the LR
# schedule decays over it) so that generation + MINUTES + export ends well
# inside the call's timeout.
#
# RUNS lists the trainings, `;`-separated, each `NAME|TRAIN ARGS`; they run at
# once, sharing WORKERS loader processes; they start in models/, so give
# paths absolute (`--init $PWD/.device/init.pt`). The default fine-tunes s10
# (`--init .device/init.pt --freeze-bn`). A run from scratch gives no --init
# (and a higher --lr); `--width`, `--dec` and `--ins-width` widen the network,
# from scratch or grown from --init (model.grow_state). Fine-tuning lowers the
# centre peaks, so score fine-tunes at several centre thresholds
# (models/EXPERIMENTS.md, "The centre loss and the count").
# To train the leaf-tip head with every layer at once (MODEL.md, next steps
# item 1), add `--tips --max-tip-gap 8` to a run's arguments: the data made here
# has leaf_tips and leaf_tip_gaps, and the exports then have the fourth output.
# `--bf16` runs the network under bfloat16 autocast (models/EXPERIMENTS.md,
# "bfloat16 autocast and the loader"); keep --freeze-bn with it.
# Session 24's call (models/EXPERIMENTS.md, "The first GPU run") rendered 450
# plants in 105 s and its 14 loader workers made about 100 crops/s for both
# runs together, with the GPU mostly idle: the loaders, not the GPU, set how
# much a call trains. So the photometric ops (about half a loader's time) run
# batched on the GPU by default (`train --photometric device`; PHOTOMETRIC=loader
# puts them back in the loaders). Each training log line says the share of
# time the network waited for batches (`data wait N%`): high, more loader
# work is the limit; near 0, the GPU is (then try `--bf16`). Each run also
# decodes its training PNGs once before its workers start (`train --preload`,
# ~1.6 MB of RAM a pair; PRELOAD=0 turns it off).
#
# Environment (defaults in brackets): PLANTS [1200], SEED [100: no training or
# test set uses it], PRESETS [the stage-4 mix, a fifth maize], MINUTES [none:
# STEPS alone], STEPS [4000; with MINUTES an upper bound], BATCH [16], CROP
# [512], VAL_EVERY [STEPS/4], DEVICE [cuda], WORKERS [14], RUNS [ft|--init .device/init.pt --lr 1e-4
# --freeze-bn], OUT_DIR [$OUT], WORK [/tmp/phyllo-device], PYTHON [python3],
# VIEWS [0,36,72,108,144], FRAME [--full-frame; the paper's protocol: VIEWS=0,36,72,108,144,top
# FRAME="--size 512", as the pretrained-encoder model trains], GEN [.device/phyllo-gen], GEN_ARGS [--dead-remnants 0.5: half the plants keep
# their dead leaves' dried sheaths and blade stubs, labelled stem], SHARDS [8],
# GEN_SECONDS [none: every shard], KEEP_EVERY [none: also bring back a slim
# checkpoint every N steps, in steps.tar]. For the
# whole season (plants past 8 weeks, 14-16 leaves; models/EXPERIMENTS.md,
# "Plants past eight weeks"): PRESETS=btx623,pawaga,rtx430,sc301,tx3197,maize:1.7,maize-late:3
# GEN_ARGS="--dead-remnants 0.5 --max-age 84 --max-leaves 16".
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
plants=${PLANTS:-1200}
seed=${SEED:-100}
presets=${PRESETS:-btx623,pawaga,rtx430,sc301,tx3197,maize:1.7}
steps=${STEPS:-4000}
out=${OUT_DIR:-${OUT:?set OUT_DIR or run under the device tool, which sets OUT}}
work=${WORK:-/tmp/phyllo-device}
py=${PYTHON:-python3}
gen=${GEN:-$root/.device/phyllo-gen}
runs=${RUNS:-"ft|--init $root/.device/init.pt --lr 1e-4 --freeze-bn"}
[[ $py == */* && $py != /* ]] && py=$PWD/$py
mkdir -p "$out" "$work"
log=$out/device-train.log
exec > >(tee -a "$log") 2>&1
echo "device-train: $(date -u +%FT%TZ), $(nproc) cores"
"$py" -c 'import torch; print("torch", torch.__version__, "cuda", torch.cuda.is_available(), torch.cuda.get_device_name(0) if torch.cuda.is_available() else "")'
[ -x "$gen" ] || { echo "device-train: no phyllo-gen at $gen (carry .device, see the header)"; exit 2; }

t0=$(date +%s)
data=$work/train-s$seed
if [ ! -e "$data/manifest.jsonl" ]; then
  # In SHARDS parts, so that GEN_SECONDS can stop it between parts with a
  # smaller set of whole plants rather than spend the call on rendering.
  shards=${SHARDS:-8}
  for ((k = 0; k < shards; k++)); do
    if [ -n "${GEN_SECONDS:-}" ] && (( $(date +%s) - t0 >= GEN_SECONDS )); then
      echo "device-train: GEN_SECONDS=$GEN_SECONDS spent; training on $k of $shards shards"
      break
    fi
    # shellcheck disable=SC2086 # GEN_ARGS is a word list
    "$gen" dataset --out "$data" --plants "$plants" --seed "$seed" --views "${VIEWS:-0,36,72,108,144}" \
      ${FRAME---full-frame} --val-fraction 0.03 --preset "$presets" --quiet --shard "$k/$shards" ${GEN_ARGS---dead-remnants 0.5}
  done
  cat "$data"/manifest.shard-*.jsonl >"$data/manifest.jsonl"
fi
echo "device-train: $(wc -l <"$data/manifest.jsonl") pairs in $(( $(date +%s) - t0 )) s"

IFS=';' read -ra specs <<<"$runs"
workers=$(( ${WORKERS:-14} / ${#specs[@]} ))
keep=$(( steps / 4 > 0 ? steps / 4 : 1 ))
t1=$(date +%s)
pids=()
for spec in "${specs[@]}"; do
  name=${spec%%|*}
  # shellcheck disable=SC2086 # the run's train args are a word list
  (cd "$root/models" && PYTHONUNBUFFERED=1 "$py" -m phyllo_train.train --data "$data" --out "$work/run-$name" \
    --steps "$steps" ${MINUTES:+--minutes "$MINUTES"} --warmup 100 --crop "${CROP:-512}" \
    --batch "${BATCH:-16}" --device "${DEVICE:-cuda}" --workers "$workers" --photometric "${PHOTOMETRIC:-device}" \
    $([ "${PRELOAD:-1}" = 1 ] && echo --preload) ${KEEP_EVERY:+--keep-every "$KEEP_EVERY"} \
    --val-every "${VAL_EVERY:-$keep}" --ckpt-every "${VAL_EVERY:-$keep}" --log-every 50 --seed "$seed" ${spec#*|} \
    --data-note "scripts/device-train.sh: phyllo-gen dataset --plants $plants --seed $seed --preset $presets ${GEN_ARGS---dead-remnants 0.5}" \
    >"$work/train-$name.log" 2>&1 && echo "device-train: run $name finished" \
    || echo "device-train: run $name failed: $(tail -2 "$work/train-$name.log")") &
  pids+=($!)
done
wait "${pids[@]}" || true
echo "device-train: trained in $(( $(date +%s) - t1 )) s"

# At most 8 files come back from the device tool: this log, one tar of the
# runs' logs and slim checkpoints (EMA weights and args: what export and --init
# read), and the ONNX exports of each run's best and last steps.
slim='import sys, torch
ck = torch.load(sys.argv[1], map_location="cpu", weights_only=False)
keys = ("model", "step", "best", "args", "training_data", "contract_version")
out = {k: ck[k] for k in keys if k in ck}
out["raw_model"] = out["model"]  # what --init reads; one copy on disk (torch.save shares storages)
torch.save(out, sys.argv[2])'
mkdir -p "$work/back"
for spec in "${specs[@]}"; do
  name=${spec%%|*}
  run=$work/run-$name
  mkdir -p "$work/back/$name"
  cp "$work/train-$name.log" "$work/back/$name/" 2>/dev/null || true
  cp "$run/log.jsonl" "$work/back/$name/" 2>/dev/null || true
  for ck in "$run"/best.pt "$run"/last.pt; do
    [ -e "$ck" ] || continue
    "$py" -c "$slim" "$ck" "$work/back/$name/$(basename "$ck")"
    tag=device-s$seed-$name-$(basename "$ck" .pt)
    (cd "$root/models" && "$py" -m phyllo_train.export --checkpoint "$ck" --out "$out/$tag.onnx" --name "$tag" | tail -1) \
      || echo "device-train: export of $ck failed (the slim checkpoint is in runs.tar)"
  done
  tail -3 "$work/train-$name.log" | sed "s/^/[$name] /"
done
tar -C "$work/back" -cf "$out/runs.tar" .
# KEEP_EVERY's step checkpoints (slim, as above) go in steps.tar, so that the
# run can be scored step by step here (scripts/score-checkpoints.sh). A file
# may bring back 16 MiB: the earliest steps are dropped until the tar fits.
if [ -n "${KEEP_EVERY:-}" ]; then
  mkdir -p "$work/steps"
  for spec in "${specs[@]}"; do
    name=${spec%%|*}
    mkdir -p "$work/steps/$name"
    for ck in "$work/run-$name"/step-*.pt; do
      [ -e "$ck" ] && "$py" -c "$slim" "$ck" "$work/steps/$name/$(basename "$ck")"
    done
  done
  while :; do
    tar -C "$work/steps" -cf "$out/steps.tar" .
    (( $(stat -c %s "$out/steps.tar") <= 15 * 1024 * 1024 )) && break
    oldest=$(cd "$work/steps" && ls -- */step-*.pt 2>/dev/null | sort -t/ -k2 | head -1)
    [ -n "$oldest" ] || break
    echo "device-train: steps.tar over 15 MiB, leaving out $oldest"
    rm -f "$work/steps/$oldest"
  done
fi
echo "device-train: done in $(( $(date +%s) - t0 )) s; $(ls "$out" | tr '\n' ' ')"
