#!/usr/bin/env bash
# The ARM build, tested under emulation: cross-builds the aarch64 tree
# (scripts/build-aarch64.sh), runs it under qemu-aarch64 on the three samples
# and four development images, checks that it counts exactly what the x86
# build counts, then runs `phyllo serve` under emulation, drops a sample in,
# waits for its count in the database and stops it with SIGTERM (a clean stop
# is exit 0). CI runs it after the test command (.ci/run); it takes about 15
# minutes on a 2-core machine, most of it the cross build.
#
#   scripts/test-aarch64.sh
#
# Installs what it lacks (as root, with apt-get): qemu-user 8 or newer, from
# the distribution's backports suite where the release's own is older
# (bookworm's 7.2 crashes in ONNX Runtime's CPU detection), and, through
# build-aarch64.sh, the Rust target and Debian's cross compiler.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
sysroot=/usr/aarch64-linux-gnu
tree=out/aarch64

qemu_major() {
  command -v qemu-aarch64 >/dev/null || { echo 0; return; }
  qemu-aarch64 --version | sed -n 's/^qemu-aarch64 version \([0-9]*\).*/\1/p'
}

# The first Debian mirror this machine's apt already uses.
debian_mirror() {
  cat /etc/apt/sources.list.d/*.sources /etc/apt/sources.list 2>/dev/null |
    grep -oE 'https?://[^ ]*/debian/?( |$)' | head -1 | tr -d ' ' || true
}

if (($(qemu_major) < 8)); then
  echo "== qemu-user 8 or newer (backports)"
  . /etc/os-release
  suite="$VERSION_CODENAME-backports"
  if ! grep -rqs "$suite" /etc/apt/sources.list /etc/apt/sources.list.d/; then
    mirror=$(debian_mirror)
    cat >/etc/apt/sources.list.d/phyllo-backports.sources <<EOF
Types: deb
URIs: ${mirror:-http://deb.debian.org/debian/}
Suites: $suite
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
EOF
  fi
  apt-get update -qq
  apt-get install -y -qq -t "$suite" qemu-user >/dev/null
fi
qemu-aarch64 --version | head -1

scripts/build-aarch64.sh "$tree"

echo "== x86 build (the reference counts)"
cargo build --locked -q -p phyllo
x86=target/debug/phyllo

dev=${PHYLLO_DEV_DATA:-../shared/data/unl-maize-dev}
images=(docs/samples/*.jpg)
if [ -d "$dev/images" ]; then
  mapfile -t more < <(ls "$dev"/images/81-*.jpg | head -2; ls "$dev"/crops/*.jpg | head -2)
  images+=("${more[@]}")
fi

echo "== phyllo count on ${#images[@]} images, x86 and aarch64 (emulated)"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$x86" count --json "${images[@]}" >"$work/x86.json"
start=$(date +%s)
qemu-aarch64 -L "$sysroot" "$tree/bin/phyllo" count --json "${images[@]}" >"$work/arm.json"
emulated_s=$(($(date +%s) - start))

echo "== phyllo serve under emulation: one sample dropped, then SIGTERM"
python3 scripts/serve_burst.py --phyllo "$tree/bin/phyllo" --qemu "$sysroot" \
  --images "${images[0]}" --timeout 900 >"$work/serve.json"
cat "$work/serve.json"

python3 - "$work" "${images[0]}" "$emulated_s" <<'PY'
import json, pathlib, sys
work, first, seconds = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]).name, int(sys.argv[3])

def counts(path):
    # `count --json` prints one object per image.
    out = {}
    for line in path.read_text().splitlines():
        if line.strip():
            o = json.loads(line)
            out[pathlib.Path(o["file"]).name] = (o.get("leaf_count"), o.get("tiles"), o.get("scale"))
    return out

x86, arm = counts(work / "x86.json"), counts(work / "arm.json")
bad = [f"{k}: x86 {x86[k]} arm {arm.get(k)}" for k in x86 if arm.get(k) != x86[k]]
if not x86 or bad or set(arm) != set(x86):
    sys.exit("aarch64 counts differ from x86 (leaves, tiles, scale):\n  " + "\n  ".join(bad or ["different files"]))
serve = json.loads((work / "serve.json").read_text())
if serve["exit_code"] != 0 or serve["counted"] != 1:
    sys.exit(f"phyllo serve under emulation: {serve}")
if serve["counts"].get(first) != x86[first][0]:
    sys.exit(f"serve counted {serve['counts'].get(first)} leaves in {first}, x86 count says {x86[first][0]}")
tiles = sum(t for _, t, _ in arm.values())
print(f"aarch64 (emulated): {len(arm)} images ({tiles} tiles) counted exactly as on x86 (leaves, tiles, scale) "
      f"in {seconds} s, {seconds / tiles:.0f} s a tile emulated; serve counted {first} "
      f"({serve['counts'][first]} leaves) and stopped cleanly on SIGTERM, peak RSS {serve['peak_rss_mb']:.0f} MB under qemu")
PY
