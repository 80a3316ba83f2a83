"""A training run's resume point, small enough to commit, so one schedule can span sessions.

    python -m phyllo_train.tools.resume_state pack RUN_DIR/last.pt --out schedule/NAME.pt
    python -m phyllo_train.tools.resume_state unpack schedule/NAME.pt --out RUN_DIR/last.pt

A session's run directory does not outlive the session; the repository does. ``pack`` keeps
what ``train`` needs to go on exactly where it stopped (raw weights, EMA weights, step, RNG
state, the optimiser's step counts and learning-rate groups) and drops the export copy of the
EMA weights that ``last.pt`` also holds (``unpack`` rebuilds it). The optimiser's moments are
kept in bfloat16: they are running statistics of gradients, whose third significant digit does
not change a step; the weights stay float32.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import torch

# Optimiser state entries that are per-element running statistics (AdamW's moments, SGD's buffer).
MOMENTS = ("exp_avg", "exp_avg_sq", "momentum_buffer")


def _cast_moments(opt_state: dict, dtype: torch.dtype) -> dict:
    out = {"param_groups": opt_state["param_groups"], "state": {}}
    for k, st in opt_state["state"].items():
        out["state"][k] = {n: (v.to(dtype) if n in MOMENTS and torch.is_tensor(v) and v.is_floating_point() else v)
                           for n, v in st.items()}
    return out


def pack(ck: dict) -> dict:
    """The resume point of a ``train`` checkpoint (see the module)."""
    out = {k: v for k, v in ck.items() if k != "model"}
    if ck.get("ema") is None:
        out["model"] = ck["model"]  # without EMA the export weights are the only copy
    out["optimizer"] = _cast_moments(ck["optimizer"], torch.bfloat16)
    out["packed"] = True
    return out


def unpack(packed: dict) -> dict:
    """A ``train`` checkpoint (``last.pt``) from :func:`pack`'s output."""
    ck = {k: v for k, v in packed.items() if k != "packed"}
    ck["optimizer"] = _cast_moments(packed["optimizer"], torch.float32)
    if "model" not in ck:
        ck["model"] = packed["ema"]["module"]
    return ck


def _save(obj: dict, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    """CLI: ``pack`` or ``unpack`` one file."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.tools.resume_state", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("action", choices=("pack", "unpack"))
    ap.add_argument("checkpoint", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    ck = torch.load(args.checkpoint, map_location="cpu", weights_only=False)
    if args.action == "pack":
        if ck.get("packed"):
            raise SystemExit(f"{args.checkpoint}: already packed")
        _save(pack(ck), args.out)
    else:
        if not ck.get("packed"):
            raise SystemExit(f"{args.checkpoint}: not a packed resume point (made by `pack`)")
        _save(unpack(ck), args.out)
    size = args.out.stat().st_size / 1e6
    print(f"{args.out}: step {ck['step']}, {size:.1f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
