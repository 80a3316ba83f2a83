"""The Python decoder's peak rule is the Rust decoder's (inference/src/postprocess.rs::find_peaks)."""

import numpy as np
import torch

from phyllo_train.tools.postprocess import find_centers


def rust_find_peaks(heat: np.ndarray, threshold: float, kernel: int, top_k: int) -> list[tuple[int, int]]:
    """A line-by-line port of the Rust loop, the reference for the vectorised rule."""
    h, w = heat.shape
    r = kernel // 2
    peaks = []
    for y in range(h):
        for x in range(w):
            v = heat[y, x]
            if v < threshold:
                continue
            if v < heat[max(0, y - r):y + r + 1, max(0, x - r):x + r + 1].max():
                continue
            earlier_tie = any(
                (yy < y or xx < x) and heat[yy, xx] == v
                for yy in range(max(0, y - r), y + 1) for xx in range(max(0, x - r), min(w, x + r + 1)))
            if not earlier_tie:
                peaks.append((-float(v), y, x))
    return [(y, x) for _, y, x in sorted(peaks)[:top_k]]


def test_a_plateau_gives_one_peak():
    heat = np.zeros((20, 20), np.float32)
    heat[5:8, 9:11] = 0.75  # a 3x2 plateau
    got = find_centers(torch.from_numpy(heat)[None], 0.3, 7, 64).tolist()
    assert got == [[5, 9]], "one peak per plateau, the first in raster order"


def test_a_value_at_the_threshold_is_a_peak():
    heat = np.zeros((9, 9), np.float32)
    heat[4, 4] = 0.3
    assert find_centers(torch.from_numpy(heat)[None], 0.3, 3, 8).tolist() == [[4, 4]]


def test_rounded_heatmaps_decode_as_in_rust():
    """Maps rounded to a few levels (as bfloat16 rounds a heatmap) are full of ties: same peaks, same order."""
    rng = np.random.default_rng(7)
    for trial in range(12):
        smooth = rng.random((40, 48)).astype(np.float32)
        for _ in range(2):  # blur a little so peaks spread over neighbours
            smooth = (smooth + np.roll(smooth, 1, 0) + np.roll(smooth, 1, 1)) / 3
        levels = 8 + trial
        heat = (np.round(smooth * levels) / levels).astype(np.float32)
        for kernel in (3, 5, 7):
            got = [tuple(p) for p in find_centers(torch.from_numpy(heat)[None], 0.4, kernel, 30).tolist()]
            assert got == rust_find_peaks(heat, 0.4, kernel, 30), (trial, kernel)
