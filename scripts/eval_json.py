#!/usr/bin/env python3
"""Turns one `phyllo eval --json` object (on stdin) into the scripts' table rows.

    phyllo eval --json ... | scripts/eval_json.py row LABEL [NOTE]
    phyllo eval --json ... | scripts/eval_json.py intervals LABEL
    phyllo eval --json ... | scripts/eval_json.py field KEY

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


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] not in ("row", "intervals", "field"):
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
    else:
        print(v[argv[1]])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
