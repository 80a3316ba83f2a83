"""Panoptic-DeepLab losses: top-k hard-pixel cross-entropy, centre MSE, offset L1."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch.nn import functional as F


@dataclass
class LossWeights:
    """Relative weights of the three terms (Panoptic-DeepLab: 1 / 200 / 0.01) and the top-k ratio."""

    semantic: float = 1.0
    center: float = 200.0
    offset: float = 0.01
    top_k: float = 0.2
    center_focal: float = 0.0
    """Weight of :func:`center_focal_loss`, added to the centre MSE (0: off, the shipped recipe)."""


def semantic_topk_ce(logits: torch.Tensor, target: torch.Tensor, weight: torch.Tensor, top_k: float) -> torch.Tensor:
    """Weighted per-pixel cross-entropy averaged over the hardest ``top_k`` fraction of pixels in the batch."""
    pixel = F.cross_entropy(logits, target, reduction="none") * weight
    pixel = pixel.flatten()
    if top_k < 1.0:
        k = max(1, int(top_k * pixel.numel()))
        pixel, _ = torch.topk(pixel, k, sorted=False)
    return pixel.mean()


def center_mse(pred: torch.Tensor, target: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """Weighted MSE on the heatmap, averaged over all pixels (as Panoptic-DeepLab)."""
    return ((pred - target) ** 2 * weight).sum() / weight.sum().clamp_min(1.0)


def center_focal_loss(pred: torch.Tensor, target: torch.Tensor, alpha: float = 2.0, beta: float = 4.0) -> torch.Tensor:
    """CenterNet's penalty-reduced focal loss on the (unbounded) centre heatmap, clamped into (0, 1).

    The MSE is paid over every pixel, so a small leaf's peak is a few dozen
    pixels out of a crop's tens of thousands, and a fine-tune lowers it by
    blurring neighbouring peaks into one (models/EXPERIMENTS.md, session 17: lower
    centre MSE, fewer leaves counted). This term is paid per centre: a missed
    peak costs about -log(p), a spurious one away from every centre
    -log(1 - p), and pixels near a centre are forgiven by ``(1 - target) ** beta``.
    Outside (0, 1) it has no gradient; the MSE it is added to still has.
    """
    return penalty_reduced_focal(pred, target, alpha, beta)


def offset_l1(pred: torch.Tensor, target: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """L1 on (dy, dx) over thing pixels only, normalised by their count."""
    return ((pred - target).abs() * weight).sum() / weight.sum().clamp_min(1.0)


def panoptic_loss(outputs: tuple[torch.Tensor, torch.Tensor, torch.Tensor], targets: dict[str, torch.Tensor],
                  w: LossWeights) -> tuple[torch.Tensor, dict[str, float]]:
    """Total weighted loss and its (unweighted) parts for logging."""
    sem, center, offset = outputs
    l_sem = semantic_topk_ce(sem, targets["semantic"], targets["semantic_weight"], w.top_k)
    l_cen = center_mse(center, targets["center"], targets["center_weight"])
    l_off = offset_l1(offset, targets["offset"], targets["offset_weight"])
    total = w.semantic * l_sem + w.center * l_cen + w.offset * l_off
    parts = {"sem": l_sem, "center": l_cen, "offset": l_off}
    if w.center_focal > 0:
        parts["focal"] = center_focal_loss(center, targets["center"])
        total = total + w.center_focal * parts["focal"]
    parts["loss"] = total
    return total, {k: float(v.detach()) for k, v in parts.items()}


def tip_focal_loss(logits: torch.Tensor, target: torch.Tensor, alpha: float = 2.0, beta: float = 4.0) -> torch.Tensor:
    """CenterNet's penalty-reduced focal loss (Zhou et al., 2019), normalised by the number of tips.

    ``target`` peaks are exactly 1 (targets.gaussian_heatmap); pixels near a
    peak are penalised less for firing, by ``(1 - target) ** beta``.
    """
    return penalty_reduced_focal(torch.sigmoid(logits), target, alpha, beta)


def penalty_reduced_focal(p: torch.Tensor, target: torch.Tensor, alpha: float, beta: float) -> torch.Tensor:
    """The focal loss of probabilities ``p`` (clamped into (0, 1)) against unit-peak Gaussian ``target``s, per peak."""
    p = p.clamp(1e-4, 1 - 1e-4)
    pos = target.ge(1.0 - 1e-6).float()
    pos_loss = -torch.log(p) * (1 - p) ** alpha * pos
    neg_loss = -torch.log(1 - p) * p ** alpha * (1 - target) ** beta * (1 - pos)
    return (pos_loss.sum() + neg_loss.sum()) / pos.sum().clamp_min(1.0)
