"""How many true leaves the centre NMS window loses even with a perfect heatmap.

Merged leaves are most of the model's misses. Two causes are possible: the
network draws one blob where there are two peaks, or the true centres lie so
close that the decoder's max-pool window (``nms_kernel`` output pixels a
side) keeps only one of them. This measures the second from the labels
alone, at the scale the counter sees each frame (the contract's small-plant
zoom, output stride)::

    python -m phyllo_train.experiments.nms_floor /work/data/calib-s700001 [--kernels 3,5,7]

Centres are leaves' centres of mass (the training target). Centres are kept
greedily, larger leaves first (a larger leaf is likelier to hold the higher
peak), and a centre within the window of a kept one is lost.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ..augment import plant_zoom
from ..contract import Contract, load_contract
from ..dataset import read_label, read_manifest


def leaf_centres(label: np.ndarray, contract: Contract) -> tuple[np.ndarray, np.ndarray]:
    """(K, 2) centres of mass (y, x) in input pixels and (K,) areas of the label's leaf instances."""
    div = contract.label_divisor
    leaf = (label // div == contract.leaf) & (label % div > 0)
    ys, xs = np.nonzero(leaf)
    if len(ys) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    _, inv = np.unique(label[ys, xs], return_inverse=True)
    area = np.bincount(inv).astype(np.float64)
    cy = np.bincount(inv, weights=ys) / area
    cx = np.bincount(inv, weights=xs) / area
    return np.stack([cy, cx], axis=1), area


def lost_to_window(centres: np.ndarray, areas: np.ndarray, kernel: int) -> int:
    """Centres (output pixels) that a max-pool window of side ``kernel`` hides behind a larger leaf's."""
    kept: list[np.ndarray] = []
    half = kernel // 2
    for j in np.argsort(-areas, kind="stable"):
        if any(np.max(np.abs(centres[j] - k)) <= half for k in kept):
            continue
        kept.append(centres[j])
    return len(centres) - len(kept)


def main(argv: list[str] | None = None) -> int:
    """CLI entry point: one line per window size."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.experiments.nms_floor", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--kernels", default="3,5,7", help="window sides to try, output pixels (the contract's is 7)")
    ap.add_argument("--split", default=None, help="only this split (default: all rows)")
    args = ap.parse_args(argv)
    contract = load_contract()
    kernels = [int(k) for k in args.kernels.split(",")]
    rows = read_manifest(args.dataset, args.split)
    truth, lost = [], {k: [] for k in kernels}
    for row in rows:
        label = read_label(args.dataset / row["label"])
        centres, areas = leaf_centres(label, contract)
        z = plant_zoom(label, contract.label_divisor, contract.zoom_plant_height, contract.max_zoom)
        # Input pixel i maps to output coordinate (i - (s - 1) / 2) / s; only distances matter here.
        out = centres * z / contract.stride
        truth.append(len(centres))
        for k in kernels:
            lost[k].append(lost_to_window(out, areas, k))
    t = np.array(truth)
    print(f"{args.dataset}: {len(rows)} images, {t.sum()} leaves")
    print("| window | leaves lost | images losing one or more | exact ceiling | bias from the window alone |")
    print("|---:|---:|---:|---:|---:|")
    for k in kernels:
        n = np.array(lost[k])
        print(f"| {k} | {n.sum()} ({100 * n.sum() / max(t.sum(), 1):.1f} %) | {100 * (n > 0).mean():.1f} % | "
              f"{100 * (n == 0).mean():.1f} % | {-n.mean():+.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
