#!/usr/bin/env bash
# Measures where phyllo says each new leaf emerged (crate::leaf_site), with
# the model in the loop, against the generator's labels: renders a growth
# sequence with panoptic labels (phyllo-gen sequence --labels), lets a real
# `phyllo serve` count every frame from its drop directory (so each count
# keeps its leaf instances), exports the emergence events with their sites,
# and asks of each site's instance which true leaf it lies on
# (scripts/leaf_site_accuracy.py).
# Usage: scripts/leaf-site-accuracy.sh
# Environment: PLANTS [8], DAYS [14], START_AGE [14], SEED [820001], DATA
#   [/work/data] (the sequence goes to DATA/seq-s<SEED>-labels, rendered only
#   when missing), MODEL [models/phyllo.onnx], WORK [a temporary folder; the
#   store and the exports, kept when given]. The scoring runs in models/.venv
#   (numpy, pillow; ./scripts/test.sh makes it).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seed=${SEED:-820001}
dir=${DATA:-/work/data}/seq-s$seed-labels
cargo build -q --release -p phyllo -p phyllo-gen --manifest-path "$root/Cargo.toml"
bin=$root/target/release
if [ ! -e "$dir/truth.csv" ]; then
  "$bin/phyllo-gen" sequence --out "$dir" --plants "${PLANTS:-8}" --days "${DAYS:-14}" \
    --start-age "${START_AGE:-14}" --seed "$seed" --views 0,36,72,108,144 --labels --quiet
fi
work=${WORK:-$(mktemp -d)}
mkdir -p "$work/drop"
# The frames only (labels/ would be counted too), as hard links: no copies.
find "$dir" -maxdepth 1 -name '*.png' -exec ln -f {} "$work/drop/" \;
frames=$(find "$work/drop" -maxdepth 1 -name '*.png' | wc -l)
cat >"$work/phyllo.toml" <<TOML
drop_dir = "$work/drop"
database = "$work/db.sqlite"
[inference]
model = "${MODEL:-$root/models/phyllo.onnx}"
TOML
"$bin/phyllo" serve --config "$work/phyllo.toml" 2>"$work/serve.log" &
serve=$!
trap 'kill -TERM $serve 2>/dev/null || true' EXIT
echo "counting $frames frames with phyllo serve (store in $work)" >&2
python3 - "$work/db.sqlite" "$frames" "$serve" <<'PY'
import os, sqlite3, sys, time
db, frames, serve = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
while True:
    time.sleep(5)
    try:
        os.kill(serve, 0)
    except OSError:
        sys.exit("phyllo serve stopped early; see serve.log in the store's folder")
    if not os.path.exists(db):
        continue
    try:
        done = sqlite3.connect(db).execute("SELECT COUNT(*) FROM images WHERE state IN ('counted','failed','duplicate')").fetchone()[0]
    except sqlite3.Error:
        continue
    if done >= frames:
        break
PY
kill -TERM $serve
wait $serve || true
trap - EXIT
"$bin/phyllo" export --config "$work/phyllo.toml" --what events --out "$work/events.csv"
"$root/models/.venv/bin/python" "$root/scripts/leaf_site_accuracy.py" --sequence "$dir" --events "$work/events.csv" \
  --db "$work/db.sqlite"
