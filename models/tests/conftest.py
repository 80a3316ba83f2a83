"""Test fixtures: a tiny fabricated phyllo-gen-style dataset (unit tests only, never training data)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, ImageDraw

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from phyllo_train.contract import load_contract  # noqa: E402


def _ellipse_polygon(cy, cx, ry, rx, angle, n=48):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    y, x = ry * np.sin(t), rx * np.cos(t)
    ca, sa = np.cos(angle), np.sin(angle)
    return [(float(cx + x[i] * ca - y[i] * sa), float(cy + x[i] * sa + y[i] * ca)) for i in range(n)]


def fabricate(root: Path, n: int = 6, size: int = 512, seed: int = 0) -> Path:
    """Write ``n`` images of a stem plus ellipse 'leaves' with panoptic labels and a manifest."""
    c = load_contract()
    rng = np.random.default_rng(seed)
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "labels").mkdir(parents=True, exist_ok=True)
    rows = []
    for k in range(n):
        img = Image.new("RGB", (size, size), (235, 235, 230))
        lab = Image.new("I", (size, size), 0)
        di, dl = ImageDraw.Draw(img), ImageDraw.Draw(lab)
        sx = size // 2 + int(rng.integers(-30, 30))
        di.rectangle([sx - 4, 120, sx + 4, size - 60], fill=(110, 120, 60))
        dl.rectangle([sx - 4, 120, sx + 4, size - 60], fill=2 * c.label_divisor)
        leaves = int(rng.integers(3, 7))
        for i in range(1, leaves + 1):
            cy = int(rng.integers(140, size - 100))
            side = 1 if i % 2 else -1
            cx = sx + side * int(rng.integers(50, 110))
            poly = _ellipse_polygon(cy, cx, int(rng.integers(6, 12)), int(rng.integers(45, 100)), rng.uniform(-0.5, 0.5))
            g = int(rng.integers(100, 180))
            di.polygon(poly, fill=(40, g, 40))
            dl.polygon(poly, fill=1 * c.label_divisor + i)
        if k % 3 == 2:  # a panicle on top
            di.ellipse([sx - 12, 80, sx + 12, 130], fill=(200, 170, 60))
            dl.ellipse([sx - 12, 80, sx + 12, 130], fill=3 * c.label_divisor + 1)
        label = np.array(lab, dtype=np.int32).astype(np.uint16)
        img.save(root / "images" / f"{k:04d}.png")
        Image.fromarray(label).save(root / "labels" / f"{k:04d}.png")
        visible = len({v % c.label_divisor for v in np.unique(label) if v // c.label_divisor == 1 and v % c.label_divisor})
        rows.append({"image": f"images/{k:04d}.png", "label": f"labels/{k:04d}.png", "plant": f"fake{k}",
                     "view": "top" if k == 5 else f"sv{36 * (k % 5)}", "preset": "fixture", "age_days": 20 + k,
                     "leaf_count": leaves, "visible_leaf_count": visible, "split": "val" if k >= n - 2 else "train",
                     "seed": seed * 1000 + k})
    (root / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return root


@pytest.fixture(scope="session")
def contract():
    """The repository's contract."""
    return load_contract()


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory) -> Path:
    """A 6-image fabricated dataset (4 train, 2 val)."""
    return fabricate(tmp_path_factory.mktemp("tiny"))
