"""Score leaf-count rules of a tip model offline, from one `phyllo count --json` run.

    target/release/phyllo count --json --model TIPS.onnx --tip-threshold 0.3 IMAGES... > counts.jsonl
    python -m phyllo_train.experiments.count_rules --counts counts.jsonl --dataset DIR [--split all]
    python -m phyllo_train.experiments.count_rules --counts counts.jsonl --truth crops_counts.csv

A tip model's ``count --json`` lists every tip peak above the run's tip
threshold with the leaf instance it joins (``tip_instances``). Peaks do not
depend on the threshold (they are local maxima), so a run at the lowest
threshold holds every higher threshold's tips too, and each rule below is
scored from the same run in seconds instead of one inference pass each:

- ``centres``: one leaf per leaf instance (the shipped rule);
- ``split``: each leaf instance counts the tips joining it, at least one
  and at most ``cap``;
- ``split`` with ``max_area``: only instances smaller than that (image px)
  may count more than one, since merges are of small whorl leaves;
- ``split`` with ``min_gap``: a tip closer than that (image px) to a
  stronger tip on the same instance is not another leaf.

Only ``centres`` and ``split`` at cap infinity without an area limit are
in the Rust counter; a rule that wins here goes there before it is used.
Calibrate on a synthetic set used neither for training nor for testing.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .tip_match import read_counts
from ..tools.truth_rules import metrics


NO_CAP = 1 << 30


@dataclass(frozen=True)
class Rule:
    """A count rule: ``split`` with a tip score threshold, a per-instance cap and an area limit."""

    name: str
    threshold: float = 0.0
    cap: int = NO_CAP
    max_area: float = math.inf
    min_gap: float = 0.0

    def label(self) -> str:
        """A short table label."""
        if self.name == "centres":
            return "centres"
        cap = "∞" if self.cap >= NO_CAP else str(self.cap)
        area = "∞" if math.isinf(self.max_area) else f"{self.max_area:g}"
        gap = f" gap≥{self.min_gap:g}" if self.min_gap > 0 else ""
        return f"split t={self.threshold:g} cap={cap} area<{area}{gap}"


def count(record: dict, rule: Rule) -> int:
    """The leaf count of one ``count --json`` record under ``rule``."""
    leaves = {i["id"]: i for i in record.get("instances", []) if i.get("class_name") == "leaf"}
    if rule.name == "centres":
        return len(leaves)
    # Tips come strongest first, so a weaker tip near a kept one is the one dropped.
    joined: dict[int, list[list[float]]] = {}
    for tip, inst in zip(record.get("tips", []), record.get("tip_instances", [])):
        if inst is None or inst not in leaves or tip[2] < rule.threshold:
            continue
        kept = joined.setdefault(inst, [])
        if all(math.hypot(tip[0] - k[0], tip[1] - k[1]) >= rule.min_gap for k in kept):
            kept.append(tip)
    total = 0
    for i, leaf in leaves.items():
        n = len(joined.get(i, [])) if leaf["area"] < rule.max_area else 1
        total += min(max(n, 1), rule.cap)
    return total


def read_truth(dataset: Path | None, split: str, truth_csv: Path | None) -> dict[str, int]:
    """``image file name -> true leaf count`` from a phyllo-gen manifest or a ``file,leaf_count`` CSV."""
    if truth_csv is not None:
        with open(truth_csv, newline="", encoding="utf-8") as f:
            return {Path(r["file"]).name: int(r["leaf_count"]) for r in csv.DictReader(f)}
    from ..dataset import read_manifest

    rows = read_manifest(dataset, None if split == "all" else split)
    return {Path(r["image"]).name: int(r["visible_leaf_count"]) for r in rows}


def default_rules(thresholds: list[float], caps: list[int], areas: list[float], gaps: list[float]) -> list[Rule]:
    """``centres`` and every combination of the given split parameters."""
    return [Rule("centres")] + [Rule("split", t, c, a, g)
                                for t, c, a, g in itertools.product(thresholds, caps, areas, gaps)]


def main(argv: list[str] | None = None) -> int:
    """CLI entry point: one Markdown row per rule."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.experiments.count_rules", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--counts", type=Path, required=True, help="JSON lines of `phyllo count --json`")
    ap.add_argument("--dataset", type=Path, help="phyllo-gen dataset (truth: visible_leaf_count)")
    ap.add_argument("--split", default="all")
    ap.add_argument("--truth", type=Path, help="file,leaf_count CSV (real images)")
    ap.add_argument("--thresholds", default="0.4,0.5,0.6,0.7,0.8")
    ap.add_argument("--caps", default="2,3,inf", help="most leaves one instance may count (inf: no limit)")
    ap.add_argument("--areas", default="inf", help="instance area limits in image px (inf: none)")
    ap.add_argument("--gaps", default="0", help="least distance between two tips of one instance, image px")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if (args.dataset is None) == (args.truth is None):
        ap.error("give exactly one of --dataset and --truth")
    truth = read_truth(args.dataset, args.split, args.truth)
    counts = read_counts(args.counts)
    names = sorted(set(truth) & set(counts))
    if not names:
        print(f"no image of {args.counts} has a truth", file=sys.stderr)
        return 1
    floats = lambda text: [float(v) for v in text.split(",")]  # noqa: E731
    rules = default_rules(floats(args.thresholds), [NO_CAP if v == "inf" else int(v) for v in args.caps.split(",")],
                          floats(args.areas), floats(args.gaps))
    t = np.array([truth[n] for n in names])
    preds = [(r, np.array([count(counts[n], r) for n in names])) for r in rules]
    centres = preds[0][1]
    # Against the centres, frame by frame: a rule's exact agreement is what it fixes minus what it breaks.
    rows = [(r, {**metrics(t, p), "fixed": int(np.sum((p == t) & (centres != t))),
                 "broken": int(np.sum((p != t) & (centres == t)))}) for r, p in preds]
    if args.json:
        print(json.dumps([{"rule": r.label(), **m} for r, m in rows]))
        return 0
    print("| rule | images | exact | within ±1 | RMSE | MAE | bias | right, centres wrong | wrong, centres right |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r, m in rows:
        print(f"| {r.label()} | {m['images']} | {100 * m['exact']:.1f} % | {100 * m['within1']:.1f} % | "
              f"{m['rmse']:.3f} | {m['mae']:.3f} | {m['bias']:+.3f} | {m['fixed']} | {m['broken']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
