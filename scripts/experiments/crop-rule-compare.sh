#!/usr/bin/env bash
# Counts the dev crops under the old crop rule (long side -> 448 px; crops with
# the frame's aspect taken as frames) and the current one (x0.5), with the same
# model, and prints exact / within one / RMSE / bias for each. Reproduces the
# "crop scale fix" table in models/MODEL.md.
# Usage: scripts/experiments/crop-rule-compare.sh [MODEL] [unl-maize-dev dir]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
model=${1:-$root/models/phyllo.onnx}
dev=${2:-$root/../shared/data/unl-maize-dev}
bin=$root/target/release/phyllo
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
python3 - "$bin" "$model" "$dev" <<'PY'
import csv, json, math, subprocess, sys, struct
from pathlib import Path

bin_, model, dev = sys.argv[1], sys.argv[2], Path(sys.argv[3])

def size(p):
    # JPEG SOF marker scan: width and height without an imaging library.
    b = p.read_bytes(); i = 2
    while i < len(b):
        if b[i] != 0xFF: i += 1; continue
        m = b[i + 1]
        if m in (0xC0, 0xC1, 0xC2):
            h, w = struct.unpack(">HH", b[i + 5:i + 9]); return w, h
        i += 2 + struct.unpack(">H", b[i + 2:i + 4])[0]
    raise SystemExit(f"{p}: no JPEG frame header")

def old_scale(w, h):
    return 514 / h if abs((w / h) / 1.1936 - 1) <= 0.02 else 448 / max(w, h)

truth = {r["file"]: int(r["leaf_count"]) for r in csv.DictReader(open(dev / "crops_counts.csv"))}
rows = {"old: long side -> 448 px": [], "new: x0.5 (contract)": []}
for name, t in sorted(truth.items()):
    p = dev / "crops" / name
    for rule, extra in (("old: long side -> 448 px", ["--scale", f"{old_scale(*size(p)):.6f}"]),
                        ("new: x0.5 (contract)", [])):
        out = subprocess.run([bin_, "count", "--json", "--threads", "2", "--model", model, *extra, str(p)],
                             check=True, capture_output=True, text=True).stdout
        rows[rule].append(json.loads(out.splitlines()[0])["leaf_count"] - t)
print("| crop rule | images | exact | within ±1 | RMSE | bias |")
print("|---|---:|---:|---:|---:|---:|")
for rule, e in rows.items():
    n = len(e)
    print(f"| {rule} | {n} | {100 * sum(x == 0 for x in e) / n:.1f}% | {100 * sum(abs(x) <= 1 for x in e) / n:.1f}% | "
          f"{math.sqrt(sum(x * x for x in e) / n):.3f} | {sum(e) / n:+.3f} |")
PY
