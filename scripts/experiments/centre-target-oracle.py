#!/usr/bin/env python3
"""How many leaves a centre target keeps apart once a smooth network blends it.

For each label of a phyllo-gen set, every leaf's centre (centre of mass,
output pixels) gets a Gaussian of the width a rule gives it; the Gaussians
are *summed*, as a network whose output is smooth blends neighbours, and
the contract's peak finder (threshold 0.3, NMS window 7) counts the peaks.
Prints the share of images whose peak count equals their leaf count, per rule:
the contract's sigma 4, the same on centres moved onto their own blade
(`train --center-point blade`), sigma 2.5, and crowded centres narrowed
(`train --center-sigma-min`). Not a model's score: a ceiling on what a
blurred copy of each target can count (models/EXPERIMENTS.md, "Stage 8").

    models/.venv/bin/python scripts/experiments/centre-target-oracle.py /work/data/calib-e40-mini 120
    models/.venv/bin/python scripts/experiments/centre-target-oracle.py /work/data/calib-top-s700301 150 7,5,3

The optional third argument lists NMS windows (default: the contract's 7).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "models"))

import numpy as np  # noqa: E402
import torch  # noqa: E402

from phyllo_train.contract import load_contract  # noqa: E402
from phyllo_train.dataset import read_label, read_manifest  # noqa: E402
from phyllo_train.tools.postprocess import find_centers  # noqa: E402
from phyllo_train.targets import crowding_sigmas, instance_centres  # noqa: E402


def leaf_centres(lab: np.ndarray, leaf: int, div: int, s: int, point: str = "mass") -> np.ndarray:
    """(K, 2) centres of the leaf instances of at least one output pixel, output px.

    ``point``: ``mass`` (centre of mass) or ``blade`` (`train --center-point blade`)."""
    ys, xs = np.nonzero((lab // div == leaf) & (lab % div > 0))
    if len(ys) == 0:
        return np.zeros((0, 2))
    _, inv = np.unique(lab[ys, xs], return_inverse=True)
    my, mx, area = instance_centres(ys, xs, inv, point)
    cy = (my - (s - 1) / 2) / s
    cx = (mx - (s - 1) / 2) / s
    return np.stack([cy, cx], 1)[area >= s * s]


def main() -> int:
    c = load_contract()
    root = Path(sys.argv[1])
    rows = read_manifest(root, None)[: int(sys.argv[2]) if len(sys.argv) > 2 else None]
    labels = [read_label(root / r["label"]).astype(np.int64) for r in rows]
    mass = [leaf_centres(lab, c.leaf, c.label_divisor, c.stride) for lab in labels]
    blade = [leaf_centres(lab, c.leaf, c.label_divisor, c.stride, "blade") for lab in labels]
    moved = np.concatenate([np.hypot(*(b - m).T) for b, m in zip(blade, mass)])
    print(f"blade centres: {len(moved)} leaves, {100 * np.mean(moved > 0.5):.1f} % moved off their centre of mass, "
          f"by {np.mean(moved[moved > 0.5]) if (moved > 0.5).any() else 0:.1f} output px on average\n")
    rules = [("sigma 4 (the contract's)", mass, lambda cs: np.full(len(cs), 4.0)),
             ("sigma 4, centres on the blade", blade, lambda cs: np.full(len(cs), 4.0)),
             ("sigma 2.5", mass, lambda cs: np.full(len(cs), 2.5)),
             ("crowded centres narrowed, min 2", mass, lambda cs: crowding_sigmas(cs, 4.0, 2.0))]
    contract_window = int(c.raw["postprocess"]["nms_kernel"])
    windows = [int(k) for k in sys.argv[3].split(",")] if len(sys.argv) > 3 else [contract_window]
    print("| centre target | NMS window | images | counts kept | bias |")
    print("|---|---:|---:|---:|---:|")
    for name, centres, rule in rules:
        heats = []
        for lab, cs in zip(labels, centres):
            h, w = lab.shape[0] // c.stride, lab.shape[1] // c.stride
            gy, gx = np.ogrid[0:h, 0:w]
            heat = np.zeros((h, w), np.float32)
            for (cy, cx), sg in zip(cs, rule(cs)):
                heat += np.exp(-((gy - cy) ** 2 + (gx - cx) ** 2) / (2 * sg * sg)).astype(np.float32)
            heats.append(torch.from_numpy(heat)[None])
        for k in windows:
            diffs = np.array([len(find_centers(heat, 0.3, k, 200)) - len(cs) for heat, cs in zip(heats, centres)])
            print(f"| {name} | {k} | {len(labels)} | {100 * np.mean(diffs == 0):.1f} % | {np.mean(diffs):+.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
