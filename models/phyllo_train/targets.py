"""Panoptic-DeepLab training targets from a panoptic label, at the contract's output stride.

Conventions (shared with the Rust decoder, see models/MODEL.md):

* output pixel (i, j) covers input pixels (s*i .. s*i+s-1, s*j .. s*j+s-1) with
  s = stride; its centre is input coordinate (s*i + (s-1)/2, s*j + (s-1)/2)
  in pixel-index units;
* an instance's centre is the centre of mass of its input pixels, expressed
  in output-pixel coordinates: c_out = (c_in - (s-1)/2) / s;
* offset[:, i, j] = (cy - i, cx - j) in output pixels, on thing pixels only;
* the centre heatmap is max over instances of exp(-d^2 / (2 sigma^2)) around
  the centre rounded to the nearest output pixel, so every peak is exactly 1
  and sits on a pixel; with ``center_sigma_min`` a crowded centre's sigma is
  narrowed (:func:`crowding_sigmas`). The decoder never reads sigma.

Centres belong to the *whole* instance in the source image, not to the part
visible in a crop: the daemon stitches tile outputs into one canvas and then
decodes it once, so a leaf crossing a tile border must point to one centre
from both tiles. In a crop, offsets may therefore point outside the crop, and
the crop's heatmap holds only the (possibly partial) Gaussians of centres that
lie in or near it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .contract import Contract


@dataclass
class Targets:
    """Per-image targets at output resolution (h = H/stride, w = W/stride)."""

    semantic: np.ndarray        # (h, w) int64 class ids
    semantic_weight: np.ndarray  # (h, w) float32
    center: np.ndarray          # (1, h, w) float32 Gaussian heatmap
    center_weight: np.ndarray   # (1, h, w) float32
    offset: np.ndarray          # (2, h, w) float32 (dy, dx) in output pixels
    offset_weight: np.ndarray   # (1, h, w) float32, 1 on thing pixels
    instances: np.ndarray       # (h, w) int32 panoptic id (class*divisor+inst) of thing pixels, else 0
    centers: np.ndarray         # (K, 2) float32 centres (y, x) of thing instances, output px of the crop (may lie outside)


def downsample_label(label: np.ndarray, stride: int) -> np.ndarray:
    """Label at output resolution: the first non-background of each stride x stride block.

    Preferring foreground (rather than a fixed corner) keeps leaves one or two
    input pixels wide from vanishing at stride 2.
    """
    h, w = label.shape[0] // stride, label.shape[1] // stride
    label = label[: h * stride, : w * stride]
    out = np.zeros((h, w), dtype=label.dtype)
    for dy in range(stride):
        for dx in range(stride):
            sub = label[dy::stride, dx::stride]
            np.copyto(out, sub, where=(out == 0))
    return out


def gaussian_heatmap(shape: tuple[int, int], centers: np.ndarray, sigma: float | np.ndarray) -> np.ndarray:
    """Max of unit-peak Gaussians at the given integer (y, x) centres; drawn in 3-sigma windows.

    ``sigma`` is one width for every centre or one per centre (:func:`crowding_sigmas`).
    """
    h, w = shape
    heat = np.zeros((h, w), dtype=np.float32)
    sigmas = np.broadcast_to(np.asarray(sigma, dtype=np.float64), (len(centers),))
    kernels: dict[float, tuple[int, np.ndarray]] = {}
    for (cy, cx), sg in zip(centers.astype(int), sigmas):
        if sg not in kernels:
            r = int(np.ceil(3 * sg))
            g1 = np.arange(-r, r + 1, dtype=np.float32)
            kernels[sg] = (r, np.exp(-(g1[:, None] ** 2 + g1[None, :] ** 2) / (2 * sg * sg)))
        r, g = kernels[sg]
        y0, y1, x0, x1 = max(0, cy - r), min(h, cy + r + 1), max(0, cx - r), min(w, cx + r + 1)
        if y0 >= y1 or x0 >= x1:
            continue
        patch = g[y0 - (cy - r): y1 - (cy - r), x0 - (cx - r): x1 - (cx - r)]
        np.maximum(heat[y0:y1, x0:x1], patch, out=heat[y0:y1, x0:x1])
    return heat


# Two Gaussians of width d / 2.5 whose centres lie d apart leave a dip to 46 % of
# the peak between them, the same for every d, so a crowded centre stays one peak.
CROWDING_RATIO = 2.5


def crowding_sigmas(centers: np.ndarray, sigma: float, sigma_min: float) -> np.ndarray:
    """One Gaussian width per centre: ``sigma``, narrowed to the nearest other centre's
    distance / :data:`CROWDING_RATIO` but never under ``sigma_min`` (output pixels).

    Young leaves crowd at the whorl, where the contract's sigma-4 Gaussians of
    neighbours 4–8 px apart blend into one blob that a per-pixel loss fits well
    and the peak finder counts once; an isolated leaf keeps the wide target.
    """
    n = len(centers)
    if n < 2 or sigma_min >= sigma:
        return np.full(n, sigma, dtype=np.float64)
    c = centers.astype(np.float64)
    d2 = ((c[:, None, :] - c[None, :, :]) ** 2).sum(-1)
    np.fill_diagonal(d2, np.inf)
    # Rounded to 0.25 px so that the heatmap's kernels are drawn a few times, not once per centre.
    sig = np.clip(np.sqrt(d2.min(axis=1)) / CROWDING_RATIO, sigma_min, sigma)
    return np.round(sig * 4.0) / 4.0


# Two centres further apart than this many sigmas leave a dip the peak finder sees anyway.
SADDLE_REACH = 4.0


def saddle_pairs(centers: np.ndarray, max_distance: float) -> np.ndarray:
    """(P, 2, 2) pairs of centres (y, x) at most ``max_distance`` apart, each pair once."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    i, j = np.triu_indices(len(c), k=1)
    near = ((c[i] - c[j]) ** 2).sum(-1) <= max_distance ** 2
    return np.stack([c[i[near]], c[j[near]]], axis=1)


def saddle_weight(shape: tuple[int, int], centers: np.ndarray, sigma: float, weight: float) -> np.ndarray:
    """(h, w) centre-loss weight: ``weight`` on the saddle between each two centres closer than
    :data:`SADDLE_REACH` sigmas, else 1.

    Two neighbours' target Gaussians leave a dip between them, and the dip is
    what keeps them two peaks for the decoder. A per-pixel MSE pays for those
    few dip pixels no more than for any other, so a network fits a blob over
    both and the count loses a leaf (models/EXPERIMENTS.md, "What holds the
    pretrained network back"). The saddle is the middle third of the segment
    between the two centres, thickened to one pixel either side.
    """
    h, w = shape
    out = np.ones((h, w), dtype=np.float32)
    if weight == 1.0:
        return out
    for a, b in saddle_pairs(centers, SADDLE_REACH * sigma):
        for t in np.linspace(1.0 / 3.0, 2.0 / 3.0, 5):
            y, x = np.rint(a + t * (b - a)).astype(int)
            y0, y1, x0, x1 = max(0, y - 1), min(h, y + 2), max(0, x - 1), min(w, x + 2)
            if y0 < y1 and x0 < x1:
                np.maximum(out[y0:y1, x0:x1], weight, out=out[y0:y1, x0:x1])
    return out


CENTER_POINTS = ("mass", "blade")


def blade_points(ys: np.ndarray, xs: np.ndarray, inv: np.ndarray, my: np.ndarray,
                 mx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per instance, its own pixel nearest to its centre of mass (input pixels, float).

    ``ys``, ``xs`` are the instances' pixels, ``inv`` each pixel's instance index and
    ``my``, ``mx`` the centres of mass. An arched or hooked blade's centre of mass lies
    in the air beside it, where the network must draw a peak on background and point
    every pixel of the blade at it; long curved real blades come out as two or three
    instances. The nearest pixel of the blade is a centre the blade itself holds; a
    centre of mass that lies on the blade (within half a pixel of one of its pixels'
    centres, in both directions) is kept.
    """
    d = (ys - my[inv]) ** 2 + (xs - mx[inv]) ** 2
    order = np.lexsort((d, inv))
    _, first = np.unique(inv[order], return_index=True)
    pick = order[first]
    # A centre of mass within a pixel of the blade stays where it is: only centres in the air move.
    on_blade = d[pick] <= 0.5
    return (np.where(on_blade, my, ys[pick]).astype(np.float64),
            np.where(on_blade, mx, xs[pick]).astype(np.float64))


def instance_centres(ys: np.ndarray, xs: np.ndarray, inv: np.ndarray,
                     center_point: str = "mass") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centre rows, centre columns, areas) per instance, in the label's input pixels.

    ``ys``, ``xs`` are the instances' pixels and ``inv`` each pixel's instance index;
    ``center_point`` is ``mass`` (centre of mass) or ``blade`` (:func:`blade_points`).
    """
    area = np.bincount(inv).astype(np.float64)
    my, mx = np.bincount(inv, weights=ys) / area, np.bincount(inv, weights=xs) / area
    if center_point == "blade":
        my, mx = blade_points(ys, xs, inv, my, mx)
    return my, mx, area


def make_targets(label: np.ndarray, contract: Contract, *, window: tuple[int, int, int, int] | None = None,
                 small_area: int = 1024, small_weight: float = 3.0,
                 small_center_weight: float = 1.0, center_sigma_min: float | None = None,
                 saddle_center_weight: float = 1.0, center_point: str = "mass") -> Targets:
    """Compute all targets from a (H, W) panoptic label (class*divisor + instance).

    ``window`` = (y0, x0, h, w) in input pixels selects the crop the network
    sees; instance centres are computed on the whole ``label``. ``small_area``
    (input pixels, whole instance) and ``small_weight``: Panoptic-DeepLab
    up-weights the semantic loss on small instances; young leaves are exactly those.
    ``small_center_weight`` weights the centre loss within 2 sigma of a small
    instance's centre the same way (1: the shipped recipe). Merges of small
    neighbouring leaves are most of the model's misses; their peaks are few
    pixels among many, so an unweighted MSE barely pays for them.
    ``center_sigma_min`` narrows crowded centres' Gaussians (:func:`crowding_sigmas`);
    None keeps the contract's sigma for all. ``saddle_center_weight`` weights the
    centre loss on the dips between neighbouring centres (:func:`saddle_weight`; 1: off).
    ``center_point`` is where a leaf's centre lies: ``mass`` (its centre of mass, the
    contract's rule) or ``blade`` (:func:`blade_points`).
    """
    if center_point not in CENTER_POINTS:
        raise ValueError(f"center_point must be one of {CENTER_POINTS}, got {center_point!r}")
    s, div = contract.stride, contract.label_divisor
    label = np.asarray(label).astype(np.int64)
    y0, x0, ch, cw = window if window is not None else (0, 0, *label.shape)
    crop = label[y0:y0 + ch, x0:x0 + cw]
    h, w = ch // s, cw // s

    low = downsample_label(crop, s)
    semantic = (low // div).astype(np.int64)
    semantic[semantic >= contract.num_classes] = 0  # unknown classes read as background
    low_things = np.isin(semantic, contract.things) & (low % div > 0)
    instances = np.where(low_things, low, 0).astype(np.int32)

    sem_w = np.ones((h, w), dtype=np.float32)
    offset = np.zeros((2, h, w), dtype=np.float32)
    off_w = low_things.astype(np.float32)[None]
    centers_int = []
    centers = []
    small_centers: list[tuple[int, int]] = []
    things = np.isin(label // div, contract.things) & (label % div > 0)
    if things.any():
        ys, xs = np.nonzero(things)
        uniq, inv = np.unique(label[ys, xs], return_inverse=True)
        # Centres in whole-label input pixels -> output pixel coordinates of the crop.
        my, mx, area = instance_centres(ys, xs, inv, center_point)
        cy = (my - y0 - (s - 1) / 2.0) / s
        cx = (mx - x0 - (s - 1) / 2.0) / s
        # A sliver smaller than one output pixel gets no centre: it cannot be decoded.
        kept = area >= s * s
        small = kept & (area < small_area)
        # Every output-pixel instance id is some input pixel's, so it is in uniq:
        # one lookup replaces a mask per instance (the loader's hot loop).
        py, px = np.nonzero(instances)
        k = np.searchsorted(uniq, instances[py, px])
        on = kept[k]
        py, px, k = py[on], px[on], k[on]
        offset[0][py, px] = cy[k] - py.astype(np.float32)
        offset[1][py, px] = cx[k] - px.astype(np.float32)
        sem_w[py[small[k]], px[small[k]]] = small_weight
        for kk in np.flatnonzero(kept):
            centers.append((cy[kk], cx[kk]))
            centers_int.append((int(np.rint(cy[kk])), int(np.rint(cx[kk]))))
            if small[kk]:
                small_centers.append(centers_int[-1])
    # Gaussians whose centre lies outside the crop still contribute their visible tail.
    centers_arr = np.array(centers_int, dtype=np.int64).reshape(-1, 2)
    centers_sub = np.array(centers, dtype=np.float64).reshape(-1, 2)
    sigma = contract.center_sigma if center_sigma_min is None else crowding_sigmas(
        centers_sub, contract.center_sigma, center_sigma_min)
    center = gaussian_heatmap((h, w), centers_arr, sigma)
    center_w = saddle_weight((h, w), centers_sub, contract.center_sigma, saddle_center_weight)
    if small_center_weight != 1.0 and small_centers:
        r = 2.0 * contract.center_sigma
        gy, gx = np.ogrid[0:h, 0:w]
        for cy_i, cx_i in small_centers:
            disc = (gy - cy_i) ** 2 + (gx - cx_i) ** 2 <= r * r
            center_w[disc] = np.maximum(center_w[disc], small_center_weight)
    return Targets(
        semantic=semantic,
        semantic_weight=sem_w,
        center=center[None],
        center_weight=center_w[None],
        offset=offset,
        offset_weight=off_w,
        instances=instances,
        centers=np.array(centers, dtype=np.float32).reshape(-1, 2),
    )


def tip_heatmap(points: np.ndarray, window: tuple[int, int, int, int], stride: int, sigma: float) -> np.ndarray:
    """(1, h, w) leaf-tip target of a crop: unit Gaussians at the tips, at output resolution.

    ``points`` are (K, 2) ``(x, y)`` in the whole label's continuous pixel
    coordinates (pixel (i, j) spans [i, i+1) x [j, j+1)), as
    :func:`phyllo_train.augment.augment` returns them; ``window`` is its
    ``(y0, x0, h, w)`` crop. Output pixel i covers input pixels
    ``s*i .. s*i+s-1``, so input coordinate x lands at ``x / s - 0.5``.
    Tips just outside the crop still leave their tails in it.
    """
    y0, x0, ch, cw = window
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    yx = np.stack([(pts[:, 1] - y0) / stride - 0.5, (pts[:, 0] - x0) / stride - 0.5], axis=1)
    heat = gaussian_heatmap((ch // stride, cw // stride), np.rint(yx).astype(np.int64), sigma)
    return heat[None]
