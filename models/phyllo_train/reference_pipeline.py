"""Python reference of the daemon's inference path, for benchmarks and cross-checks.

Mirrors ``inference/src`` (tiling.rs, region.rs, stitch.rs, postprocess.rs,
counter.rs) as of commit 7297cc3: scale to the contract's scale, find the
plant region by colour, lay out overlapping 512 tiles on a stride-aligned
canvas, run ONNX Runtime in batches, stitch per-pixel from the tile where the
pixel is farthest from an interior tile border, decode once (Panoptic-DeepLab),
count leaves. Known differences from the Rust code: resizing uses Pillow's
bilinear filter (Rust: fast_image_resize's bilinear convolution), so pixels
may differ by one grey level; centre NMS ties on exact plateaus are resolved
by max-pool equality rather than raster order.

    python -m phyllo_train.reference_pipeline MODEL.onnx IMAGE... [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from .contract import Contract, load_contract
from .postprocess import find_centers


def scale_for(c: Contract, w: int, h: int) -> float:
    """Model pixels per original pixel: frames by aspect ratio to ``frame_height``, crops to ``crop_long_side``."""
    inp = c.raw["input"]
    if abs((w / h) / inp["frame_aspect"] - 1.0) <= inp["frame_aspect_tolerance"]:
        return inp["frame_height"] / h
    return inp["crop_long_side"] / max(w, h)


def median_colour(img: np.ndarray) -> np.ndarray:
    """Per-channel median (lower median over the histogram, as region.rs)."""
    flat = img.reshape(-1, 3)
    half = -(-flat.shape[0] // 2)
    out = []
    for ch in range(3):
        cum = np.cumsum(np.bincount(flat[:, ch], minlength=256))
        out.append(int(np.argmax(cum >= half)))
    return np.array(out, np.float32)


def plant_mask(img: np.ndarray) -> np.ndarray:
    """region.rs ``is_plant_pixel`` on every pixel, white-balanced against the median colour."""
    n = img.astype(np.float32) / np.maximum(median_colour(img), 1.0)
    r, g, b = n[..., 0], n[..., 1], n[..., 2]
    return (g - np.maximum(r, b) > 0.06) | ((r - b > 0.25) & (g - b > 0.15))


def _trimmed_span(hist: np.ndarray, cut: int) -> tuple[int, int]:
    cum = np.cumsum(hist)
    lo = int(np.argmax(cum > cut)) if (cum > cut).any() else 0
    rcum = np.cumsum(hist[::-1])
    hi = len(hist) - int(np.argmax(rcum > cut)) if (rcum > cut).any() else len(hist)
    return lo, max(hi, lo + 1)


def plant_bbox(img: np.ndarray, trim: float = 0.02, margin: int = 12, min_pixels: int = 40) -> tuple[int, int, int, int] | None:
    """Trimmed bounding box ``(x0, y0, x1, y1)`` of plant-coloured pixels, grown by ``margin``."""
    m = plant_mask(img)
    total = int(m.sum())
    if total < min_pixels:
        return None
    cut = int(total * trim)
    x0, x1 = _trimmed_span(m.sum(0), cut)
    y0, y1 = _trimmed_span(m.sum(1), cut)
    h, w = m.shape
    return max(0, x0 - margin), max(0, y0 - margin), min(w, x1 + margin), min(h, y1 + margin)


def tile_starts(length: int, tile: int, overlap: int, stride: int) -> list[int]:
    """Evenly spaced, stride-aligned tile starts covering ``length`` with at least ``overlap``."""
    if length <= tile:
        return [0]
    step = tile - overlap
    n = -(-(length - tile) // step) + 1
    last = length - tile
    return [min(last * i // (n - 1) // stride * stride, last // stride * stride) for i in range(n)]


@dataclass
class Canvas:
    """Model-scale pixels around the plant, and the tiles cut from them."""

    image: np.ndarray          # (H, W, 3) uint8, H and W multiples of the stride, >= one tile
    scale: float
    origin: tuple[int, int]    # (x, y) of the canvas's top-left in the scaled image
    tiles: list[tuple[int, int]] = field(default_factory=list)  # (x, y) top-left corners


def prepare(c: Contract, img: np.ndarray, region: str = "auto") -> Canvas:
    """tiling.rs ``prepare``: scale, choose the region, pad to a stride-aligned canvas, lay out tiles."""
    tile, stride = c.tile, c.stride
    h, w = img.shape[:2]
    scale = scale_for(c, w, h)
    nw, nh = max(1, round(w * scale)), max(1, round(h * scale))
    scaled = img if (nw, nh) == (w, h) else np.asarray(Image.fromarray(img).resize((nw, nh), Image.BILINEAR))
    sh, sw = scaled.shape[:2]
    box = plant_bbox(scaled) if region == "auto" else None
    rx0, ry0, rx1, ry1 = box or (0, 0, sw, sh)

    def span(lo: int, hi: int, length: int) -> tuple[int, int]:
        want = -(-max(hi - lo, tile) // stride) * stride
        start = (lo + hi) // 2 - want // 2
        start = min(max(start, 0), length - want) if length >= want else -((want - length) // 2)
        return start, want

    ox, cw = span(rx0, rx1, sw)
    oy, ch = span(ry0, ry1, sh)
    border = np.concatenate([scaled[0], scaled[-1], scaled[:, 0], scaled[:, -1]])
    fill = np.sort(border, axis=0)[len(border) // 2]
    canvas = np.empty((ch, cw, 3), np.uint8)
    canvas[:] = fill
    ys, xs = max(0, oy), max(0, ox)
    ye, xe = min(sh, oy + ch), min(sw, ox + cw)
    canvas[ys - oy:ye - oy, xs - ox:xe - ox] = scaled[ys:ye, xs:xe]
    overlap = c.tile_overlap
    tiles = [(x, y) for y in tile_starts(ch, tile, overlap, stride) for x in tile_starts(cw, tile, overlap, stride)]
    return Canvas(canvas, scale, (ox, oy), tiles)


def batch_tensor(c: Contract, canvas: np.ndarray, tiles: list[tuple[int, int]]) -> np.ndarray:
    """NCHW float32 batch of the given tiles, normalised per the contract."""
    t = c.tile
    x = np.stack([canvas[y:y + t, x0:x0 + t] for x0, y in tiles]).astype(np.float32) / 255.0
    x = (x - np.asarray(c.mean, np.float32)) / np.asarray(c.std, np.float32)
    return np.ascontiguousarray(x.transpose(0, 3, 1, 2))


def stitch(outs: list[np.ndarray], tiles: list[tuple[int, int]], cw: int, ch: int, stride: int) -> list[np.ndarray]:
    """stitch.rs: each output pixel from the tile where it is farthest from an interior tile border."""
    sem, cen, off = outs
    n, k, t, _ = sem.shape
    h, w = ch // stride, cw // stride
    res = [np.zeros((k, h, w), np.float32), np.zeros((1, h, w), np.float32), np.zeros((2, h, w), np.float32)]
    best = np.full((h, w), -1, np.int64)
    far = np.iinfo(np.int64).max
    ii = np.arange(t)
    for j, (tx, ty) in enumerate(tiles):
        ox, oy = tx // stride, ty // stride
        hh, ww = min(t, h - oy), min(t, w - ox)
        top = ii[:hh] if oy > 0 else np.full(hh, far)
        bottom = (t - 1 - ii[:hh]) if oy + t < h else np.full(hh, far)
        left = ii[:ww] if ox > 0 else np.full(ww, far)
        right = (t - 1 - ii[:ww]) if ox + t < w else np.full(ww, far)
        margin = np.minimum(np.minimum(top, bottom)[:, None], np.minimum(left, right)[None, :])
        region = best[oy:oy + hh, ox:ox + ww]
        take = margin > region
        region[take] = margin[take]
        for dst, src in zip(res, (sem[j], cen[j], off[j])):
            view = dst[:, oy:oy + hh, ox:ox + ww]
            view[:, take] = src[:, :hh, :ww][:, take]
    return res


@dataclass
class Result:
    """Count and timings for one image."""

    leaf_count: int
    segments: list[dict]
    tiles: int
    ms: dict[str, float]


def panoptic(c: Contract, sem: np.ndarray, cen: np.ndarray, off: np.ndarray) -> tuple[np.ndarray, list[dict]]:
    """postprocess.rs ``panoptic``: instances with area >= min_leaf_area, classes by majority vote."""
    pp = c.raw["postprocess"]
    semantic = sem.argmax(0)
    h, w = semantic.shape
    centres = find_centers(torch.from_numpy(cen), float(pp["center_threshold"]), int(pp["nms_kernel"]),
                           int(pp["top_k"])).numpy()
    inst = np.zeros((h, w), np.int64)
    thing = np.isin(semantic, c.things)
    segs: list[dict] = []
    if len(centres) and thing.any():
        ys, xs = np.nonzero(thing)
        ty, tx = ys + off[0, ys, xs], xs + off[1, ys, xs]
        d = (centres[None, :, 0] - ty[:, None]) ** 2 + (centres[None, :, 1] - tx[:, None]) ** 2
        owner = d.argmin(1)
        inst[ys, xs] = owner + 1
        votes = np.zeros((len(centres), c.num_classes), np.int64)
        np.add.at(votes, (owner, semantic[ys, xs]), 1)
        areas = votes.sum(1)
        for j in range(len(centres)):
            if areas[j] >= max(1, int(pp["min_leaf_area"])):
                segs.append({"class": int(votes[j].argmax()), "area": int(areas[j]),
                             "centre_xy": [int(centres[j, 1]), int(centres[j, 0])],
                             "score": float(cen[0, centres[j, 0], centres[j, 1]])})
    return inst, segs


class ReferencePipeline:
    """Model + contract; ``run(image)`` counts leaves as the daemon does."""

    def __init__(self, model: str | Path, contract: Contract | None = None, threads: int = 2, batch: int = 4):
        import onnxruntime as ort

        self.c = contract or load_contract()
        so = ort.SessionOptions()
        so.intra_op_num_threads = threads
        so.add_session_config_entry("session.intra_op.allow_spinning", "0")
        self.sess = ort.InferenceSession(str(model), so, providers=["CPUExecutionProvider"])
        meta = self.sess.get_modelmeta().custom_metadata_map
        got = meta.get(self.c.meta_contract_version)
        if got != str(self.c.version):
            raise ValueError(f"{model}: contract version {got!r}, this code speaks {self.c.version}")
        self.batch = batch

    def run(self, img: np.ndarray, region: str = "auto") -> Result:
        """Count the leaves of an (H, W, 3) uint8 RGB image."""
        t0 = time.perf_counter()
        cv = prepare(self.c, img, region)
        t1 = time.perf_counter()
        parts: list[list[np.ndarray]] = []
        for i in range(0, len(cv.tiles), self.batch):
            x = batch_tensor(self.c, cv.image, cv.tiles[i:i + self.batch])
            parts.append(self.sess.run(list(self.c.output_names), {self.c.input_name: x}))
        outs = [np.concatenate([p[k] for p in parts]) for k in range(3)]
        t2 = time.perf_counter()
        sem, cen, off = stitch(outs, cv.tiles, cv.image.shape[1], cv.image.shape[0], self.c.stride)
        _, segs = panoptic(self.c, sem, cen, off)
        t3 = time.perf_counter()
        leaves = sum(1 for s in segs if s["class"] == self.c.leaf)
        ms = {"tile": (t1 - t0) * 1e3, "inference": (t2 - t1) * 1e3, "postprocess": (t3 - t2) * 1e3}
        return Result(leaves, segs, len(cv.tiles), ms)


def main(argv: list[str] | None = None) -> int:
    """CLI: print a leaf count per image."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.reference_pipeline", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model")
    ap.add_argument("images", nargs="+", type=Path)
    ap.add_argument("--region", choices=["auto", "full"], default="auto")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    pipe = ReferencePipeline(a.model, threads=a.threads)
    for p in a.images:
        with Image.open(p) as im:
            r = pipe.run(np.asarray(im.convert("RGB")), a.region)
        if a.json:
            print(json.dumps({"file": str(p), "leaf_count": r.leaf_count, "tiles": r.tiles, "ms": r.ms,
                              "segments": r.segments}))
        else:
            print(f"{p}\t{r.leaf_count}\t{r.tiles} tiles\t" + " ".join(f"{k} {v:.0f} ms" for k, v in r.ms.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
