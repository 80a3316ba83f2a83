#!/usr/bin/env bash
# The README's test command: every test in the workspace, end-to-end ones
# included, then the training code's tests (models/tests) in a virtual
# environment made from models/requirements.txt (PyPI only; about 5.5 GB the
# first time, reused after; no pip cache, which would add 3 GB more).
# PHYLLO_SKIP_PYTHON=1 runs the Rust tests only.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --workspace --locked "$@"

if [[ "${PHYLLO_SKIP_PYTHON:-0}" == 1 ]]; then
  echo "PHYLLO_SKIP_PYTHON=1: training code tests skipped"
  exit 0
fi
venv=models/.venv
stamp="$venv/.requirements"
if ! cmp -s models/requirements.txt "$stamp" 2>/dev/null; then
  echo "== training environment ($venv, from models/requirements.txt)"
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install -q --no-cache-dir --disable-pip-version-check -r models/requirements.txt
  cp models/requirements.txt "$stamp"
fi
echo "== training code tests (models/tests)"
(cd models && .venv/bin/python -m pytest -q tests)
