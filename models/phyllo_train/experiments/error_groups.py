"""Count errors of one `phyllo eval --json --per-image` run, split into groups of images.

    phyllo eval --dataset DIR --split all --json --per-image > run.json
    python -m phyllo_train.experiments.error_groups run.json --dataset DIR
    phyllo eval --counts crops_counts.csv --images crops --json --per-image > crops.json
    python -m phyllo_train.experiments.error_groups crops.json --truth 4-11 12-15 14-15

Prints one row per group: images, exact / within ±1 / RMSE / bias. Every run
gets the `--truth` ranges (true counts, inclusive). With `--dataset`, the
phyllo-gen manifest adds groups by plant age (8 weeks or younger, older),
late maize older than 8 weeks (preset `maize-late`) and flowering sorghum
(a sorghum preset, day 62 on, when the panicle is out): the groups of
models/EXPERIMENTS.md, "Plants past eight weeks".
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ..dataset import read_manifest
from ..tools.truth_rules import metrics as count_metrics

EIGHT_WEEKS = 56.0
PANICLE_DAY = 62.0
MAIZE = ("maize", "maize-late")


def metrics(errors: list[int]) -> str:
    """`n | exact / ±1 / RMSE / bias` of predicted minus true counts."""
    if not errors:
        return "0 | |"
    # The errors are predicted minus true counts: against a truth of zero they are the predictions.
    m = count_metrics(np.zeros(len(errors)), np.asarray(errors))
    return f"{m['images']} | {100 * m['exact']:.1f} / {100 * m['within1']:.1f} / {m['rmse']:.3f} / {m['bias']:+.2f}"


def groups(images: list[dict], truth_ranges: list[tuple[int, int]],
           manifest: dict[str, dict] | None = None) -> dict[str, list[int]]:
    """Errors by group name, in print order. `manifest` maps an image path
    as the manifest writes it (`images/NAME.png`) to its row."""
    out: dict[str, list[int]] = {"all": []}
    for lo, hi in truth_ranges:
        out[f"truth {lo}–{hi}"] = []
    if manifest is not None:
        for name in ("plant 8 weeks old or younger", "plant older than 8 weeks",
                     "late maize older than 8 weeks", "flowering sorghum (day 62 on)"):
            out[name] = []
    for im in images:
        err = int(im["predicted"]) - int(im["truth"])
        out["all"].append(err)
        for lo, hi in truth_ranges:
            if lo <= im["truth"] <= hi:
                out[f"truth {lo}–{hi}"].append(err)
        if manifest is None:
            continue
        row = manifest.get("/".join(Path(im["file"]).parts[-2:]))
        if row is None:
            raise KeyError(f"{im['file']} is not in the dataset's manifest")
        age, preset = float(row["age_days"]), row["preset"]
        out["plant 8 weeks old or younger" if age <= EIGHT_WEEKS else "plant older than 8 weeks"].append(err)
        if preset == "maize-late" and age > EIGHT_WEEKS:
            out["late maize older than 8 weeks"].append(err)
        if preset not in MAIZE and age >= PANICLE_DAY:
            out["flowering sorghum (day 62 on)"].append(err)
    return out


def _range(text: str) -> tuple[int, int]:
    lo, _, hi = text.partition("-")
    return int(lo), int(hi or lo)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path, help="output of phyllo eval --json --per-image")
    ap.add_argument("--dataset", type=Path, help="the phyllo-gen dataset the run counted (for age and preset groups)")
    ap.add_argument("--truth", nargs="*", default=[(13, 99)], type=_range,
                    help="true-count ranges LO-HI (default: 13-99)")
    args = ap.parse_args(argv)
    run = json.loads(args.run.read_text())
    if "images" not in run:
        raise SystemExit(f"{args.run}: no per-image counts (run phyllo eval with --per-image)")
    manifest = None
    if args.dataset is not None:
        manifest = {r["image"]: r for r in read_manifest(args.dataset)}
    print("| images | n | exact / ±1 / RMSE / bias |")
    print("|---|---:|---|")
    for name, errors in groups(run["images"], args.truth, manifest).items():
        print(f"| {name} | {metrics(errors)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
