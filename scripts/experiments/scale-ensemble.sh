#!/usr/bin/env bash
# Counting each image at three scales and keeping the median or the largest
# count (models/EXPERIMENTS.md, "Counting at three scales"): one row per set
# and rule, exact / within ±1 / RMSE / bias.
# Usage: scripts/experiments/scale-ensemble.sh [SET...]   (default: calib-s700001 calib-s700003-late frames crops)
# Environment: MODEL [models/phyllo.onnx], DATA [/work/data], THREADS [2].
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
model=${MODEL:-$root/models/phyllo.onnx}
data=${DATA:-/work/data}
real=$root/../shared/data/unl-maize-dev
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
sets=("$@")
[ ${#sets[@]} -gt 0 ] || sets=(calib-s700001 calib-s700003-late frames crops)
for s in "${sets[@]}"; do
  case $s in
    frames) args=(--counts "$real/leaf_tips.csv" --images "$real/images"); scales="0.45 0.5 0.56" ;;
    crops) args=(--counts "$real/crops_counts.csv" --images "$real/crops"); scales="0.45 0.5 0.56" ;;
    *) args=(--dataset "$data/$s" --split all); scales="0.9 1.0 1.12" ;;
  esac
  files=()
  for x in $scales; do
    "$root/target/release/phyllo" eval --model "$model" --threads "${THREADS:-2}" "${args[@]}" \
      --per-image --scale "$x" >"$tmp/$s-$x.txt"
    files+=("$tmp/$s-$x.txt")
  done
  python3 - "$s" "$scales" "${files[@]}" <<'PY'
import math, re, statistics, sys
name, scales, paths = sys.argv[1], sys.argv[2].split(), sys.argv[3:]
def read(p):
    out = {}
    for line in open(p):
        m = re.match(r"^(\S+)\t\S*\ttrue (\d+)\tpredicted (\d+)", line)
        if m:
            out[m[1]] = (int(m[2]), int(m[3]))
    return out
runs = [read(p) for p in paths]
keys = list(runs[1])
def row(label, pairs):
    e = [p - t for t, p in pairs]
    n = len(e)
    print(f"{name:20} {label:14} {100 * sum(x == 0 for x in e) / n:5.1f} / {100 * sum(abs(x) <= 1 for x in e) / n:5.1f} / "
          f"{math.sqrt(sum(x * x for x in e) / n):.3f} / {sum(e) / n:+.3f}  (n={n})")
for s, r in zip(scales, runs):
    row(f"scale {s}", [r[k] for k in keys])
row("median of 3", [(runs[1][k][0], statistics.median(r[k][1] for r in runs)) for k in keys])
row("largest of 3", [(runs[1][k][0], max(r[k][1] for r in runs)) for k in keys])
PY
done
