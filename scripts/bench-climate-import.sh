#!/usr/bin/env bash
# Time of `phyllo import LOG.csv` (a 90-day, 15-minute temperature log) into
# a store of PLANTS plants with 60 days of counts each (three side views a
# day, a leaf every 2.5-4.5 days): what the hourly phyllo-import.timer pays
# each time the climate computer rewrites its log. Every plant's thermal
# phyllochron and next-leaf forecast are worked out again on each import.
# Prints a table, one row per binary and round, rounds alternating, so that
# two builds compare side by side on this noisy machine: give the other
# build's phyllo as BASE (e.g. a worktree of an older commit).
# Usage: scripts/bench-climate-import.sh   Environment: PLANTS [500], ROUNDS [3], BASE [none]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cargo build -q --release --locked -p phyllo --manifest-path "$root/Cargo.toml"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
PLANTS=${PLANTS:-500} python3 - <<'PY'
import datetime as dt, os, random
random.seed(1)
start = dt.datetime(2026, 9, 1)
with open("counts.csv", "w") as f:
    f.write("plant,timestamp,view,leaf_count\n")
    for p in range(int(os.environ["PLANTS"])):
        rate = 2.5 + random.random() * 2
        for d in range(60):
            t = start + dt.timedelta(days=d, hours=8)
            for a in (0, 72, 144):
                f.write(f"P{p:04d},{t:%Y-%m-%dT%H:%M:%S},SV_{a},{3 + int(d / rate)}\n")
with open("log.csv", "w") as f:
    f.write("timestamp,temp_c\n")
    for k in range(90 * 96):
        t = start - dt.timedelta(days=10) + dt.timedelta(minutes=15 * k)
        f.write(f"{t:%Y-%m-%dT%H:%M:%S},{20 + 5 * ((t.hour - 2) % 24 < 12)}\n")
PY
printf 'drop_dir = "drop"\ndatabase = "db.sqlite"\n' >p.toml
"$root/target/release/phyllo" import -c p.toml counts.csv >/dev/null
cp db.sqlite counted.sqlite
echo "| binary | round | plants | time |"
echo "|---|---:|---:|---:|"
for ((r = 1; r <= ${ROUNDS:-3}; r++)); do
  for bin in ${BASE:-} "$root/target/release/phyllo"; do
    cp counted.sqlite db.sqlite
    rm -f db.sqlite-wal db.sqlite-shm
    rm -rf imports
    t0=$(date +%s%N)
    "$bin" import -c p.toml log.csv >/dev/null
    t1=$(date +%s%N)
    echo "| $bin | $r | ${PLANTS:-500} | $(( (t1 - t0) / 1000000 )) ms |"
    cp db.sqlite "after-$(basename "$(dirname "$bin")")-$RANDOM.sqlite"
  done
done
# Both builds must leave every plant with the same numbers.
python3 - after-*.sqlite <<'PY'
import sqlite3, sys
q = "SELECT name, ROUND(phyllochron_cd, 9), next_leaf_at FROM plants ORDER BY name"
results = {f: sqlite3.connect(f).execute(q).fetchall() for f in sys.argv[1:]}
same = len({tuple(r) for r in results.values()}) == 1
print(f"every plant's degree-days per leaf and next-leaf forecast the same after all {len(results)} runs: {same}")
sys.exit(0 if same else 1)
PY
