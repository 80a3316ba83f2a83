#!/usr/bin/env bash
# Does a count hinge on the plant's size in the tile? Counts the same
# synthetic frames at 1×, 1.5× and 2× the contract's scale (`phyllo eval
# --scale`) and prints, per model, the share of frames whose counts at 1.5×
# and 2× both stay within ±1 of the count at 1× (issue 58's stability figure;
# target ≥ 90 %), with each scale's exact share against the truth.
# Usage: scripts/experiments/scale-stability.sh DATASET MODEL.onnx [MODEL.onnx ...]
# Environment: EXTRA (more `phyllo eval` options, e.g. "--count-rule tips"),
# THREADS [2], LIMIT (first N frames only, default all).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
usage="usage: scale-stability.sh DATASET MODEL.onnx [MODEL.onnx ...]"
data=${1:?$usage}
shift
[ $# -gt 0 ] || { echo "$usage" >&2; exit 2; }
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if [ "${LIMIT:-0}" -gt 0 ]; then
  # The first LIMIT frames as a dataset of their own (the same files, linked).
  mkdir "$tmp/subset"
  head -n "$LIMIT" "$data/manifest.jsonl" >"$tmp/subset/manifest.jsonl"
  ln -s "$(cd "$data" && pwd)/images" "$(cd "$data" && pwd)/labels" "$tmp/subset/"
  data=$tmp/subset
fi
echo "| model | frames | within ±1 of 1× at 1.5× and 2× | exact at 1× | exact at 1.5× | exact at 2× |"
echo "|---|---:|---:|---:|---:|---:|"
for model in "$@"; do
  for s in 1 1.5 2; do
    # shellcheck disable=SC2086
    "$root/target/release/phyllo" eval --model "$model" --dataset "$data" --split all --threads "${THREADS:-2}" \
      --scale "$s" --per-image ${EXTRA:-} 2>/dev/null | grep -P '\ttrue \d+\tpredicted ' >"$tmp/$s.txt" || true
  done
  python3 - "$(basename "$model")" "$tmp" <<'PY'
import sys
name, tmp = sys.argv[1], sys.argv[2]
runs = {}
for s in ("1", "1.5", "2"):
    rows = {}
    for line in open(f"{tmp}/{s}.txt", encoding="utf-8"):
        p = line.rstrip("\n").split("\t")
        rows[p[0]] = (int(p[2][5:]), int(p[3][10:]))
    runs[s] = rows
names = sorted(set.intersection(*(set(r) for r in runs.values())))
if not names:
    sys.exit(f"{name}: no per-image lines")
stable = sum(all(abs(runs[s][n][1] - runs["1"][n][1]) <= 1 for s in ("1.5", "2")) for n in names)
exact = {s: sum(runs[s][n][0] == runs[s][n][1] for n in names) / len(names) for s in runs}
print(f"| {name} | {len(names)} | {100 * stable / len(names):.1f} % | {100 * exact['1']:.1f} % | "
      f"{100 * exact['1.5']:.1f} % | {100 * exact['2']:.1f} % |")
PY
done
