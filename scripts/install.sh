#!/usr/bin/env bash
# Installs phyllo: the binary, the model, the ONNX Runtime library, the docs
# and the example config under PREFIX, where the binary's own search paths
# look (PREFIX/share/phyllo/phyllo.onnx and phyllo-top.onnx, PREFIX/lib/phyllo/libonnxruntime.so),
# so the installed `phyllo` counts from any directory with any HOME; then,
# unless --no-systemd, the units (pointed at PREFIX/bin/phyllo), the system
# user and /etc/phyllo/phyllo.toml (kept if it exists). docs/daemon.md,
# "Install", runs it with sudo.
#
# Usage: scripts/install.sh [--prefix DIR] [--bin FILE] [--no-build] [--no-systemd]
#   --prefix DIR   where to install (default /usr/local)
#   --bin FILE     install this phyllo binary (default: target/release/phyllo, built first)
#   --no-build     do not run cargo build (with the default binary: it must exist)
#   --no-systemd   only PREFIX: no units, user or /etc config (a test, or a user install)
# Environment: PHYLLO_ORT_LIB [the ONNX Runtime library to install; default:
#   the copy the build provisioned in ${XDG_CACHE_HOME:-~/.cache}/phyllo].
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
prefix=/usr/local bin="" build=1 systemd=1
while [ $# -gt 0 ]; do
  case $1 in
    --prefix) prefix=$2; shift 2 ;;
    --bin) bin=$2; build=0; shift 2 ;;
    --no-build) build=0; shift ;;
    --no-systemd) systemd=0; shift ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    *) echo "install.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
if [ -z "$bin" ]; then
  bin=$root/target/release/phyllo
  [ "$build" = 0 ] || (cd "$root" && cargo build --release --locked -p phyllo)
fi
[ -x "$bin" ] || { echo "install.sh: $bin is not an executable phyllo binary (build it, or give --bin)" >&2; exit 1; }
ver=$(sed -n 's/^const ORT_VERSION: &str = "\(.*\)";/\1/p' "$root/inference/build.rs")
# Under sudo, the build's cache is the invoking user's, not root's.
home=$HOME
[ -z "${SUDO_USER:-}" ] || home=$(getent passwd "$SUDO_USER" | cut -d: -f6)
cache=${PHYLLO_ORT_CACHE:-${XDG_CACHE_HOME:-$home/.cache}/phyllo/onnxruntime-$ver}
ort=${PHYLLO_ORT_LIB:-$cache/libonnxruntime.so.$ver}
if [ ! -f "$ort" ] && [ -z "${PHYLLO_ORT_LIB:-}" ]; then
  # A build without a cache directory (no HOME) keeps its copy in its OUT_DIR.
  for f in "$root"/target/*/build/phyllo-inference-*/out/onnxruntime/libonnxruntime.so."$ver"; do
    [ -f "$f" ] && ort=$f && break
  done
fi
[ -f "$ort" ] || {
  echo "install.sh: ONNX Runtime $ver not found at $ort: cargo build provisions it there; or set PHYLLO_ORT_LIB" >&2
  exit 1
}

install -D -m 0755 "$bin" "$prefix/bin/phyllo"
# The release profile keeps line tables for readable backtraces while
# developing: 80 of the binary's 100 MB, which an installed service does not
# need. Symbol names stay. Another architecture's binary is left to its own
# strip (scripts/build-aarch64.sh).
strip --strip-debug "$prefix/bin/phyllo" 2>/dev/null || true
install -D -m 0644 "$root/models/phyllo.onnx" "$prefix/share/phyllo/phyllo.onnx"
# The top-view model, found beside the side-view model ([inference.top_views]).
if [ -e "$root/models/phyllo-top.onnx" ]; then
  install -D -m 0644 "$root/models/phyllo-top.onnx" "$prefix/share/phyllo/phyllo-top.onnx"
fi
install -D -m 0644 "$ort" "$prefix/lib/phyllo/libonnxruntime.so.$ver"
ln -sf "libonnxruntime.so.$ver" "$prefix/lib/phyllo/libonnxruntime.so"
install -D -m 0644 "$root/systemd/phyllo.toml.example" "$prefix/share/phyllo/phyllo.toml.example"
install -D -m 0644 "$root/docs/daemon.md" "$prefix/share/doc/phyllo/daemon.md"
echo "installed phyllo, its model and ONNX Runtime $ver under $prefix"

[ "$systemd" = 1 ] || exit 0
units=(phyllo.service phyllo-export.service phyllo-export.timer phyllo-backup.service
  phyllo-backup.timer phyllo-import.service phyllo-import.timer)
for u in "${units[@]}"; do
  sed -e "s|/usr/local/bin/phyllo|$prefix/bin/phyllo|g" -e "s|/usr/local/share/doc/phyllo|$prefix/share/doc/phyllo|g" \
    "$root/systemd/$u" >"/etc/systemd/system/$u"
  chmod 0644 "/etc/systemd/system/$u"
done
install -D -m 0644 "$root/systemd/phyllo.sysusers" /usr/lib/sysusers.d/phyllo.conf
systemd-sysusers
install -d -m 0755 /etc/phyllo
if [ -e /etc/phyllo/phyllo.toml ]; then
  echo "kept /etc/phyllo/phyllo.toml (the new example is $prefix/share/phyllo/phyllo.toml.example)"
else
  install -m 0644 "$root/systemd/phyllo.toml.example" /etc/phyllo/phyllo.toml
  echo "wrote /etc/phyllo/phyllo.toml: set drop_dir and database, then: systemctl enable --now phyllo.service"
fi
if [ -d /run/systemd/system ]; then
  systemctl daemon-reload
  echo "installed the units in /etc/systemd/system (enable them as docs/daemon.md says)"
else
  # A container or an image build: everything is installed; the units load
  # when systemd next starts.
  echo "installed the units in /etc/systemd/system; systemd is not running here, so no daemon-reload (they load at its next start)"
fi
