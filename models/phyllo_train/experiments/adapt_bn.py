"""Adapt a checkpoint's BatchNorm statistics to unlabelled images (AdaBN), then export it::

    python -m phyllo_train.experiments.adapt_bn --checkpoint runs/s10-onnx/best.pt --images DIR [--images DIR] \
        --out runs/NAME/best.pt [--batch 3 --limit N]

Every BatchNorm keeps its learned scale and shift but normalises by the mean and
variance its inputs have on the given images, cut into the tiles the daemon
runs (``reference_pipeline.prepare``: the contract's scale rule, the canvas
around the plant, 512² tiles, first pass). No labels or counts are read. This is
the classic unsupervised correction for a domain shift in a network's first
statistics (Li et al., "Revisiting Batch Normalization for Practical Domain
Adaptation", 2016): the renderer's images and the chamber camera's differ in
colour, contrast and noise in ways augmentation covers only in part.

The checkpoint must hold BatchNorm statistics of the images it was trained on
(``from_onnx --calibrate`` gives the shipped model's); a checkpoint written by
``train`` has them.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch
from PIL import Image
from torch import nn

from ..contract import load_contract
from .daemon_inputs import image_paths, reference_pipeline
from ..export import load_checkpoint_model

__all__ = ["adapt_batchnorm", "daemon_tiles", "image_paths", "main"]


def daemon_tiles(paths: list[Path]) -> list[np.ndarray]:
    """The normalised first-pass tiles (T, 3, 512, 512) the daemon would run on each image."""
    rp = reference_pipeline()
    out = []
    for p in paths:
        try:
            with Image.open(p) as im:
                img = np.asarray(im.convert("RGB"))
        except OSError as e:
            raise ValueError(f"{p}: cannot read the image: {e}") from e
        canvas, tiles, _, _ = rp.prepare(img)
        out.append(rp.normalise(canvas, tiles))
    return out


def adapt_batchnorm(model: nn.Module, batches: list[torch.Tensor], layers: int | None = None) -> int:
    """Replaces BatchNorms' running mean and variance by their averages over ``batches``.

    Only the first ``layers`` BatchNorms (module order, which is the encoder's
    order) are adapted when given; the rest keep their statistics. Training mode
    normalises each batch by its own statistics, so every adapted layer sees
    inputs already adapted upstream, and ``momentum=None`` makes the running
    statistics the plain average of the per-batch ones (what training kept).
    Returns the number of BatchNorm layers adapted.
    """
    bns = [m for m in model.modules() if isinstance(m, nn.BatchNorm2d)][:layers]
    saved = [bn.momentum for bn in bns]
    model.eval()
    for bn in bns:
        bn.reset_running_stats()
        bn.momentum = None
        bn.train()
    try:
        with torch.no_grad():
            for x in batches:
                model(x)
    finally:
        for bn, m in zip(bns, saved):
            bn.momentum = m
        model.eval()
    return len(bns)


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.experiments.adapt_bn", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", type=Path, required=True, help="training checkpoint (.pt) with BatchNorm statistics")
    ap.add_argument("--images", type=Path, action="append", required=True,
                    help="image file, folder of images or phyllo-gen dataset (repeatable)")
    ap.add_argument("--out", type=Path, required=True, help="checkpoint to write (.pt), exportable and usable as --init")
    ap.add_argument("--batch", type=int, default=3, help="tiles per batch (the training batch: BatchNorm's statistics are per batch)")
    ap.add_argument("--limit", type=int, default=None, help="use at most this many images (in order)")
    ap.add_argument("--seed", type=int, default=0, help="shuffles the tiles into batches")
    ap.add_argument("--layers", type=int, default=None,
                    help="adapt only the first N BatchNorms (the early, colour- and contrast-bound ones; default: all)")
    ap.add_argument("--contract", default=None, help="contract.toml (default: models/contract.toml)")
    args = ap.parse_args(argv)

    contract = load_contract(args.contract)
    try:
        paths = image_paths(args.images)[: args.limit]
        if not paths:
            raise ValueError(f"no images in {', '.join(map(str, args.images))}")
        tiles = np.concatenate(daemon_tiles(paths))
    except (ValueError, OSError) as e:
        print(f"adapt_bn: {e}", file=sys.stderr)
        return 2
    order = np.random.default_rng(args.seed).permutation(len(tiles))
    batches = [torch.from_numpy(tiles[order[i:i + args.batch]]) for i in range(0, len(order), args.batch)]
    if len(batches) > 1 and len(batches[-1]) < args.batch:
        batches.pop()  # a short last batch would weigh its variance like a full one
    used = sum(len(b) for b in batches)
    model, ck = load_checkpoint_model(args.checkpoint, contract)
    n = adapt_batchnorm(model, batches, args.layers)
    note = (f" | {n} BatchNorm layers' statistics adapted (AdaBN) to {len(paths)} unlabelled images "
            f"({', '.join(p.name for p in args.images)}), {used} daemon tiles")
    state = model.state_dict()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({**ck, "model": state, "raw_model": state, "ema": None,
                "training_data": ck.get("training_data", "unknown") + note}, args.out)
    print(f"wrote {args.out}: {n} BatchNorm layers adapted to {len(paths)} images, "
          f"{used} tiles in batches of {args.batch}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
