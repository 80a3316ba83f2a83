#!/usr/bin/env bash
# Cross-builds phyllo for a 64-bit ARM box beside the imaging station (a
# Jetson, a Raspberry Pi 5, an Ampere or Graviton server) and lays out an
# installable tree as `scripts/install.sh --prefix` does, plus a tarball:
#
#   scripts/build-aarch64.sh [OUT]        (default out/aarch64)
#
# OUT/bin/phyllo and phyllo-gen, OUT/share/phyllo/ (the side and top models,
# the example config, the units), OUT/lib/phyllo/libonnxruntime.so (ARM), and
# OUT.tar.gz; copy the tree to the box's /usr/local (or any prefix) and set up
# the unit as docs/daemon.md says for x86.
#
# Installs what it needs where it is missing: the Rust target (rustup), the
# cross linker and C compiler for the bundled SQLite (Debian's
# gcc-aarch64-linux-gnu, with apt-get: run as root), and ONNX Runtime's ARM
# library, taken from PyPI's onnxruntime wheel for manylinux_2_28_aarch64 (the
# same version the x86 build provisions). The build sets PHYLLO_ORT_NO_FETCH,
# so inference/build.rs does not fetch the x86 library for it.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
out=$(realpath -m "${1:-out/aarch64}")
target=aarch64-unknown-linux-gnu
ort=$(sed -n 's/^const ORT_VERSION: &str = "\(.*\)";/\1/p' inference/build.rs)

echo "== toolchain for $target"
rustup target list --installed | grep -qx "$target" || rustup target add "$target"
if ! command -v aarch64-linux-gnu-gcc >/dev/null; then
  apt-get update -qq && apt-get install -y -qq gcc-aarch64-linux-gnu libc6-dev-arm64-cross
fi

echo "== ONNX Runtime $ort for aarch64 (PyPI wheel)"
wheels=.whl/aarch64
lib="$wheels/libonnxruntime.so.$ort"
if [ ! -e "$lib" ]; then
  python3 -m pip download -q --no-deps --only-binary=:all: --platform manylinux_2_28_aarch64 \
    --python-version 3.12 -d "$wheels" "onnxruntime==$ort"
  python3 - "$wheels" "$ort" <<'PY'
import pathlib, sys, zipfile
wheels, version = pathlib.Path(sys.argv[1]), sys.argv[2]
wheel = next(wheels.glob(f"onnxruntime-{version}-*aarch64*.whl"))
with zipfile.ZipFile(wheel) as z:
    name = next(n for n in z.namelist() if n.endswith(f"capi/libonnxruntime.so.{version}"))
    (wheels / f"libonnxruntime.so.{version}").write_bytes(z.read(name))
PY
fi

echo "== cargo build --release --target $target"
export PHYLLO_ORT_NO_FETCH=1
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CC_aarch64_unknown_linux_gnu=aarch64-linux-gnu-gcc
export AR_aarch64_unknown_linux_gnu=aarch64-linux-gnu-ar
cargo build --release --locked --target "$target" -p phyllo -p phyllo-gen

echo "== tree in $out"
rm -rf "$out"
PHYLLO_ORT_LIB="$lib" scripts/install.sh --prefix "$out" --bin "target/$target/release/phyllo" --no-build --no-systemd
install -D -m 0755 "target/$target/release/phyllo-gen" "$out/bin/phyllo-gen"
# The release profile keeps debug info (backtraces here); an edge box wants
# the small binaries.
aarch64-linux-gnu-strip --strip-debug "$out/bin/phyllo" "$out/bin/phyllo-gen"
for u in systemd/*.service systemd/*.timer systemd/phyllo.sysusers; do
  install -D -m 0644 "$u" "$out/share/phyllo/systemd/$(basename "$u")"
done
tar -C "$(dirname "$out")" -czf "$out.tar.gz" "$(basename "$out")"
file "$out/bin/phyllo" | sed 's/, BuildID.*//'
du -sh "$out" "$out.tar.gz"
