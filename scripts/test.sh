#!/usr/bin/env bash
# The README's test command: every test in the workspace, end-to-end ones
# included, then the training code's tests (models/tests) in a virtual
# environment made from models/requirements.txt (PyPI only; about 5.5 GB the
# first time, reused after; no pip cache, which would add 3 GB more).
# PHYLLO_SKIP_PYTHON=1 runs the Rust tests only. The last line sums up both.
set -euo pipefail
cd "$(dirname "$0")/.."
log=$(mktemp -d)
trap 'rm -rf "$log"' EXIT

rust_rc=0
cargo test --workspace --locked "$@" 2>&1 | tee "$log/rust" || rust_rc=$?
# One "test result: ok. 9 passed; 0 failed; 0 ignored; ..." line per test binary.
rust=$(awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i; if ($(i+1) ~ /^ignored/) g += $i } }
  END { printf "%d passed, %d failed, %d ignored", p, f, g }' "$log/rust")

py_rc=0
python="Python skipped (PHYLLO_SKIP_PYTHON=1)"
if [[ "${PHYLLO_SKIP_PYTHON:-0}" != 1 ]]; then
  venv=models/.venv
  stamp="$venv/.requirements"
  if ! cmp -s models/requirements.txt "$stamp" 2>/dev/null; then
    echo "== training environment ($venv, from models/requirements.txt): pip installs torch and the rest, about 5.5 GB; a few quiet minutes the first time"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install -q --no-cache-dir --disable-pip-version-check -r models/requirements.txt
    cp models/requirements.txt "$stamp"
  fi
  echo "== training code tests (models/tests)"
  (cd models && .venv/bin/python -m pytest -q tests) 2>&1 | tee "$log/python" || py_rc=$?
  # pytest's last line: "115 passed, 2 skipped in 61.2s" (or "1 failed, 114 passed ...").
  python=$(tail -1 "$log/python" | grep -oE '[0-9]+ (passed|failed|skipped|error|errors)' | paste -sd, - | sed 's/,/, /g')
  python="Python ${python:-no result}"
fi

if [[ $rust_rc == 0 && $py_rc == 0 ]]; then verdict="all passed"; else verdict="FAILED"; fi
echo "phyllo tests: Rust $rust; $python: $verdict"
[[ $rust_rc == 0 && $py_rc == 0 ]]
