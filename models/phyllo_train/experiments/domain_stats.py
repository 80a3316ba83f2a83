"""How real and synthetic images differ at the model's input, one row per source::

    python -m phyllo_train.experiments.domain_stats --images REAL_DIR --images DATASET [--augmented DATASET] [--limit 80]

``--images`` sources (folders of images or phyllo-gen datasets) are resized by the
contract's scale rule, as the daemon resizes them; ``--augmented`` draws training
crops from a dataset's train split through the training augmentation. Per image it
takes the plant pixels by the daemon's colour test (``reference_pipeline.plant_colour``)
and the rest as wall, then prints the median over images, with the 5th and 95th
percentiles, of: the wall's and the plant's mean colour, the plant's green over red,
and the wall's roughness (mean absolute difference of neighbouring grey values,
0..255, over neighbours that are both wall): sensor noise, JPEG blocks and
texture that the renderer may lack. A source whose real range lies outside the
augmented one is something training never shows.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image

from ..augment import AugmentConfig, add_noise_args, with_noise_args
from .daemon_inputs import image_paths, reference_pipeline

STATS = ("wall R", "wall G", "wall B", "plant R", "plant G", "plant B", "plant G−R", "wall roughness")


def image_stats(rgb: np.ndarray, plant: np.ndarray) -> np.ndarray | None:
    """The :data:`STATS` of one uint8 RGB image with its plant mask, or None without both parts."""
    wall = ~plant
    if plant.sum() < 50 or wall.sum() < 50:
        return None
    x = rgb.astype(np.float32)
    grey = x.mean(axis=2)
    gy, gx = np.abs(np.diff(grey, axis=0)), np.abs(np.diff(grey, axis=1))
    diffs = np.concatenate([gy[wall[1:] & wall[:-1]], gx[wall[:, 1:] & wall[:, :-1]]])
    p, w = x[plant].mean(0), x[wall].mean(0)
    return np.array([*w, *p, p[1] - p[0], diffs.mean() if len(diffs) else np.nan])


def scaled_images(paths: list[Path]):
    """Each image resized by the contract's scale rule (frames and crops alike), as uint8 RGB."""
    rp = reference_pipeline()
    for path in paths:
        with Image.open(path) as im:
            img = im.convert("RGB")
        s = rp.scale_for(*img.size)
        size = (max(round(img.width * s), 1), max(round(img.height * s), 1))
        yield np.asarray(img.resize(size, Image.BILINEAR))


def augmented_crops(dataset: Path, limit: int, crop: int, aug=None):
    """Training crops of ``dataset``'s train split as the training run draws them, as uint8 RGB.

    ``aug`` is the :class:`~phyllo_train.augment.AugmentConfig` (default: the recipe's at ``crop``).
    """
    from ..dataset import PanopticDataset

    ds = PanopticDataset(dataset, "train", aug or AugmentConfig(crop=crop), seed=19)
    mean, std = (np.asarray(v, np.float32) for v in (ds.contract.mean, ds.contract.std))
    for i in range(min(limit, len(ds))):
        x, _ = ds[i]
        yield np.clip((x.numpy().transpose(1, 2, 0) * std + mean) * 255 + 0.5, 0, 255).astype(np.uint8)


def source_row(name: str, images) -> str:
    """One markdown table row: median [5th, 95th percentile] of each statistic over ``images``."""
    rp = reference_pipeline()
    rows = [r for r in (image_stats(img, rp.plant_colour(img)) for img in images) if r is not None]
    if not rows:
        return f"| {name} | 0 |" + " |" * len(STATS)
    a = np.array(rows)
    lo, med, hi = np.nanpercentile(a, [5, 50, 95], axis=0)
    cells = [f"{m:.1f} [{lo_:.1f}, {hi_:.1f}]" for lo_, m, hi_ in zip(lo, med, hi)]
    return f"| {name} | {len(rows)} | " + " | ".join(cells) + " |"


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.experiments.domain_stats", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", type=Path, action="append", default=[],
                    help="folder of images or phyllo-gen dataset, resized as the daemon resizes it (repeatable)")
    ap.add_argument("--augmented", type=Path, action="append", default=[],
                    help="phyllo-gen dataset whose training crops are drawn through the augmentation (repeatable)")
    ap.add_argument("--limit", type=int, default=80, help="images per source")
    ap.add_argument("--crop", type=int, default=448, help="training crop side for --augmented")
    add_noise_args(ap)
    args = ap.parse_args(argv)
    if not args.images and not args.augmented:
        ap.error("give at least one --images or --augmented source")
    aug = with_noise_args(AugmentConfig(crop=args.crop), args)
    print("| source | images | " + " | ".join(STATS) + " |")
    print("|---|---:|" + "---|" * len(STATS))
    try:
        for src in args.images:
            print(source_row(src.name, scaled_images(image_paths([src])[: args.limit])), flush=True)
        for src in args.augmented:
            print(source_row(f"{src.name}, augmented {args.crop}² crops", augmented_crops(src, args.limit, args.crop, aug)),
                  flush=True)
    except (OSError, ValueError) as e:
        print(f"domain_stats: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
