#!/usr/bin/env python3
"""Did the pipeline enlarge each plant as training did? Counts split by it.

Reads `phyllo count --scale 1 --json` lines for a phyllo-gen set's images
(COUNT_JSONL) and the set's labels. For each image it compares the scale the
pipeline settled on (the first pass's instances choose the enlargement) with
the enlargement training gives the same plant (measured on its label,
`phyllo_train.augment.plant_zoom`), and prints exact agreement and bias where
the two agree within 10 % and where they do not. A model whose deficit sits
where the zoom went wrong has a pipeline problem; one whose deficit is the
same in both has a network problem (models/EXPERIMENTS.md, session 44).

    target/release/phyllo count --scale 1 --json [--model M] IMAGES... >COUNT_JSONL
    models/.venv/bin/python scripts/experiments/zoom-vs-label.py DATASET COUNT_JSONL
"""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "models"))

from phyllo_train.augment import plant_zoom  # noqa: E402
from phyllo_train.contract import load_contract  # noqa: E402
from phyllo_train.dataset import read_label, read_manifest  # noqa: E402


def main(dataset: Path, counts: Path) -> None:
    """Print the table (see the module doc)."""
    contract = load_contract()
    by_file = {}
    for line in counts.read_text().splitlines():
        row = json.loads(line)
        if "error" in row:
            raise SystemExit(f"{counts}: {row['file']}: {row['error']}")
        by_file[str(Path(row["file"]).resolve())] = row
    rows = []
    for r in read_manifest(dataset, None):
        image = str((dataset / r["image"]).resolve())
        if image not in by_file:
            raise SystemExit(f"{counts}: no count for {image}")
        label = read_label(dataset / r["label"])
        z = plant_zoom(label, contract.label_divisor, contract.zoom_plant_height, contract.max_zoom)
        got = by_file[image]
        rows.append((got["scale"] / z, got["leaf_count"], r["visible_leaf_count"]))
    a = np.array(rows, dtype=np.float64)
    agree = np.abs(np.log(a[:, 0])) <= np.log(1.1)
    print("| images | zoom as training's (within 10 %) | n | exact | bias |")
    print("|---|---|---:|---:|---:|")
    for name, sel in (("all", np.ones(len(a), bool)), ("yes", agree), ("no", ~agree)):
        if sel.any():
            err = a[sel, 1] - a[sel, 2]
            print(f"| {len(a)} | {name} | {sel.sum()} | {100 * np.mean(err == 0):.1f} % | {err.mean():+.2f} |")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    main(Path(sys.argv[1]), Path(sys.argv[2]))
