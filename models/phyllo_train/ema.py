"""Exponential moving average of model weights, with a warm-up of the decay.

A fixed decay of 0.999 would leave the average stuck near the random init for
the first thousands of steps of a short CPU run; the decay therefore ramps as
min(decay, (1 + n) / (10 + n)) over the n updates so far (as TF/timm do).
"""

from __future__ import annotations

import copy

import torch
from torch import nn


class ModelEma:
    """Keeps ``module``, an averaged copy of a model (parameters and BN buffers)."""

    def __init__(self, model: nn.Module, decay: float = 0.999):
        self.module = copy.deepcopy(model).eval()
        for p in self.module.parameters():
            p.requires_grad_(False)
        self.decay = decay
        self.updates = 0

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        """Blend the current weights of ``model`` into the average."""
        self.updates += 1
        d = min(self.decay, (1 + self.updates) / (10 + self.updates))
        src = model.state_dict()
        for k, v in self.module.state_dict().items():
            if v.dtype.is_floating_point:
                v.mul_(d).add_(src[k].detach(), alpha=1 - d)
            else:
                v.copy_(src[k])  # e.g. BN's num_batches_tracked

    def state_dict(self) -> dict:
        """Weights and update count, for checkpoints."""
        return {"module": self.module.state_dict(), "updates": self.updates}

    def load_state_dict(self, state: dict) -> None:
        """Restore from :meth:`state_dict`."""
        self.module.load_state_dict(state["module"])
        self.updates = int(state["updates"])
