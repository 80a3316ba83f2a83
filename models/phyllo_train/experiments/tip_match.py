"""Predicted leaf tips against the tips people marked on real frames.

    target/release/phyllo count --json --model MODEL IMAGES... > counts.jsonl
    python -m phyllo_train.experiments.tip_match --tips ../shared/data/unl-maize-dev/leaf_tips.csv --counts counts.jsonl
    python -m phyllo_train.experiments.tip_match --dataset DIR --split val --counts counts.jsonl   # phyllo-gen leaf_tips

``phyllo count --json`` lists a tip model's tip peaks (``tips``: x, y, score
in image pixels). Each marked tip (``tips_xy``) is matched one to one to a
predicted tip within ``--radius`` pixels, nearest pairs first. A marked tip
without a partner is missed, a predicted tip without one is extra. This says
how well the tip head, trained on synthetic tips only, finds real ones,
independently of how the counts come out.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np


def match_tips(marked: np.ndarray, predicted: np.ndarray, radius: float) -> tuple[int, int, int]:
    """(matched, missed, extra): greedy one-to-one matching, nearest pairs first, within ``radius``."""
    marked = np.asarray(marked, np.float64).reshape(-1, 2)
    predicted = np.asarray(predicted, np.float64).reshape(-1, 2)
    if len(marked) == 0 or len(predicted) == 0:
        return 0, len(marked), len(predicted)
    d = np.linalg.norm(marked[:, None, :] - predicted[None, :, :], axis=2)
    pairs = sorted((d[i, j], i, j) for i in range(len(marked)) for j in range(len(predicted)) if d[i, j] <= radius)
    used_m, used_p = set(), set()
    for _, i, j in pairs:
        if i not in used_m and j not in used_p:
            used_m.add(i)
            used_p.add(j)
    n = len(used_m)
    return n, len(marked) - n, len(predicted) - n


def read_marked(path: Path) -> dict[str, np.ndarray]:
    """``file -> (K, 2)`` marked tips of a ``leaf_tips.csv``."""
    with open(path, newline="", encoding="utf-8") as f:
        return {r["file"]: np.array(json.loads(r["tips_xy"]), np.float64).reshape(-1, 2) for r in csv.DictReader(f)}


def read_dataset_tips(root: Path, split: str) -> dict[str, np.ndarray]:
    """``image file name -> (K, 2)`` apparent tips of a phyllo-gen dataset's ``split`` (its ``leaf_tips``)."""
    from ..dataset import read_manifest

    return {Path(r["image"]).name: np.array(list(r.get("leaf_tips", {}).values()), np.float64).reshape(-1, 2)
            for r in read_manifest(root, split)}


def read_counts(path: Path) -> dict[str, dict]:
    """``image file name -> record`` of ``phyllo count --json`` lines; an image that failed is reported and left out."""
    out = {}
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        rec = json.loads(line)
        if "error" in rec:
            print(f"{path}:{n}: {rec['file']}: {rec['error']}", file=sys.stderr)
            continue
        out[Path(rec["file"]).name] = rec
    return out


def main(argv: list[str] | None = None) -> int:
    """CLI entry point: one row per radius, summed over the images both files name."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.experiments.tip_match", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--tips", type=Path, help="leaf_tips.csv (file, ..., tips_xy)")
    src.add_argument("--dataset", type=Path, help="a phyllo-gen dataset whose manifest has leaf_tips")
    ap.add_argument("--split", default="val", help="with --dataset: the split (default val)")
    ap.add_argument("--counts", type=Path, required=True, help="`phyllo count --json` output (JSON lines)")
    ap.add_argument("--radius", type=float, action="append", help="match radius in image pixels (repeatable; default 6 12 24 40)")
    args = ap.parse_args(argv)
    marked = read_marked(args.tips) if args.tips else read_dataset_tips(args.dataset, args.split)
    predicted = {name: np.array([t[:2] for t in rec.get("tips", [])], np.float64).reshape(-1, 2)
                 for name, rec in read_counts(args.counts).items()}
    files = sorted(set(marked) & set(predicted))
    if not files:
        print(f"no image of {args.counts} is in {args.tips or args.dataset}", file=sys.stderr)
        return 1
    print(f"{len(files)} images, {sum(len(marked[f]) for f in files)} marked tips, "
          f"{sum(len(predicted[f]) for f in files)} predicted tips")
    print("| radius (px) | matched | missed | extra | recall | precision |")
    print("|---:|---:|---:|---:|---:|---:|")
    for r in args.radius or [6.0, 12.0, 24.0, 40.0]:
        m, mi, ex = (sum(v) for v in zip(*(match_tips(marked[f], predicted[f], r) for f in files)))
        print(f"| {r:g} | {m} | {mi} | {ex} | {m / max(m + mi, 1):.3f} | {m / max(m + ex, 1):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
