"""Re-score `phyllo eval --dataset ... --per-image` output under another truth rule.

`phyllo eval` counts as truth the leaves of at least --truth-min-pixels in
the label (default 1: every visible leaf; 96 until session 5). This reads
its per-image lines and the dataset manifest and prints the count metrics against *every* visible leaf instance
(the manifest's ``visible_leaf_count``), so the two rules can be compared on
the same predictions, and the metrics against every visible leaf by plant
age (seedlings are where counting is hardest)::

    phyllo eval --dataset DIR --split val --per-image > per_image.txt
    python -m phyllo_train.tools.truth_rules --dataset DIR per_image.txt [--tip-gaps 4,8,16]

``--tip-gaps`` adds the rule human annotators follow on the real frames
(``leaf_tips.csv``: a leaf counts when its tip is seen, or cut by the image's
edge): truth is the number of leaves whose tip gap (the manifest's
``leaf_tip_gaps``, the distance from the projected blade tip to the nearest
pixel of that leaf; phyllo-gen since session 15) is at most each given number
of image pixels. ``--person`` adds the tip rule the tip head trains on
(:mod:`phyllo_train.tip_truth`: each seen tip, coinciding tips once) and the
same without the leaves still furled in the whorl.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..dataset import read_manifest
from ..tip_truth import MAX_TIP_GAP, open_count, person_count


# Seedlings, young plants, grown plants.
AGE_BINS = ((0.0, 25.0), (25.0, 40.0), (40.0, float("inf")))


def parse_per_image(lines) -> dict[str, tuple[int, int]]:
    """``{image path: (true, predicted)}`` from eval's tab-separated per-image lines."""
    out = {}
    for line in lines:
        parts = line.rstrip("\n").split("\t")
        if len(parts) < 4 or not parts[2].startswith("true ") or not parts[3].startswith("predicted "):
            continue
        out[parts[0]] = (int(parts[2][5:]), int(parts[3][10:]))
    return out


def metrics(truth: np.ndarray, pred: np.ndarray) -> dict[str, float]:
    """Exact, within one, RMSE, MAE and bias of predicted counts."""
    err = pred.astype(np.float64) - truth
    return {"images": len(err), "exact": float((err == 0).mean()), "within1": float((np.abs(err) <= 1).mean()),
            "rmse": float(np.sqrt((err ** 2).mean())), "mae": float(np.abs(err).mean()), "bias": float(err.mean())}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", type=Path, required=True, help="the phyllo-gen dataset that was evaluated")
    ap.add_argument("per_image", type=Path, help="saved output of phyllo eval --per-image")
    ap.add_argument("--tip-gaps", default="", help="comma-separated largest tip gaps (image pixels) for the "
                    "visible-tip rule, e.g. 4,8,16")
    ap.add_argument("--person", action="store_true",
                    help=f"add the person's tip rule (tip gap <= {MAX_TIP_GAP:g} px), and it without furled leaves")
    args = ap.parse_args(argv)
    gap_limits = [float(g) for g in args.tip_gaps.split(",") if g.strip()]
    with open(args.per_image, encoding="utf-8") as f:
        scored = parse_per_image(f)
    if not scored:
        raise SystemExit(f"{args.per_image}: no per-image lines (was --per-image given?)")
    by_image = {str(args.dataset / r["image"]): r for r in read_manifest(args.dataset)}
    countable, visible, pred, age, gaps, person, opened = [], [], [], [], [], [], []
    for path, (t, p) in scored.items():
        row = by_image.get(path) or by_image.get(str(Path(path)))
        if row is None:
            raise SystemExit(f"{path}: not in {args.dataset / 'manifest.jsonl'}")
        countable.append(t)
        visible.append(int(row["visible_leaf_count"]))
        pred.append(p)
        age.append(float(row.get("age_days", "nan")))
        person.append(person_count(row))
        opened.append(open_count(row))
        if gap_limits:
            if not row.get("leaf_tip_gaps") and int(row["visible_leaf_count"]) > 0:
                raise SystemExit(f"{path}: the manifest has no leaf_tip_gaps (written before phyllo-gen had them); "
                                 "regenerate the dataset")
            gaps.append(list(row.get("leaf_tip_gaps", {}).values()))
    pred_a = np.asarray(pred)
    rules = [("as phyllo eval ran (--truth-min-pixels)", countable), ("every visible leaf", visible)]
    rules += [(f"leaves whose tip is seen (tip gap <= {g:g} px)", [sum(x <= g for x in gs) for gs in gaps])
              for g in gap_limits]
    if args.person:
        rules.append(("tips a person would click (phyllo_train.tip_truth)", person))
        rules.append(("the same, expanded leaves only (no leaf furled in the whorl)", opened))
    print("| truth rule | images | exact | within ±1 | RMSE | MAE | bias |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, t in rules:
        m = metrics(np.asarray(t), pred_a)
        print(f"| {name} | {m['images']} | {100 * m['exact']:.1f}% | {100 * m['within1']:.1f}% | "
              f"{m['rmse']:.3f} | {m['mae']:.3f} | {m['bias']:+.3f} |")
    if gap_limits:
        all_gaps = np.asarray([g for gs in gaps for g in gs], dtype=np.float64)
        if all_gaps.size:
            q = np.quantile(all_gaps, [0.1, 0.25, 0.5, 0.75, 0.9, 0.95])
            print()
            print(f"tip gaps of {all_gaps.size} leaves (px): 10th / 25th / 50th / 75th / 90th / 95th percentile "
                  + " / ".join(f"{v:.1f}" for v in q))
    age_a, vis_a = np.asarray(age), np.asarray(visible)
    print()
    print("| plant age (days), every visible leaf | images | exact | within ±1 | RMSE | MAE | bias |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for lo, hi in AGE_BINS:
        sel = (age_a >= lo) & (age_a < hi)
        if not sel.any():
            continue
        m = metrics(vis_a[sel], pred_a[sel])
        name = f"{lo:g}–{hi:g}" if np.isfinite(hi) else f">= {lo:g}"
        print(f"| {name} | {m['images']} | {100 * m['exact']:.1f}% | {100 * m['within1']:.1f}% | "
              f"{m['rmse']:.3f} | {m['mae']:.3f} | {m['bias']:+.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
