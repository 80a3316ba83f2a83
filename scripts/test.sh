#!/usr/bin/env bash
# The README's test command: every test in the workspace, end-to-end ones included.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --workspace --locked "$@"
