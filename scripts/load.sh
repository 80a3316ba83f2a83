#!/usr/bin/env bash
# The full load run: a burst of 10,000 files into a running `phyllo serve`
# (release build), all processed once, peak RSS reported and checked.
# CI runs the same test with 1000 files in the debug build.
#   PHYLLO_LOAD_FILES (10000)  PHYLLO_LOAD_COUNT_EVERY (25)  PHYLLO_LOAD_MAX_RSS_MB (300)
set -euo pipefail
cd "$(dirname "$0")/.."
export PHYLLO_LOAD_FILES="${PHYLLO_LOAD_FILES:-10000}"
exec nice -n 10 cargo test --release --locked -p phyllo --test load -- --nocapture "$@"
