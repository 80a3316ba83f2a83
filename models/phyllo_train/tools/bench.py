"""Measure ONNX Runtime latency per tile, as the daemon runs it (CPU provider, fixed thread count).

    python -m phyllo_train.tools.bench models/phyllo-untrained.onnx --threads 2 --batch 1 --size 512
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np


def bench(path: str, threads: int = 2, batch: int = 1, size: int = 512, runs: int = 30, warmup: int = 5,
          spin: bool = True) -> dict[str, float]:
    """Return median / p90 / min wall milliseconds per tile, and CPU milliseconds per tile.

    CPU time (all threads, this process) is robust to other processes competing
    for the cores, so it is the figure to compare on a shared machine.
    """
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = threads
    so.inter_op_num_threads = 1
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    # Spinning worker threads help on idle cores but halve throughput when other
    # processes share them (measured here: 54 -> 30 ms/tile on 2 busy cores).
    so.add_session_config_entry("session.intra_op.allow_spinning", "1" if spin else "0")
    sess = ort.InferenceSession(path, so, providers=["CPUExecutionProvider"])
    name = sess.get_inputs()[0].name
    x = np.random.default_rng(0).standard_normal((batch, 3, size, size), dtype=np.float32)
    for _ in range(warmup):
        sess.run(None, {name: x})
    times = []
    cpu0 = time.process_time()
    for _ in range(runs):
        t0 = time.perf_counter()
        sess.run(None, {name: x})
        times.append((time.perf_counter() - t0) * 1000.0 / batch)
    cpu_ms = (time.process_time() - cpu0) * 1000.0 / (runs * batch)
    times.sort()
    return {"median_ms": statistics.median(times), "p90_ms": times[int(0.9 * (len(times) - 1))], "min_ms": times[0],
            "cpu_ms": cpu_ms}


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.tools.bench", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--batch", type=int, default=1)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--no-spin", action="store_true", help="session.intra_op.allow_spinning=0 (shared cores)")
    a = ap.parse_args(argv)
    r = bench(a.model, a.threads, a.batch, a.size, a.runs, spin=not a.no_spin)
    print(f"{a.model}: {a.size}x{a.size}, batch {a.batch}, {a.threads} threads{', no spin' if a.no_spin else ''}: "
          f"median {r['median_ms']:.1f} ms/tile, p90 {r['p90_ms']:.1f}, min {r['min_ms']:.1f}; "
          f"CPU {r['cpu_ms']:.1f} ms/tile (all threads)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
