#!/usr/bin/env python3
"""A straightforward Python twin of phyllo's inference path, for `phyllo bench`.

PIL + numpy + onnxruntime, one process, the same model, scale rule, region,
tiling, stitching and Panoptic-DeepLab post-processing as the Rust code
(inference/src/{tiling,region,stitch,postprocess}.rs). It is the baseline a
scientist would write first; `phyllo bench` runs it on the same frames in the
same run and reports the ratio. It leaves out the separate-pieces stage
(inference/src/pieces.rs, session 23), which moves no count on the bench's
frames (`phyllo bench` still reports the same leaf count on all 8) and costs
the Rust side under 1 ms a frame.

    python3 models/reference_pipeline.py --model models/phyllo.onnx --frames DIR [--repeat 3]

Prints one line per image (file, leaf count) and, last, a JSON summary with
mean ms per stage, images/s and the counts.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import onnxruntime as ort
from numpy.lib.stride_tricks import sliding_window_view
from PIL import Image

CONTRACT = tomllib.loads((Path(__file__).parent / "contract.toml").read_text())


def scale_for(w: int, h: int) -> float:
    spec = CONTRACT["input"]
    if abs((w / h) / spec["frame_aspect"] - 1.0) <= spec["frame_aspect_tolerance"] and h >= spec["frame_height"]:
        return spec["frame_height"] / h
    return spec["crop_scale"]


def median_colour(img: np.ndarray) -> np.ndarray:
    """Per-channel median as region.rs computes it (the lower median of an even count)."""
    flat = np.sort(img.reshape(-1, 3), axis=0)
    return flat[(len(flat) + 1) // 2 - 1]


def plant_colour(img: np.ndarray) -> np.ndarray:
    """Green or senescent pixels, white-balanced on the image median (region.rs)."""
    white = median_colour(img).astype(np.float32).clip(1, None)
    n = img.astype(np.float32) / white
    r, g, b = n[..., 0], n[..., 1], n[..., 2]
    backlit = (np.maximum(np.maximum(r, g), b) < 0.5) & (g - b > 0.05) & (g >= r - 0.03)
    return (g - np.maximum(r, b) > 0.06) | ((r - b > 0.25) & (g - b > 0.15)) | backlit


def plant_bbox(img: np.ndarray, trim: float = 0.02, margin: int = 12, min_pixels: int = 40):
    h, w, _ = img.shape
    mask = plant_colour(img)
    total = int(mask.sum())
    if total < min_pixels:
        return None
    cut = int(total * trim)

    def span(hist):
        c = np.cumsum(hist)
        lo = int(np.argmax(c > cut))
        rc = np.cumsum(hist[::-1])
        hi = len(hist) - int(np.argmax(rc > cut))
        return lo, max(hi, lo + 1)

    x0, x1 = span(mask.sum(0))
    y0, y1 = span(mask.sum(1))
    return max(x0 - margin, 0), max(y0 - margin, 0), min(x1 + margin, w), min(y1 + margin, h)


def tile_starts(length: int, tile: int, overlap: int, stride: int) -> list[int]:
    if length <= tile:
        return [0]
    step = tile - overlap
    n = -(-(length - tile) // step) + 1
    last = length - tile
    return [min(last * i // (n - 1) // stride * stride, last // stride * stride) for i in range(n)]


def zoom_for(rows) -> float:
    """The contract's zoom for a first pass whose instances span ``rows`` (output px)."""
    inp = CONTRACT["input"]
    if rows is None or not inp.get("zoom_plant_height", 0):
        return 1.0
    height = (rows[1] - rows[0]) * CONTRACT["outputs"]["stride"] + 2 * ZOOM_MARGIN
    z = min(max(inp["zoom_plant_height"] / max(height, 1), 1.0), inp.get("max_zoom", 1.0))
    return z if z >= MIN_ZOOM else 1.0


def prepare(img: np.ndarray, s: float | None = None):
    tile, stride = CONTRACT["input"]["tile"], CONTRACT["outputs"]["stride"]
    h, w, _ = img.shape
    s = s or scale_for(w, h)
    sw, sh = max(round(w * s), 1), max(round(h * s), 1)
    scaled = np.asarray(Image.fromarray(img).resize((sw, sh), Image.BILINEAR))
    found = plant_bbox(scaled)
    box = found or (0, 0, sw, sh)

    def span(lo, hi, length):
        want = max(hi - lo, tile)
        want = -(-want // stride) * stride
        start = (lo + hi) // 2 - want // 2
        start = min(max(start, 0), length - want) if length >= want else -((want - length) // 2)
        return start, want

    ox, cw = span(box[0], box[2], sw)
    oy, ch = span(box[1], box[3], sh)
    canvas = np.empty((ch, cw, 3), np.uint8)
    canvas[:] = median_colour(scaled)  # the chamber wall (tiling.rs)
    ys, xs = max(oy, 0), max(ox, 0)
    ye, xe = min(oy + ch, sh), min(ox + cw, sw)
    canvas[ys - oy:ye - oy, xs - ox:xe - ox] = scaled[ys:ye, xs:xe]
    ov = CONTRACT["input"]["tile_overlap"]
    tiles = [(x, y) for y in tile_starts(ch, tile, ov, stride) for x in tile_starts(cw, tile, ov, stride)]
    plant = None if found is None else (box[0] - ox, box[1] - oy, box[2] - ox, box[3] - oy)
    return canvas, tiles, plant, s


def normalise(canvas: np.ndarray, tiles) -> np.ndarray:
    t = CONTRACT["input"]["tile"]
    mean = np.array(CONTRACT["input"]["mean"], np.float32)
    std = np.array(CONTRACT["input"]["std"], np.float32)
    batch = np.stack([canvas[y:y + t, x:x + t] for x, y in tiles]).astype(np.float32) / 255.0
    return ((batch - mean) / std).transpose(0, 3, 1, 2).copy()


def stitch(sem, cen, off, tiles, cw, ch):
    s = CONTRACT["outputs"]["stride"]
    t = sem.shape[-1]
    h, w = ch // s, cw // s
    out_sem = np.zeros((4, h, w), np.float32)
    out_cen = np.zeros((h, w), np.float32)
    out_off = np.zeros((2, h, w), np.float32)
    best = np.full((h, w), -1, np.int64)
    far = np.iinfo(np.int64).max
    idx = np.arange(t)
    for k, (tx, ty) in enumerate(tiles):
        ox, oy = tx // s, ty // s
        top = idx if oy > 0 else np.full(t, far)
        bottom = t - 1 - idx if oy + t < h else np.full(t, far)
        left = idx if ox > 0 else np.full(t, far)
        right = t - 1 - idx if ox + t < w else np.full(t, far)
        margin = np.minimum(np.minimum(top, bottom)[:, None], np.minimum(left, right)[None, :])
        region = (slice(oy, oy + t), slice(ox, ox + t))
        take = margin > best[region]
        best[region][take] = margin[take]
        out_sem[:, region[0], region[1]][:, take] = sem[k][:, take]
        out_cen[region][take] = cen[k, 0][take]
        out_off[:, region[0], region[1]][:, take] = off[k][:, take]
    return out_sem, out_cen, out_off


PLANT_MARGIN = 16  # model pixels of slack around the plant box, as in counter.rs
ZOOM_MARGIN = 12  # model pixels above and below the instances, as BOX_MARGIN in zoom.rs
MIN_ZOOM = 1.1  # smaller enlargements are skipped, as in zoom.rs


ATTACH_RADIUS = 3  # output pixels, as DEFAULT_ATTACH_RADIUS in postprocess.rs


def components(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """8-connected components by flood fill: labels from 1, and their number."""
    h, w = mask.shape
    label = np.zeros((h, w), np.int32)
    n = 0
    for y0, x0 in zip(*np.nonzero(mask)):
        if label[y0, x0]:
            continue
        n += 1
        label[y0, x0] = n
        todo = [(y0, x0)]
        while todo:
            y, x = todo.pop()
            for yy in range(max(y - 1, 0), min(y + 2, h)):
                for xx in range(max(x - 1, 0), min(x + 2, w)):
                    if mask[yy, xx] and not label[yy, xx]:
                        label[yy, xx] = n
                        todo.append((yy, xx))
    return label, n


def attached(semantic, inst, n_inst, canvas):
    """Per instance: whether at least half its pixels lie in a plant body (attachment.rs)."""
    r, s = ATTACH_RADIUS, CONTRACT["outputs"]["stride"]
    plant = semantic != 0
    padded = np.pad(plant, r)
    bridged = sliding_window_view(padded, (2 * r + 1, 2 * r + 1)).any(axis=(2, 3))
    body, n = components(bridged)
    green = plant_colour(canvas)[s // 2::s, s // 2::s][: plant.shape[0], : plant.shape[1]]
    colour = np.bincount(body[plant & green], minlength=n + 1)
    size = np.bincount(body[plant], minlength=n + 1)
    score = colour if colour.any() else size
    kept = (score > 0) & (score >= 0.25 * score.max())
    in_body = kept[body]
    ids = inst[inst > 0]
    area = np.bincount(ids, minlength=n_inst + 1)
    inside = np.bincount(ids[in_body[inst > 0]], minlength=n_inst + 1)
    return (inside >= 0.5 * area)[1:]


def postprocess(sem, cen, off, plant=None, canvas=None):
    pp = CONTRACT["postprocess"]
    things = CONTRACT["classes"]["things"]
    semantic = sem.argmax(0)
    r = pp["nms_kernel"] // 2
    padded = np.pad(cen, r, constant_values=-np.inf)
    pooled = sliding_window_view(padded, (2 * r + 1, 2 * r + 1)).max(axis=(2, 3))
    ys, xs = np.nonzero((cen >= pp["center_threshold"]) & (cen >= pooled))
    order = np.argsort(-cen[ys, xs], kind="stable")[: pp["top_k"]]
    cy, cx = ys[order], xs[order]
    thing = np.isin(semantic, things)
    ty, tx = np.nonzero(thing)
    if len(cy) == 0 or len(ty) == 0:
        return 0, None
    py = ty + off[0, ty, tx]
    px = tx + off[1, ty, tx]
    d = (py[:, None] - cy[None, :]) ** 2 + (px[:, None] - cx[None, :]) ** 2
    inst = d.argmin(1)
    votes = np.zeros((len(cy), 4), np.int64)
    np.add.at(votes, (inst, semantic[ty, tx]), 1)
    areas = votes.sum(1)
    classes = votes.argmax(1)
    keep = areas >= max(pp["min_leaf_area"], 1)
    if canvas is not None:
        ids = np.zeros(semantic.shape, np.int64)
        ids[ty, tx] = inst + 1
        keep &= attached(semantic, ids, len(cy), canvas)
    if plant is not None:
        # Instances centred outside the plant's box are chamber, not plant.
        s = CONTRACT["outputs"]["stride"]
        x0, y0, x1, y1 = plant
        m = PLANT_MARGIN
        keep &= (cx * s >= x0 - m) & (cx * s < x1 + m) & (cy * s >= y0 - m) & (cy * s < y1 + m)
    kept = keep[inst]
    rows = (int(ty[kept].min()), int(ty[kept].max()) + 1) if kept.any() else None
    return int(((classes == CONTRACT["classes"]["leaf"]) & keep).sum()), rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True)
    ap.add_argument("--frames", required=True, type=Path)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--batch", type=int, default=4)
    args = ap.parse_args()
    opts = ort.SessionOptions()
    if args.threads:
        opts.intra_op_num_threads = args.threads
    sess = ort.InferenceSession(args.model, opts, providers=["CPUExecutionProvider"])
    names = [CONTRACT["outputs"][k] for k in ("semantic", "center", "offset")]
    frames = sorted(p for p in args.frames.iterdir() if p.suffix.lower() == ".png")
    if not frames:
        print(f"{args.frames}: no .png frames", file=sys.stderr)
        return 2

    def count(path: Path, stats: dict | None):
        t0 = time.perf_counter()
        img = np.asarray(Image.open(path).convert("RGB"))
        t1 = time.perf_counter()
        n, rows, scale = one_pass(img, None, stats)
        z = zoom_for(rows)
        if z > 1.0:
            # A small plant is counted again, enlarged (the contract's zoom).
            n, _, _ = one_pass(img, scale * z, stats)
        if stats is not None:
            stats["decode"] += (t1 - t0) * 1e3
            stats["total"] += (time.perf_counter() - t0) * 1e3
        return n

    def one_pass(img: np.ndarray, scale: float | None, stats: dict | None):
        t1 = time.perf_counter()
        canvas, tiles, plant, scale = prepare(img, scale)
        batch = normalise(canvas, tiles)
        t2 = time.perf_counter()
        outs = [sess.run(names, {CONTRACT["input"]["name"]: batch[i:i + args.batch]})
                for i in range(0, len(batch), args.batch)]
        sem, cen, off = (np.concatenate([o[j] for o in outs]) for j in range(3))
        t3 = time.perf_counter()
        n, rows = postprocess(*stitch(sem, cen, off, tiles, canvas.shape[1], canvas.shape[0]), plant, canvas)
        t4 = time.perf_counter()
        if stats is not None:
            for k, v in (("tile", t2 - t1), ("inference", t3 - t2), ("postprocess", t4 - t3)):
                stats[k] += v * 1e3
            stats["tiles"] += len(tiles)
        return n, rows, scale

    count(frames[0], None)  # warm-up, as phyllo bench does
    stats = dict.fromkeys(("decode", "tile", "inference", "postprocess", "total", "tiles"), 0.0)
    counts = []
    t0 = time.perf_counter()
    for rep in range(args.repeat):
        for f in frames:
            n = count(f, stats)
            if rep == 0:
                counts.append(n)
                print(f"{f}\t{n}")
    wall = time.perf_counter() - t0
    images = len(frames) * args.repeat
    summary = {k: stats[k] / images for k in ("decode", "tile", "inference", "postprocess", "total")}
    summary.update(images=images, images_per_s=images / wall, tiles_per_image=stats["tiles"] / images,
                   counts=counts)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
