"""Average the weights of checkpoints fine-tuned from one parent (a model soup).

    python -m phyllo_train.experiments.soup --out RUN_DIR/best.pt A/best.pt B/best.pt [--weights 0.5,0.5]

Fine-tunes of one model lie in one basin of the loss, so their weighted
mean is a model of its own, often better than either (Wortsman et al.,
2022). Export the result like any checkpoint. Floating-point tensors are
averaged, BatchNorm statistics included; integer ones (batch counters) come
from the last checkpoint, as do its args, so export builds the same network.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch


def soup_state(states: list[dict[str, torch.Tensor]], weights: list[float]) -> dict[str, torch.Tensor]:
    """The weighted mean of state dicts with the same keys and shapes."""
    if len(states) != len(weights) or not states:
        raise ValueError(f"{len(states)} checkpoints but {len(weights)} weights")
    total = sum(weights)
    if total <= 0 or any(w < 0 for w in weights):
        raise ValueError(f"weights must be non-negative with a positive sum, got {weights}")
    keys = set(states[0])
    for i, s in enumerate(states[1:], 1):
        if set(s) != keys:
            raise ValueError(f"checkpoint {i} has other layers than checkpoint 0: {sorted(keys ^ set(s))[:5]}")
    out = {}
    for k, first in states[0].items():
        if any(s[k].shape != first.shape for s in states):
            raise ValueError(f"{k}: shapes differ across checkpoints")
        if first.is_floating_point():
            acc = sum(s[k].double() * (w / total) for s, w in zip(states, weights))
            out[k] = acc.to(first.dtype)
        else:
            out[k] = states[-1][k].clone()
    return out


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.experiments.soup", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("checkpoints", type=Path, nargs="+", help="training checkpoints (.pt) of one network")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--weights", default=None, help="comma-separated, one per checkpoint (default: equal)")
    args = ap.parse_args(argv)
    weights = [float(w) for w in args.weights.split(",")] if args.weights else [1.0] * len(args.checkpoints)
    ckpts = [torch.load(str(p), map_location="cpu", weights_only=False) for p in args.checkpoints]
    try:
        state = soup_state([c["model"] for c in ckpts], weights)
    except ValueError as e:
        print(f"soup: {e}", file=sys.stderr)
        return 2
    out = dict(ckpts[-1])
    out["model"] = state
    for k in ("raw_model", "optimizer", "ema"):
        out.pop(k, None)
    parts = ", ".join(f"{p} x{w:g}" for p, w in zip(args.checkpoints, weights))
    out["training_data"] = f"weight average of {parts} | " + " | ".join(
        str(c.get("training_data", "unknown")) for c in ckpts)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    torch.save(out, str(args.out))
    print(f"wrote {args.out}: {parts}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
