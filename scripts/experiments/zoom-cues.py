#!/usr/bin/env python3
"""Two cues a frame or crop might give of the camera's zoom, measured on the dev images
(models/EXPERIMENTS.md, "What a zoomed camera costs"): neither is adopted.

    models/.venv/bin/python scripts/experiments/zoom-cues.py ../shared/data/unl-maize-dev

- carrier: the black carrier as two dark legs (vertical runs) joined by a dark bar near
  the plant's axis, searched in each frame; prints what it finds and how many it found.
- leaf width: the 75th percentile of the green mask's thickness (shortest of four
  directions' runs through each pixel) of each crop at the contract's crop scale 0.5,
  per experiment (81-*, 402-*).
"""

import sys
from pathlib import Path

import numpy as np
from PIL import Image


def runs(line: np.ndarray, gap: int = 0) -> list[list[int]]:
    """[start, end) of the True runs of a 1-D mask, joining runs `gap` or fewer apart."""
    d = np.diff(np.concatenate([[0], line.astype(np.int8), [0]]))
    out: list[list[int]] = []
    for a, b in zip(np.where(d == 1)[0], np.where(d == -1)[0]):
        if out and a - out[-1][1] <= gap:
            out[-1][1] = b
        else:
            out.append([a, b])
    return out


def carrier(im: np.ndarray):
    """(left, right, row) of a dark bar with a dark leg down from each end, or None."""
    h, w, _ = im.shape
    dark = im.max(axis=2) < 80
    g = im[..., 1]
    green = (g > im[..., 0] + 8) & (g > im[..., 2] + 8)
    axis = np.median(np.where(green)[1]) if green.any() else w / 2
    band_h = max(2, int(0.008 * h))
    for y in range(int(0.4 * h), h - 3):
        for a, b in runs(dark[y:y + band_h].any(axis=0), gap=3):
            length = b - a
            if not (0.04 * w <= length <= 0.3 * w and a < axis < b):
                continue
            leg, depth = max(3, int(0.12 * length)), min(int(0.3 * length), h - y)
            if depth < 0.1 * length:
                continue
            left = dark[y:y + depth, a:a + leg].any(axis=1).mean()
            right = dark[y:y + depth, b - leg:b].any(axis=1).mean()
            above = dark[max(0, y - int(0.1 * length)):y, a + leg:b - leg].mean() if y > 0 else 0.0
            if left > 0.8 and right > 0.8 and above < 0.3:
                return a, b, y
    return None


def leaf_width(im: np.ndarray, scale: float) -> float:
    """75th percentile of the green mask's thickness, in model pixels."""
    r, g, b = im[..., 0], im[..., 1], im[..., 2]
    m = (g > r + 8) & (g > b + 8) & (g < 235)
    if m.sum() < 50:
        return float("nan")

    def run_lengths(mask: np.ndarray) -> np.ndarray:
        out = np.zeros(mask.shape, np.float32)
        for y in range(mask.shape[0]):
            for a, b in runs(mask[y]):
                out[y, a:b] = b - a
        return out

    def diagonal_run_lengths(mask: np.ndarray) -> np.ndarray:
        h, w = mask.shape
        out = np.zeros(mask.shape, np.float32)
        for k in range(-h + 1, w):
            idx = np.arange(max(0, -k), min(h, w - k))
            for a, b in runs(mask[idx, idx + k]):
                out[idx[a:b], idx[a:b] + k] = (b - a) * 1.4142
        return out

    t = np.minimum.reduce([run_lengths(m), run_lengths(m.T).T, diagonal_run_lengths(m),
                           diagonal_run_lengths(m[:, ::-1])[:, ::-1]])
    return float(np.percentile(t[m], 75) * scale)


def main() -> None:
    dev = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/unl-maize-dev")
    read = lambda f: np.asarray(Image.open(f).convert("RGB")).astype(np.int16)  # noqa: E731
    frames = sorted((dev / "images").glob("*.jpg"))
    found = 0
    for f in frames:
        c = carrier(read(f))
        found += c is not None
        print(f"carrier {f.name[:40]}: {'none' if c is None else f'x {c[0]}-{c[1]} row {c[2]}'}")
    print(f"carrier found in {found} of {len(frames)} frames")
    widths: dict[str, list[float]] = {}
    for f in sorted((dev / "crops").glob("*.jpg")):
        widths.setdefault(f.name.split("-")[0], []).append(leaf_width(read(f), 0.5))
    for exp, v in sorted(widths.items()):
        print(f"leaf width {exp}-*: {len(v)} crops, 75th percentile {min(v):.1f}-{max(v):.1f} px")


if __name__ == "__main__":
    main()
