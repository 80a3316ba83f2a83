"""Targets from a teacher network: the student learns the teacher's centre heatmap (and offsets).

Why: a network fitted to the contract's Gaussian centre targets blends a cluster
of young leaves into one smooth blob, and no fine-tune on those targets has raised
a count (models/EXPERIMENTS.md, "Six levers"). s10's heatmaps count better than a
perfect fit of those targets would; a student paid to reproduce them inherits
the dips that keep neighbouring leaves apart. Top views keep their label targets:
s10 never saw one and misses five leaves in them.
"""

from __future__ import annotations

from pathlib import Path

import torch

from ..contract import Contract
from ..export import load_checkpoint_model

MODES = ("center", "center+offset")
"""Which targets the teacher replaces on side views."""


def load_teacher(path: str | Path, contract: Contract, device: torch.device) -> torch.nn.Module:
    """The checkpoint's network (its ``model`` weights, layout from its ``args``), frozen in eval mode."""
    model, _ = load_checkpoint_model(path, contract)
    model.eval().to(device, memory_format=torch.channels_last)
    for p in model.parameters():
        p.requires_grad_(False)
    return model


@torch.no_grad()
def teacher_targets(teacher: torch.nn.Module, xs: torch.Tensor, ts: dict[str, torch.Tensor],
                    mode: str, peak_weight: float = 0.0) -> dict[str, torch.Tensor]:
    """``ts`` with the side views' centre (and, in ``center+offset`` mode, offset) targets
    replaced by the teacher's outputs on the same normalised batch ``xs``.

    Samples whose ``top_view`` flag is set keep their label targets. The weights are the
    label's: padding outside the crop stays unpaid, as before. The teacher runs in
    float32 even when the student trains under bfloat16 autocast: s10's heatmap under
    autocast has spurious maxima, which counts 150 of its own300 images 17 % exactly
    against 33 % in float32 (models/EXPERIMENTS.md, session 45).

    ``peak_weight`` W > 0 weighs each side-view pixel's centre loss by 1 + W x the
    teacher's heatmap (clamped into [0, 1]): four fifths of a student's squared
    error to s10 lies away from its peaks, which are what the count reads.
    """
    if mode not in MODES:
        raise ValueError(f"distillation mode must be one of {MODES}, got {mode!r}")
    _, center, offset = teacher(xs)[:3]  # a tip network adds a fourth output
    side = (ts["top_view"] < 0.5).view(-1, 1, 1, 1)
    out = dict(ts)
    out["center"] = torch.where(side, center, ts["center"])
    if peak_weight > 0:
        peaks = ts["center_weight"] * (1.0 + peak_weight * center.clamp(0.0, 1.0))
        out["center_weight"] = torch.where(side, peaks, ts["center_weight"])
    if mode == "center+offset":
        out["offset"] = torch.where(side, offset, ts["offset"])
    return out
