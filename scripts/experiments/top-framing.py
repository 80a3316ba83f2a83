#!/usr/bin/env python3
"""How well a phyllo-gen dataset's top views frame their plants.

    scripts/experiments/top-framing.py DATASET

Prints the number of top views, how many have a plant pixel (label class >= 1,
stem and leaves) on the crop's border, and the plant's mean share of the
crop. models/EXPERIMENTS.md, "The top camera's framing", compares top camera
fields of view (generator/src/render/camera.rs, TOP_VFOV_DEG) with it.
Needs numpy and pillow (models/.venv has both).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    root = Path(argv[0])
    cut, shares = 0, []
    for line in (root / "manifest.jsonl").read_text().splitlines():
        row = json.loads(line)
        if row["view"] != "top":
            continue
        plant = np.array(Image.open(root / row["label"])) >= 1000  # class * 1000 + instance (contract)
        border = np.concatenate([plant[0], plant[-1], plant[:, 0], plant[:, -1]])
        cut += bool(border.any())
        shares.append(float(plant.mean()))
    n = len(shares)
    if n == 0:
        print(f"{root}: no top views")
        return 1
    print(f"{root}: {n} top views, {cut} touch the border ({100 * cut / n:.0f} %), "
          f"plant covers {100 * np.mean(shares):.1f} % of the crop")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
