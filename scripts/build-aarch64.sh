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
# library, which inference/build.rs takes from PyPI's onnxruntime wheel for
# the target's architecture (manylinux_2_28_aarch64; the same version the x86
# build provisions).
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

echo "== cargo build --release --target $target"
# inference/build.rs takes ONNX Runtime's ARM library from PyPI's onnxruntime
# wheel (manylinux_2_28_aarch64) for this target; PHYLLO_ORT_CACHE keeps it in
# .whl/aarch64/, where the tree below copies it from.
export PHYLLO_ORT_CACHE="$root/.whl"
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
export CC_aarch64_unknown_linux_gnu=aarch64-linux-gnu-gcc
export AR_aarch64_unknown_linux_gnu=aarch64-linux-gnu-ar
cargo build --release --locked --target "$target" -p phyllo -p phyllo-gen
lib="$PHYLLO_ORT_CACHE/aarch64/libonnxruntime.so.$ort"
[ -e "$lib" ] || { echo "build-aarch64: no $lib: the build could not fetch ONNX Runtime's ARM wheel from PyPI (see its warning above)" >&2; exit 1; }
file -L "$lib" | grep -q aarch64 || { echo "build-aarch64: $lib is not an ARM library" >&2; exit 1; }

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
# The box's C library must be at least the newest version the binaries ask for.
glibc=$(aarch64-linux-gnu-objdump -T "$out/bin/phyllo" "$out/lib/phyllo/libonnxruntime.so" |
  grep -o 'GLIBC_[0-9.]*' | sort -t. -k2,2n -u | tail -1)
echo "needs ${glibc/_/ } or newer on the box"
du -sh "$out" "$out.tar.gz"
