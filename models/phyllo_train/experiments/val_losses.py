"""Validation losses of training checkpoints on one phyllo-gen split, side by side.

    python -m phyllo_train.experiments.val_losses --data /work/data/calib-s700001 --split val --limit 120 \\
        runs/s10-onnx/best.pt runs/RUN/step-000300.pt

One row per checkpoint (its exported, EMA weights): the training losses on
the split's samples without photometric augmentation (the small-plant zoom
and a window of the tile's size still apply, as in training). No counts:
count checkpoints on whole frames with `phyllo eval`
(`scripts/score-checkpoints.sh`); a lower centre MSE does not mean a better
count (models/EXPERIMENTS.md, "The centre loss and the count").
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from ..augment import AugmentConfig
from ..contract import load_contract
from ..dataset import PanopticDataset
from ..export import load_checkpoint_model
from ..losses import LossWeights
from ..train import evaluate


def main(argv: list[str] | None = None) -> int:
    """CLI entry point: prints a Markdown table."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.experiments.val_losses", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("checkpoints", type=Path, nargs="+", help="training checkpoints (.pt)")
    ap.add_argument("--data", type=Path, required=True, help="phyllo-gen dataset")
    ap.add_argument("--split", default="val")
    ap.add_argument("--limit", type=int, default=120, help="first N images of the split")
    ap.add_argument("--batch", type=int, default=4)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--center-focal", type=float, default=0.0, help="also report the centre focal loss")
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    contract = load_contract()
    ds = PanopticDataset(args.data, args.split, AugmentConfig.none(), contract, limit=args.limit)
    weights = LossWeights(center_focal=args.center_focal)
    cols = ["loss", "sem", "center", "offset"] + (["focal"] if args.center_focal > 0 else [])
    print(f"{len(ds)} images of {args.data} ({args.split})\n")
    print("| checkpoint | " + " | ".join(cols) + " |")
    print("|---|" + "---:|" * len(cols))
    for path in args.checkpoints:
        model, _ = load_checkpoint_model(path, contract)
        res = evaluate(model, ds, torch.device("cpu"), weights, args.batch)
        print(f"| {path} | " + " | ".join(f"{res['val_' + c]:.5g}" for c in cols) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
