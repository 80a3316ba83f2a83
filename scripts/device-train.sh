#!/usr/bin/env bash
# One call of the device tool (a GPU machine lent to a session, see
# /work/.library/device/README.md): makes a fresh training set on that
# machine's cores, fine-tunes the shipped model on its GPU, and leaves the
# exported checkpoints and the log under $OUT, to be scored here with
# scripts/score-checkpoints.sh-style evaluations (calibration set first, at
# several centre thresholds, THRESHOLDS="0.15 0.2 0.25 0.3": fine-tuning lowers
# the centre peaks; then scripts/model-metrics.sh). Nothing here is needed for CI.
#
# Prepare on this machine, from the repository root:
#   cargo build --release -p phyllo-gen
#   mkdir -p .device && strip -o .device/phyllo-gen target/release/phyllo-gen
#   (cd models && .venv/bin/python -m phyllo_train.from_onnx phyllo.onnx \
#      --out ../.device/init.pt --calibrate /work/data/train-s8 --batch 16 --crop 512)
# then call the device tool's run with carry [".device"] and a command such as
#   PLANTS=1500 STEPS=5000 scripts/device-train.sh
# Budget: the machine's start counts, a call may run 10 minutes and a session
# has 15; generation runs at roughly 8x this machine's 2-core speed.
#
# To train the leaf-tip head with every layer at once (MODEL.md, next steps
# item 1), add `--tips --max-tip-gap 8` to TRAIN_ARGS: the data made here has
# leaf_tips and leaf_tip_gaps, and the exports then have the fourth output.
# On the GPU, `--bf16` in TRAIN_ARGS runs the network under bfloat16 autocast
# (1.3x faster steps on the dev CPU, the same counts: models/EXPERIMENTS.md, "bfloat16
# autocast and the loader"); keep --freeze-bn with it.
# Environment (defaults in brackets): PLANTS [1200], SEED [100: no training or
# test set uses it], PRESETS [the stage-4 mix, a fifth maize], STEPS [4000],
# BATCH [16], CROP [512], LR [1e-4], DEVICE [cuda], WORKERS [14],
# INIT [.device/init.pt], TRAIN_ARGS [--freeze-bn; models/EXPERIMENTS.md, "Why every
# fine-tune of s10 lost", says what --small-center-weight does to each set],
# OUT_DIR [$OUT], WORK [/tmp/phyllo-device], PYTHON [python3], GEN [.device/phyllo-gen],
# GEN_ARGS [--dead-remnants 0.5: half the plants keep their dead leaves' dried
# sheaths and blade stubs, labelled stem; models/MODEL.md, next steps]. For the
# whole season (plants past 8 weeks, 14-16 leaves; models/EXPERIMENTS.md, "Plants
# past eight weeks"): PRESETS=btx623,pawaga,rtx430,sc301,tx3197,maize:1.7,maize-late:3
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
init=${INIT:-$root/.device/init.pt}
case $init in /*) ;; *) init=$root/$init ;; esac
[[ $py == */* && $py != /* ]] && py=$PWD/$py
mkdir -p "$out" "$work"
log=$out/device-train.log
exec > >(tee -a "$log") 2>&1
echo "device-train: $(date -u +%FT%TZ), $(nproc) cores"
"$py" -c 'import torch; print("torch", torch.__version__, "cuda", torch.cuda.is_available(), torch.cuda.get_device_name(0) if torch.cuda.is_available() else "")'
[ -x "$gen" ] || { echo "device-train: no phyllo-gen at $gen (carry .device, see the header)"; exit 2; }
[ -e "$init" ] || { echo "device-train: no initial checkpoint at $init (see the header)"; exit 2; }

t0=$(date +%s)
data=$work/train-s$seed
if [ ! -e "$data/manifest.jsonl" ]; then
  # shellcheck disable=SC2086 # GEN_ARGS is a word list
  "$gen" dataset --out "$data" --plants "$plants" --seed "$seed" --views 0,36,72,108,144 \
    --full-frame --val-fraction 0.03 --preset "$presets" --quiet ${GEN_ARGS---dead-remnants 0.5}
fi
echo "device-train: $(wc -l <"$data/manifest.jsonl") pairs in $(( $(date +%s) - t0 )) s"

run=$work/run
keep=$(( steps / 4 > 0 ? steps / 4 : 1 ))
t1=$(date +%s)
# shellcheck disable=SC2086 # TRAIN_ARGS is a word list
(cd "$root/models" && PYTHONUNBUFFERED=1 "$py" -m phyllo_train.train --data "$data" --out "$run" \
  --init "$init" --steps "$steps" --lr "${LR:-1e-4}" --warmup 100 --crop "${CROP:-512}" \
  --batch "${BATCH:-16}" --device "${DEVICE:-cuda}" --workers "${WORKERS:-14}" \
  --val-every "$keep" --ckpt-every "$keep" --keep-every "$keep" --log-every 50 --seed "$seed" \
  ${TRAIN_ARGS---freeze-bn} \
  --data-note "scripts/device-train.sh: phyllo-gen dataset --plants $plants --seed $seed --preset $presets ${GEN_ARGS---dead-remnants 0.5}")
echo "device-train: trained in $(( $(date +%s) - t1 )) s"

# At most 8 files come back from the device tool: the log, best and four kept steps.
for ck in "$run"/best.pt "$run"/step-*.pt; do
  name=device-s$seed-$(basename "$ck" .pt)
  (cd "$root/models" && "$py" -m phyllo_train.export --checkpoint "$ck" --out "$out/$name.onnx" --name "$name" | tail -1)
done
cp "$run/log.jsonl" "$out/train-log.jsonl"
echo "device-train: done in $(( $(date +%s) - t0 )) s; $(ls "$out" | tr '\n' ' ')"
