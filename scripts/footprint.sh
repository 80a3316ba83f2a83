#!/usr/bin/env bash
# phyllo's footprint, for sizing an edge box (issue 59): binary and install
# sizes of the x86-64 and aarch64 trees, then a real `phyllo serve` fed a
# burst of full 2454x2056 PNG frames: peak RSS (the process's maximum resident
# set, from wait4) and seconds per frame, on x86-64 and under qemu-aarch64.
#
#   scripts/footprint.sh [N] [EMULATED_N]
#
# N: frames in the x86 burst (default 200). EMULATED_N: frames in the emulated
# burst (default 10; 0 skips it). Emulation is some hundred times slower than
# the machine and says nothing about a real ARM box's speed; its RSS is
# qemu's, the guest's memory included. The aarch64 figures need the tree
# scripts/build-aarch64.sh leaves in out/aarch64, and qemu-aarch64 8 or newer
# (scripts/test-aarch64.sh installs it).
#
# Frames: 20 synthetic plants rendered by phyllo-gen at the camera's full
# 2454x2056 (seeds 700903-700922), each dropped again with bytes appended
# after its PNG data, so every file is counted (scripts/serve_burst.py).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
n=${1:-200}
emulated_n=${2:-10}
arm=out/aarch64
cargo build -q --release --locked -p phyllo -p phyllo-gen
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "== sizes"
scripts/install.sh --prefix "$tmp/x86" --bin target/release/phyllo --no-build --no-systemd >/dev/null
mb() { du -sb --exclude=phyllo-gen "$@" | awk '{s += $1} END {printf "%.1f MB", s / 1e6}'; }
size() { stat -Lc %s "$1" | awk '{printf "%.1f MB", $1 / 1e6}'; }
echo "| tree | phyllo binary | ONNX Runtime | side + top models | whole install |"
echo "|---|---:|---:|---:|---:|"
row() { # label, prefix
  echo "| $1 | $(size "$2/bin/phyllo") | $(size "$2/lib/phyllo/libonnxruntime.so") |" \
    "$(mb "$2/share/phyllo/phyllo.onnx" "$2/share/phyllo/phyllo-top.onnx") | $(mb "$2") |"
}
row "x86-64 (scripts/install.sh)" "$tmp/x86"
if [ -x "$arm/bin/phyllo" ]; then
  # The ARM tree also holds phyllo-gen, left out of the sum as on x86.
  row "aarch64 (scripts/build-aarch64.sh, stripped)" "$arm"
fi

echo
echo "== phyllo serve, a burst of full frames"
# Full-size frames (the camera's 2454x2056), one plant each, ages 20 to 58
# days over the presets, so small plants take their enlarged second pass.
mkdir -p "$tmp/frames"
presets=(btx623 pawaga rtx430 sc301 tx3197 maize)
for i in $(seq 0 19); do
  target/release/phyllo-gen render --preset "${presets[i % 6]}" --seed $((700903 + i)) --age $((20 + 2 * i)) \
    --view $((36 * (i % 5))) --frame-height 2056 --spp 4 --out "$tmp/frames/f$i.png" >/dev/null
  rm -f "$tmp/frames/f$i.label.png" "$tmp/frames/f$i.mask.png"
done
frames=("$tmp"/frames/*.png)
echo "| machine | frames | counted | failed | peak RSS | s per frame | clean stop |"
echo "|---|---:|---:|---:|---:|---:|---|"
burst() { # label, frames, serve_burst.py arguments
  local label=$1 count=$2
  shift 2
  python3 scripts/serve_burst.py "$@" --images "${frames[@]}" --n "$count" >"$tmp/burst.json" || true
  python3 - "$label" "$tmp/burst.json" <<'PY'
import json, sys
label, path = sys.argv[1], sys.argv[2]
try:
    r = json.load(open(path))
except ValueError:
    sys.exit(f"{label}: serve_burst.py gave no result")
clean = "yes (exit 0)" if r["exit_code"] == 0 else f"NO (exit {r['exit_code']})"
print(f"| {label} | {r['dropped']} | {r['counted']} | {r['failed']} | {r['peak_rss_mb']:.0f} MB | "
      f"{r['s_per_image']:.2f} | {clean} |")
PY
}
burst "x86-64, $(nproc) cores" "$n" --phyllo "$tmp/x86/bin/phyllo"
if [ "$emulated_n" -gt 0 ] && [ -x "$arm/bin/phyllo" ]; then
  # The same short burst on x86 too, to tell a longer burst's growth from emulation's.
  burst "x86-64, $(nproc) cores" "$emulated_n" --phyllo "$tmp/x86/bin/phyllo"
  burst "aarch64 under qemu-aarch64 (emulated)" "$emulated_n" --phyllo "$arm/bin/phyllo" \
    --qemu /usr/aarch64-linux-gnu --timeout 7200
fi
