#!/usr/bin/env bash
# Compares two models image by image on one phyllo-gen dataset: each model's
# exact / within ±1 / RMSE / bias, then how many images each counts closer to
# the truth and a two-sided sign test on those. Differences with p well above
# 0.05 are noise.
# Usage: scripts/compare-models.sh DATASET MODEL_A MODEL_B [extra phyllo eval args...]
# ARGS_A and ARGS_B add arguments for one side only, to compare settings of
# one model: ARGS_B="--zoom-height 480" compare-models.sh D M M
# A_CACHE=FILE keeps model A's per-image counts in FILE and reads them from
# there when it exists, so a caller comparing many models against one base
# counts the base once (scripts/score-device-run.sh).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
usage="usage: compare-models.sh DATASET MODEL_A MODEL_B [phyllo eval args...]"
data=${1:?$usage}
a=${2:?$usage}
b=${3:?$usage}
shift 3
bin=$root/target/release/phyllo
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# shellcheck disable=SC2086 # ARGS_A and ARGS_B are word lists
if [ -n "${A_CACHE:-}" ] && [ -s "$A_CACHE" ]; then
  cp "$A_CACHE" "$tmp/a"
else
  "$bin" eval --threads "${THREADS:-2}" --model "$a" --dataset "$data" --per-image "$@" ${ARGS_A:-} 2>/dev/null >"$tmp/a"
  [ -z "${A_CACHE:-}" ] || cp "$tmp/a" "$A_CACHE"
fi
"$bin" eval --threads "${THREADS:-2}" --model "$b" --dataset "$data" --per-image "$@" ${ARGS_B:-} 2>/dev/null >"$tmp/b"
python3 - "$root/scripts" "$tmp/a" "$tmp/b" <<'PY'
import math, sys
sys.path.insert(0, sys.argv[1])
from compare_counts import closer, load

(na, a), (nb, b) = load(sys.argv[2]), load(sys.argv[3])
if na == nb:
    na, nb = f"{na} (A)", f"{nb} (B)"
print("| model | images | exact | within ±1 | RMSE | bias |")
print("|---|---:|---:|---:|---:|---:|")
for name, rows in ((na, a), (nb, b)):
    e = [p - t for t, p in rows.values()]
    n = len(e)
    print(f"| {name} | {n} | {100 * sum(x == 0 for x in e) / n:.1f}% | "
          f"{100 * sum(abs(x) <= 1 for x in e) / n:.1f}% | {math.sqrt(sum(x * x for x in e) / n):.3f} | "
          f"{sum(e) / n:+.3f} |")
wa, wb, p = closer(a, b, a)
print(f"\ncloser to the truth: {na} on {wa} images, {nb} on {wb}; sign test p = {p:.3f}")
PY
