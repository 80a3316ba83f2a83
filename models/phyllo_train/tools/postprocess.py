"""Panoptic-DeepLab decoding of the network's outputs (Python twin of the Rust decoder).

Semantic argmax; centres = local maxima of the heatmap (max-pool NMS) above a
threshold, top-k; every thing pixel moves by its offset and joins the nearest
centre; an instance's class is the majority class of its pixels; the leaf count
is the number of leaf instances with at least ``min_leaf_area`` output pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch.nn import functional as F

from ..contract import Contract


@dataclass
class Panoptic:
    """Decoded result for one image at output resolution."""

    semantic: np.ndarray   # (h, w) class ids
    instance: np.ndarray   # (h, w) instance index (1..K) on thing pixels, 0 elsewhere
    classes: list[int]     # class of instance k+1
    areas: list[int]       # pixel count of instance k+1
    centers: np.ndarray    # (K, 2) centre pixel (y, x) of instance k+1
    leaf_count: int


def find_centers(center: torch.Tensor, threshold: float, nms_kernel: int, top_k: int) -> torch.Tensor:
    """(1, h, w) heatmap -> (K, 2) integer (y, x) local maxima at or above ``threshold``, strongest first.

    The Rust decoder's rule (``inference/src/postprocess.rs::find_peaks``), exactly: a pixel is a peak
    when it equals the max-pool of its ``nms_kernel`` window, and of equal values within that window
    only the first in raster order is kept, so a plateau (common when the map is rounded, e.g. to
    bfloat16) gives one peak, not one per pixel. Ties in score are ordered by (y, x).
    """
    heat = center[0]
    h, w = heat.shape
    r = nms_kernel // 2
    pooled = F.max_pool2d(center[None], nms_kernel, stride=1, padding=r)[0, 0]
    keep = (heat == pooled) & (heat >= threshold)
    if keep.any():
        # An equal value at an earlier raster position within the window: (dy < 0, any dx) or (0, dx < 0).
        padded = F.pad(heat[None, None], (r, r, r, r), value=float("nan"))[0, 0]
        earlier_tie = torch.zeros_like(keep)
        for dy in range(-r, 1):
            for dx in range(-r, r + 1):
                if dy == 0 and dx >= 0:
                    break
                earlier_tie |= padded[r + dy:r + dy + h, r + dx:r + dx + w] == heat
        keep &= ~earlier_tie
    ys, xs = torch.nonzero(keep, as_tuple=True)  # raster order
    scores = heat[ys, xs]
    order = torch.argsort(scores, descending=True, stable=True)[:top_k]
    return torch.stack([ys[order], xs[order]], dim=1)


def decode(semantic: torch.Tensor, center: torch.Tensor, offset: torch.Tensor, contract: Contract) -> Panoptic:
    """Decode one image's (4,h,w), (1,h,w), (2,h,w) outputs with the contract's post-processing defaults."""
    pp = contract.raw["postprocess"]
    sem = semantic.argmax(0)
    h, w = sem.shape
    centers = find_centers(center, float(pp["center_threshold"]), int(pp["nms_kernel"]), int(pp["top_k"]))
    thing = torch.zeros_like(sem, dtype=torch.bool)
    for c in contract.things:
        thing |= sem == c
    inst = torch.zeros((h, w), dtype=torch.int64)
    classes: list[int] = []
    areas: list[int] = []
    if len(centers) and thing.any():
        ys, xs = torch.nonzero(thing, as_tuple=True)
        py = ys.float() + offset[0, ys, xs]
        px = xs.float() + offset[1, ys, xs]
        d = (py[:, None] - centers[None, :, 0].float()) ** 2 + (px[:, None] - centers[None, :, 1].float()) ** 2
        inst[ys, xs] = d.argmin(1) + 1
        nc = contract.num_classes
        votes = torch.zeros((len(centers) + 1, nc), dtype=torch.int64)
        votes.index_put_((inst[ys, xs], sem[ys, xs]), torch.ones_like(ys), accumulate=True)
        classes = votes[1:].argmax(1).tolist()
        areas = votes[1:].sum(1).tolist()
    min_area = int(pp["min_leaf_area"])
    count = sum(1 for c, a in zip(classes, areas) if c == contract.leaf and a >= min_area)
    return Panoptic(sem.numpy(), inst.numpy(), classes, areas, centers.numpy(), count)


def label_leaf_count(label: np.ndarray, contract: Contract) -> int:
    """Leaf instances in a label that would survive at the output stride with ``min_leaf_area``."""
    from ..targets import downsample_label

    low = downsample_label(label, contract.stride)
    div = contract.label_divisor
    ids, counts = np.unique(low[(low // div == contract.leaf) & (low % div > 0)], return_counts=True)
    return int((counts >= int(contract.raw["postprocess"]["min_leaf_area"])).sum())


def count_agreement(errs: list[int]) -> tuple[float, float, float, float]:
    """Exact share, share within one, RMSE and bias of per-image count errors (predicted − true)."""
    e = np.array(errs, dtype=float)
    return float(np.mean(e == 0)), float(np.mean(np.abs(e) <= 1)), float(np.sqrt(np.mean(e ** 2))), float(e.mean())
