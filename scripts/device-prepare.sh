#!/usr/bin/env bash
# Prepares .device/ for one call of scripts/device-train.sh on a lent GPU, and
# proves it here first with a toy run of that script on this machine's CPU,
# so that no device time goes to a mistake. Everything device-train.sh's
# header asks for, in one command:
#   - phyllo-gen built and stripped into .device/phyllo-gen (the device has no Rust);
#   - .device/init.pt: the starting network rebuilt from an ONNX export
#     (default models/phyllo.onnx, or a committed export of an earlier GPU
#     run; a wider layout comes from its metadata), BatchNorm calibrated on
#     training-style 512² crops in batches of 16, as device-train.sh trains;
#   - a toy device-train.sh run (DEVICE=cpu, 4 plants, 2 steps) from that
#     init.pt, which must export an ONNX file.
# Then it prints the device tool call. Takes ~3 minutes with a built tree
# (rendering the 16-plant calibration set is most of it).
#
# Usage: scripts/device-prepare.sh [INIT_ONNX]
# Environment: CALIB_DATA [render 16 whole-season plants, seed 4242, to
#   /work/data/device-calib-s4242], BATCH [16], CROP [512], PYTHON [models/.venv/bin/python],
#   RUNS [one run growing s10 to session 24's wider layout; device-train.sh's
#   format, `$PWD/` standing for the repository root on either machine]: the
#   toy run trains these very arguments, and the printed call passes them.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
init_onnx=$(realpath "${1:-models/phyllo.onnx}")
py=${PYTHON:-models/.venv/bin/python}
[[ $py == */* && $py != /* ]] && py=$root/$py  # not realpath: a venv's python is a symlink
batch=${BATCH:-16}
runs=${RUNS:-'grow|--init $PWD/.device/init.pt --width 24,32,48,96,160 --dec 96,64,48,32 --ins-width 64 --lr 3e-4 --freeze-bn'}
crop=${CROP:-512}
[ -x "$py" ] || { echo "device-prepare: no Python at $py (make models/.venv first, see README)"; exit 2; }
[ -e "$init_onnx" ] || { echo "device-prepare: no ONNX file at $init_onnx"; exit 2; }

cargo build -q --release --locked -p phyllo-gen
mkdir -p .device
strip -o .device/phyllo-gen target/release/phyllo-gen

calib=${CALIB_DATA:-/work/data/device-calib-s4242}
if [ ! -e "$calib/manifest.jsonl" ]; then
  # Seed 4242 is no evaluation set's; the whole-season mix, as device-train.sh's
  # recommended PRESETS/GEN_ARGS render (models/EXPERIMENTS.md, "The first GPU run").
  target/release/phyllo-gen dataset --out "$calib" --plants 16 --seed 4242 --views 0,36,72,108,144 \
    --full-frame --val-fraction 0 --preset btx623,pawaga,rtx430,sc301,tx3197,maize:1.7,maize-late:2 \
    --quiet --dead-remnants 0.5 --max-age 84 --max-leaves 16
fi
(cd models && "$py" -m phyllo_train.tools.from_onnx "$init_onnx" --out "$root/.device/init.pt" \
  --calibrate "$calib" --images 80 --batch "$batch" --crop "$crop")

# The toy run: same script, same init.pt, this CPU, a few seconds of training.
toy=$(mktemp -d)
trap 'rm -rf "$toy"' EXIT
OUT_DIR=$toy/out WORK=$toy/work PLANTS=4 SHARDS=2 STEPS=2 KEEP_EVERY=1 BATCH=2 CROP=128 DEVICE=cpu WORKERS=1 \
  PYTHON=$py RUNS=${runs//\$PWD/$root} bash scripts/device-train.sh >"$toy/log" 2>&1 || true
IFS=';' read -ra specs <<<"$runs"
for spec in "${specs[@]}"; do
  if [ ! -e "$toy/out/device-s100-${spec%%|*}-last.onnx" ]; then
    echo "device-prepare: the toy run of device-train.sh made no export of run ${spec%%|*}; its log:"
    tail -20 "$toy/log"
    exit 1
  fi
done
tar -tf "$toy/out/steps.tar" | grep -q 'step-000002.pt' \
  || { echo "device-prepare: the toy run brought back no step checkpoints"; tail -20 "$toy/log"; exit 1; }
echo "device-prepare: toy run of device-train.sh on this CPU exported $(cd "$toy/out" && ls -- *.onnx | tr '\n' ' ')"
du -sh .device | sed 's/^/device-prepare: carry /'
cat <<EOF
device-prepare: ready. Call the device tool's run with carry [".device"], timeout_s 590, and e.g.
  MINUTES=6 STEPS=100000 VAL_EVERY=500 KEEP_EVERY=1000 PLANTS=2400 SHARDS=16 GEN_SECONDS=90 WORKERS=14 BATCH=$batch CROP=$crop \\
    PRESETS=btx623,pawaga,rtx430,sc301,tx3197,maize:1.7,maize-late:2,maize-whorl:1.5 \\
    GEN_ARGS="--dead-remnants 0.5 --max-age 84 --max-leaves 16" \\
    RUNS="$runs" \\
    bash scripts/device-train.sh
Then, here: scripts/score-device-run.sh DIR (DIR: where the call's files were copied).
(maize-whorl: young maize with the real plants' crowded tops, which s10 counts
44.0 % exact against 55.2 % on calib-s700001; models/EXPERIMENTS.md, "Crowded maize tops".)
(One run with every worker; photometric ops on the GPU by default. Starting from
a wider export, give RUNS without --width/--dec/--ins-width: train takes them from init.pt.)
EOF
