"""Read phyllo-gen datasets (``DIR/manifest.jsonl``) into network inputs and targets."""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import torch
from PIL import Image
from torch.utils.data import Dataset

from .augment import AugmentConfig, apply_photometric, augment_geometry, draw_photometric
from .contract import Contract, load_contract
from .targets import make_targets, tip_heatmap
from .tip_truth import TIP_RULES, tip_targets

REQUIRED_KEYS = ("image", "label", "split")


def read_manifest(root: str | Path, split: str | None = None) -> list[dict]:
    """Rows of ``root/manifest.jsonl`` (optionally only one split), in file order."""
    rows = []
    with open(Path(root) / "manifest.jsonl", encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            if not line.strip():
                continue
            row = json.loads(line)
            missing = [k for k in REQUIRED_KEYS if k not in row]
            if missing:
                raise ValueError(f"manifest line {n}: missing {missing}")
            if split is None or row["split"] == split:
                rows.append(row)
    return rows


def read_label(path: str | Path) -> np.ndarray:
    """A 16-bit grey PNG panoptic label as an (H, W) int32 array."""
    with Image.open(path) as im:
        if im.mode not in ("I;16", "I;16B", "I;16L", "I", "L"):
            raise ValueError(f"{path}: label mode {im.mode}, expected 16-bit grey")
        return np.array(im, dtype=np.int32)


def check_label_values(label: np.ndarray, contract: Contract, name: str) -> None:
    """Refuse labels whose values cannot be class * divisor + instance (e.g. byte-swapped 16-bit PNGs)."""
    top = int(label.max(initial=0))
    if top >= contract.num_classes * contract.label_divisor:
        swapped = int(np.asarray(label, np.uint16).byteswap().max())
        hint = " (looks byte-swapped: PNG stores 16-bit samples big-endian)" if swapped < top else ""
        raise ValueError(f"{name}: label value {top} is not class*{contract.label_divisor}+instance "
                         f"with {contract.num_classes} classes{hint}")


def normalise(rgb: np.ndarray, contract: Contract) -> np.ndarray:
    """uint8 HxWx3 RGB -> float32 3xHxW, pixel/255 then (x - mean) / std as the contract says."""
    x = rgb.astype(np.float32) / 255.0
    x = (x - np.asarray(contract.mean, np.float32)) / np.asarray(contract.std, np.float32)
    return np.ascontiguousarray(x.transpose(2, 0, 1))


def is_top_view(row: dict) -> bool:
    """True for top views (any rotation is plausible), from the manifest's ``view`` field."""
    v = str(row.get("view", "")).lower()
    return "top" in v or v.startswith("tv") or "_tv" in v


class PanopticDataset(Dataset):
    """Samples (image tensor, target dict) from a phyllo-gen manifest.

    Augmentation randomness is seeded from (seed, epoch, index), so a sample is
    the same whichever worker loads it, and a resumed run sees the same data.
    With ``defer_photometric`` the image is the uint8 crop as rendered, and the
    target holds its ``photometric`` draw and ``plant`` mask for
    :func:`phyllo_train.modes.photometric_torch.finish_batch` to apply on the device.
    """

    def __init__(self, root: str | Path, split: str | None = "train", aug: AugmentConfig | None = None,
                 contract: Contract | None = None, seed: int = 0, limit: int | None = None,
                 small_center_weight: float = 1.0, with_tips: bool = False, max_tip_gap: float | None = None,
                 defer_photometric: bool = False, center_sigma_min: float | None = None,
                 saddle_center_weight: float = 1.0, center_point: str = "mass", tip_rule: str = "visible"):
        self.root = Path(root)
        self.contract = contract or load_contract()
        self.rows = read_manifest(self.root, split)[: limit]
        if not self.rows:
            raise ValueError(f"no rows with split={split!r} in {self.root / 'manifest.jsonl'}")
        self.aug = aug or AugmentConfig.none()
        self.seed = seed
        self.epoch = 0
        self.small_center_weight = small_center_weight
        self.center_sigma_min = center_sigma_min
        self.saddle_center_weight = saddle_center_weight
        self.center_point = center_point
        self.with_tips = with_tips
        if with_tips:
            missing = [r["image"] for r in self.rows if "leaf_tips" not in r]
            if missing:
                raise ValueError(f"{self.root / 'manifest.jsonl'}: {len(missing)} rows have no leaf_tips "
                                 f"(first: {missing[0]}); render the set with a phyllo-gen that writes them")
        self.max_tip_gap = max_tip_gap
        if tip_rule not in TIP_RULES:
            raise ValueError(f"unknown tip rule {tip_rule!r} (expected one of {', '.join(TIP_RULES)})")
        self.tip_rule = tip_rule
        self.defer_photometric = defer_photometric
        self.decoded: list[tuple[np.ndarray, np.ndarray]] | None = None  # see preload()
        if with_tips and (max_tip_gap is not None or tip_rule == "person"):
            missing = [r["image"] for r in self.rows if r.get("leaf_tips") and "leaf_tip_gaps" not in r]
            if missing:
                raise ValueError(f"{self.root / 'manifest.jsonl'}: {len(missing)} rows have no leaf_tip_gaps "
                                 f"(first: {missing[0]}); render the set with a phyllo-gen that writes them")

    def decode(self, idx: int) -> tuple[Image.Image, np.ndarray]:
        """Row ``idx``'s RGB image and checked (H, W) int32 label, read from disk."""
        row = self.rows[idx]
        with Image.open(self.root / row["image"]) as im:
            img = im.convert("RGB")
        label = read_label(self.root / row["label"])
        check_label_values(label, self.contract, row["label"])
        if label.shape != (img.size[1], img.size[0]):
            raise ValueError(f"{row['label']}: shape {label.shape} differs from image {img.size[::-1]}")
        return img, label

    def preload(self, threads: int = 8) -> None:
        """Decodes every image and label once, now, and keeps them in memory.

        Loader workers forked afterwards share these arrays (copy-on-write)
        instead of decoding the same PNGs again every epoch, about 12 ms a
        sample at 512². Labels are kept as uint16 (PNG's own depth; values are
        checked below the contract's class * divisor range).
        """
        def one(i: int) -> tuple[np.ndarray, np.ndarray]:
            img, label = self.decode(i)
            return np.asarray(img), label.astype(np.uint16)

        # PIL releases the GIL while it inflates a PNG, so threads decode in parallel.
        with ThreadPoolExecutor(max(1, threads)) as pool:
            self.decoded = list(pool.map(one, range(len(self.rows))))

    def set_epoch(self, epoch: int) -> None:
        """Change the augmentation stream (call once per epoch)."""
        self.epoch = epoch

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, idx: int) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        row = self.rows[idx]
        rng = np.random.default_rng([self.seed, self.epoch, idx])
        if self.decoded is not None:
            rgb, label16 = self.decoded[idx]
            img, label = Image.fromarray(rgb), label16.astype(np.int32)
        else:
            img, label = self.decode(idx)
        cfg = self.aug
        if cfg.crop is None:
            # Full tiles: crop back to the original size so H, W stay multiples of 32.
            cfg = AugmentConfig(**{**cfg.__dict__, "crop": min(label.shape) // 32 * 32})
        # Hidden tips (and, under the person rule, a tip coinciding with a higher one) get no target.
        tip_items = (tip_targets(row, self.tip_rule, self.max_tip_gap) if self.with_tips
                     else row.get("leaf_tips", {}))
        tips = np.array(list(tip_items.values()), np.float64).reshape(-1, 2)
        top_view = is_top_view(row)
        rgb, label, window, tips, plant = augment_geometry(
            img, label, cfg, rng, top_view=top_view, label_divisor=self.contract.label_divisor,
            zoom=(self.contract.zoom_plant_height, self.contract.max_zoom), points=tips)
        draw = draw_photometric(cfg, rng)
        if not self.defer_photometric:
            rgb = apply_photometric(rgb, draw, plant)
        t = make_targets(label, self.contract, window=window, small_center_weight=self.small_center_weight,
                         center_sigma_min=self.center_sigma_min, saddle_center_weight=self.saddle_center_weight,
                         center_point=self.center_point)
        target = {
            "semantic": torch.from_numpy(t.semantic),
            "semantic_weight": torch.from_numpy(t.semantic_weight),
            "center": torch.from_numpy(t.center),
            "center_weight": torch.from_numpy(t.center_weight),
            "offset": torch.from_numpy(t.offset),
            "offset_weight": torch.from_numpy(t.offset_weight),
            # Read by distillation (phyllo_train.modes.distill): a teacher may not know top views.
            "top_view": torch.tensor(float(top_view)),
        }
        if self.with_tips:
            target["tip"] = torch.from_numpy(tip_heatmap(tips, window, self.contract.stride, self.contract.tip_sigma))
        if self.defer_photometric:
            target["photometric"] = torch.from_numpy(draw.to_vector())
            target["plant"] = torch.from_numpy(plant)
            return torch.from_numpy(np.ascontiguousarray(rgb.transpose(2, 0, 1))), target
        return torch.from_numpy(normalise(rgb, self.contract)), target
