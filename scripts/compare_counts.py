#!/usr/bin/env python3
"""Compares two models' per-image counts on one set (two `phyllo eval
--per-image` outputs): how many counts change, each model's exact agreement
(with a 95 % Wilson interval), within ±1, RMSE and bias, and a two-sided sign
test on which counts closer to the truth. With --split, real images are also
split by experiment (`81-*` 2018, `402-*` 2019).

    scripts/compare_counts.py LABEL A_OUTPUT B_OUTPUT [--split]

Prints markdown table rows (no header): one for the whole set, then one per
experiment. `load` and `closer` also serve scripts/compare-models.sh.
"""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path

from eval_json import wilson

LINE = re.compile(r"(\S+)\t\S+\ttrue (\d+)\tpredicted (\d+)")


def load(path: str) -> tuple[str, dict[str, tuple[int, int]]]:
    """The model's name and each image's (true, predicted) count."""
    name, rows = "?", {}
    for line in open(path):
        if line.startswith("model"):
            name = line.split()[1]
        m = LINE.match(line)
        if m:
            rows[m[1]] = (int(m[2]), int(m[3]))
    return name, rows


def closer(a: dict, b: dict, keys) -> tuple[int, int, float]:
    """On how many images each counts closer to the truth, and the two-sided
    sign test's p on those."""
    err = lambda rows, k: abs(rows[k][1] - rows[k][0])  # noqa: E731
    wa = sum(err(a, k) < err(b, k) for k in keys)
    wb = sum(err(b, k) < err(a, k) for k in keys)
    n, k = wa + wb, min(wa, wb)
    p = min(1.0, 2 * sum(math.comb(n, i) for i in range(k + 1)) / 2**n) if n else 1.0
    return wa, wb, p


def summary(rows: dict[str, tuple[int, int]], keys: list[str]) -> str:
    e = [rows[k][1] - rows[k][0] for k in keys]
    n = len(e)
    exact = sum(x == 0 for x in e)
    interval = wilson(exact, n)
    lo, hi = interval["lo"], interval["hi"]
    rmse = math.sqrt(sum(x * x for x in e) / n)
    return (f"{100 * exact / n:.0f}% [{100 * lo:.0f}, {100 * hi:.0f}] / "
            f"{100 * sum(abs(x) <= 1 for x in e) / n:.0f}% / {rmse:.2f} / {sum(e) / n:+.2f}")


def row(label: str, a: dict, b: dict, keys: list[str]) -> str:
    changed = sum(a[k][1] != b[k][1] for k in keys)
    wa, wb, p = closer(a, b, keys)
    return (f"| {label} | {len(keys)} | {changed} ({100 * changed / len(keys):.0f}%) | "
            f"{summary(a, keys)} | {summary(b, keys)} | {wa} / {wb}, p = {p:.2f} |")


def main() -> int:
    if len(sys.argv) < 4:
        print(__doc__, file=sys.stderr)
        return 2
    label, (_, a), (_, b) = sys.argv[1], load(sys.argv[2]), load(sys.argv[3])
    keys = sorted(a)
    if not keys or set(keys) != set(b):
        print(f"{label}: the two outputs count different images ({len(a)} and {len(b)})", file=sys.stderr)
        return 1
    print(row(label, a, b, keys))
    if "--split" in sys.argv[4:]:
        for exp in ("81", "402"):
            part = [k for k in keys if Path(k).name.startswith(f"{exp}-")]
            if part:
                print(row(f"  {exp}-*", a, b, part))
    return 0


if __name__ == "__main__":
    sys.exit(main())
