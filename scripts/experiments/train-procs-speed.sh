#!/usr/bin/env bash
# Training images per second on this CPU, side by side in one call: one run on
# two threads, the same run split over two single-threaded processes
# (train --procs 2), and two separate single-threaded runs at once (an A/B);
# the median of each run's logged rates after warm-up.
# Usage: scripts/experiments/train-procs-speed.sh DATASET INIT_CHECKPOINT [STEPS]
# (models/EXPERIMENTS.md, "Two processes, one thread each").
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
usage="usage: train-procs-speed.sh DATASET INIT_CHECKPOINT [STEPS]"
data=$(cd "${1:?$usage}" && pwd)
init=$(realpath "${2:?$usage}")
steps=${3:-60}
py=${PYTHON:-$root/models/.venv/bin/python}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
common=(--data "$data" --init "$init" --steps "$steps" --crop 384 --batch 4 --lr 1e-4 --warmup 10
        --encoder-lr-scale 0.5 --freeze-encoder 3 --bf16 --photometric device --workers 0 --val-limit 0
        --ckpt-every 100000 --log-every 5)
echo "| run | processes × threads | images per step | images/s (median after step 15) |"
echo "|---|---:|---:|---:|"
median() {
  "$py" -c "import json,statistics,sys;print(f'{statistics.median(json.loads(l)[\"rate\"] for l in open(sys.argv[1]) if json.loads(l)[\"step\"]>15):.2f}')" "$1/log.jsonl"
}
train() { # name, then more train arguments
  local name=$1
  shift
  (cd "$root/models" && "$py" -m phyllo_train.train "${common[@]}" --out "$tmp/$name" "$@" >"$tmp/$name.log" 2>&1) ||
    { cat "$tmp/$name.log" >&2; return 1; }
}
for cfg in "1 2" "2 1"; do
  read -r procs threads <<<"$cfg"
  train "p$procs" --procs "$procs" --threads "$threads"
  echo "| one run, --procs $procs --threads $threads | $procs × $threads | $((4 * procs)) | $(median "$tmp/p$procs") |"
done
train a --threads 1 &
pid_a=$!
train b --threads 1 --seed 1 &
pid_b=$!
wait "$pid_a"
wait "$pid_b"
echo "| two runs at once, --threads 1 each | 2 × 1 | 4 each | $(median "$tmp/a") + $(median "$tmp/b") |"
