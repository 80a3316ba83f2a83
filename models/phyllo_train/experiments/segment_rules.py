"""Score rules that drop predicted leaf instances, offline, on the table
``phyllo eval --dataset DIR --segments FILE.tsv`` writes (one row per
predicted leaf: what it is against the truth, its area, score and the
border it shares with other leaf instances)::

    phyllo eval --dataset DIR --split all --segments segments.tsv
    python -m phyllo_train.experiments.segment_rules segments.tsv [more.tsv ...]

The rule scored is the one a split-off piece of a leaf suggests: drop (merge
into its neighbour) an instance whose score is below S, that shares at least
C output-pixel edges with another leaf instance, and that is no larger than
it. For each (S, C) it prints the count metrics with those instances gone,
and how many of the dropped instances really were split-off pieces (the rest
were leaves of their own). Images without any leaf instance have no row and
are left out of every line alike.
"""

from __future__ import annotations

import argparse
import csv
from collections import defaultdict

import numpy as np

SCORES = (0.3, 0.35, 0.4, 0.5)
CONTACTS = (0, 5, 10, 20, 40)


def read_rows(paths) -> list[dict]:
    """Rows of every table, numbers parsed, image names made unique per file."""
    rows = []
    for n, path in enumerate(paths):
        with open(path, newline="") as f:
            for r in csv.DictReader(f, delimiter="\t"):
                rows.append({
                    "image": f"{n}:{r['image']}",
                    "truth": int(r["truth"]),
                    "predicted": int(r["predicted"]),
                    "kind": r["kind"],
                    "area": int(r["area"]),
                    "score": float(r["score"]),
                    "max_contact": int(r["max_contact"]),
                    "neighbour_area": int(r["neighbour_area"]),
                })
    return rows


def dropped_by(score_below: float, min_contact: int):
    """The rule: a weak piece bordering a leaf instance at least its size."""
    def rule(r: dict) -> bool:
        return (r["score"] < score_below and r["max_contact"] >= min_contact
                and r["max_contact"] > 0 and r["area"] <= r["neighbour_area"])
    return rule


def score(rows: list[dict], rule) -> dict:
    """Count metrics after dropping the instances `rule` picks."""
    truth, predicted = {}, defaultdict(int)
    split = other = 0
    for r in rows:
        truth[r["image"]] = r["truth"]
        predicted[r["image"]] += 0
        if rule(r):
            predicted[r["image"]] -= 1
            split += r["kind"] == "split"
            other += r["kind"] != "split"
    base = {r["image"]: r["predicted"] for r in rows}
    err = np.array([base[i] + predicted[i] - truth[i] for i in truth], dtype=float)
    return {
        "images": len(err),
        "exact": float(np.mean(err == 0) * 100),
        "within1": float(np.mean(np.abs(err) <= 1) * 100),
        "rmse": float(np.sqrt(np.mean(err ** 2))),
        "bias": float(np.mean(err)),
        "dropped_split": split,
        "dropped_other": other,
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tables", nargs="+", help="TSV files from phyllo eval --segments")
    args = ap.parse_args(argv)
    rows = read_rows(args.tables)
    kinds = defaultdict(int)
    for r in rows:
        kinds[r["kind"]] += 1
    print("instances by kind: " + ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())))
    for key in ("score", "max_contact", "area"):
        for kind in ("split", "found"):
            v = np.array([r[key] for r in rows if r["kind"] == kind], dtype=float)
            if len(v):
                q = np.percentile(v, [10, 25, 50, 75, 90])
                print(f"{key:>12} of {kind:<6} deciles 10/25/50/75/90: " + " / ".join(f"{x:.3g}" for x in q))
    print()
    print("| score below | contact at least | images | exact | within ±1 | RMSE | bias | dropped: split pieces | dropped: leaves |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    lines = [("off", "", score(rows, lambda r: False))]
    lines += [(f"{s}", f"{c}", score(rows, dropped_by(s, c))) for s in SCORES for c in CONTACTS]
    for s, c, m in lines:
        print(f"| {s} | {c} | {m['images']} | {m['exact']:.1f} % | {m['within1']:.1f} % | {m['rmse']:.3f} | "
              f"{m['bias']:+.3f} | {m['dropped_split']} | {m['dropped_other']} |")


if __name__ == "__main__":
    main()
