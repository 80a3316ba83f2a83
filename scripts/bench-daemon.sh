#!/usr/bin/env bash
# Performance of the daemon on full 2454x2056 PNG frames (release build):
# sustained images/s, close-to-row latency p50/p99, peak RSS, and the Python
# reference pipeline's images/s in the same run. Knobs (see
# daemon/tests/bench_daemon.rs): PHYLLO_BENCH_FRAMES, PHYLLO_BENCH_MODEL,
# PHYLLO_BENCH_LATENCY_N (20), PHYLLO_BENCH_BURST_N (40), PHYLLO_BENCH_PYTHON (python3;
# needs numpy, pillow, onnxruntime).
set -euo pipefail
cd "$(dirname "$0")/.."
exec cargo test --release --locked -p phyllo --test bench_daemon -- --ignored --nocapture "$@"
