#!/usr/bin/env python3
"""Turns one `phyllo eval --json` object (on stdin) into the scripts' table rows.

    phyllo eval --json ... | scripts/eval_json.py row LABEL [NOTE]
    phyllo eval --json ... | scripts/eval_json.py intervals LABEL
    phyllo eval --json ... | scripts/eval_json.py field KEY
    phyllo eval --json --per-image ... | scripts/eval_json.py subset LABEL VIEW[,VIEW...] | side | top

`row` prints `| LABEL | images | exact | within ±1 | RMSE | MAE | bias | R² |`
(and a last `NOTE |` cell when given) with the numbers formatted as `phyllo
eval`'s own table prints them; `intervals` prints `| LABEL | exact | within ±1 |
RMSE | bias |` with each 95 % interval; `field` prints one top-level value
(`fingerprint`, `model`, ...). The scripts read the JSON rather than the text
tables, so a change to the tables' layout cannot shift their columns. Standard
library only: any python3 runs it.
"""

from __future__ import annotations

import json
import sys


def row(v: dict, label: str, note: str | None) -> str:
    m = v["metrics"]
    cells = [label, str(m["images"]), f"{100 * m['exact']:.1f}%", f"{100 * m['within_1']:.1f}%",
             f"{m['rmse']:.3f}", f"{m['mae']:.3f}", f"{m['bias']:+.3f}", f"{m['r2']:.3f}"]
    if note is not None:
        cells.append(note)
    return "| " + " | ".join(cells) + " |"


def intervals(v: dict, label: str) -> str:
    i = v.get("intervals")
    if not i:
        return f"| {label} | | | | |"
    share = lambda k: f"[{100 * i[k]['lo']:.1f}, {100 * i[k]['hi']:.1f}] %"  # noqa: E731
    return (f"| {label} | {share('exact')} | {share('within_1')} | [{i['rmse']['lo']:.3f}, {i['rmse']['hi']:.3f}] "
            f"| [{i['bias']['lo']:+.3f}, {i['bias']['hi']:+.3f}] |")


def wilson(k: int, n: int, z: float = 1.96) -> dict:
    """95 % Wilson score interval of the share k/n."""
    if n == 0:
        return {"lo": 0.0, "hi": 0.0}
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * ((p * (1 - p) / n + z * z / (4 * n * n)) ** 0.5) / d
    return {"lo": max(0.0, c - h), "hi": min(1.0, c + h)}


def subset(v: dict, views: str) -> dict:
    """The metrics and intervals of the `images` (from --per-image) of some views, as `phyllo eval`
    reports them for all: `side` is every view but the top, `top` the top view. RMSE and bias
    intervals by bootstrap over images (2000 resamples, seed 0)."""
    import random

    if "images" not in v:
        raise SystemExit("eval_json.py subset: run phyllo eval with --per-image")
    if views == "side":
        keep = lambda view: view != "top"  # noqa: E731
    else:
        wanted = set(views.split(","))
        keep = lambda view: view in wanted  # noqa: E731
    errs = [p["predicted"] - p["truth"] for p in v["images"] if keep(str(p["view"]))]
    n = len(errs)
    if n == 0:
        return {"metrics": {"images": 0, "exact": 0, "within_1": 0, "rmse": 0, "mae": 0, "bias": 0, "r2": 0}}
    rmse = lambda e: (sum(x * x for x in e) / len(e)) ** 0.5  # noqa: E731
    bias = lambda e: sum(e) / len(e)  # noqa: E731
    truths = [p["truth"] for p in v["images"] if keep(str(p["view"]))]
    mt = sum(truths) / n
    ss = sum((t - mt) ** 2 for t in truths)
    exact, within = sum(e == 0 for e in errs), sum(abs(e) <= 1 for e in errs)
    rng = random.Random(0)
    boots = [[errs[rng.randrange(n)] for _ in range(n)] for _ in range(2000)]
    q = lambda xs: {"lo": sorted(xs)[int(0.025 * len(xs))], "hi": sorted(xs)[int(0.975 * len(xs)) - 1]}  # noqa: E731
    return {
        "metrics": {"images": n, "exact": exact / n, "within_1": within / n, "rmse": rmse(errs),
                    "mae": sum(abs(e) for e in errs) / n, "bias": bias(errs),
                    "r2": 1 - sum(e * e for e in errs) / ss if ss else 0.0},
        "intervals": {"exact": wilson(exact, n), "within_1": wilson(within, n),
                      "rmse": q([rmse(b) for b in boots]), "bias": q([bias(b) for b in boots])},
    }


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] not in ("row", "intervals", "field", "subset"):
        print(__doc__, file=sys.stderr)
        return 2
    text = sys.stdin.read()
    try:
        v = json.loads(text)
    except json.JSONDecodeError:
        print(f"eval_json.py: phyllo eval printed no JSON object: {text[:200]!r}", file=sys.stderr)
        return 1
    if argv[0] == "row":
        print(row(v, argv[1], argv[2] if len(argv) > 2 else None))
    elif argv[0] == "intervals":
        print(intervals(v, argv[1]))
    elif argv[0] == "subset":
        part = subset(v, argv[2])
        print(row(part, argv[1], None))
        print(intervals(part, argv[1]))
    else:
        print(v[argv[1]])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
