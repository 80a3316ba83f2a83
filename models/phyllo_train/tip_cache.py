"""Frozen base features of augmented crops, stored once so the tip head can train for many epochs.

    python -m phyllo_train.tips cache --base models/phyllo.onnx --data DIR [--data DIR2] --out CACHE --passes 2

Training the tip head on live crops spends nearly all its time in the frozen
base network's forward pass (2.5 crops/s on two cores). The base never
changes, so each augmented crop's features (stem at stride 2, decoder at
stride 4) and tip target are computed once and written to disk as float16
memory maps; the head then trains on them at tens of crops per second.
Each pass over the training images uses a new augmentation draw (the
dataset's epoch), so ``--passes`` sets how many views of each image the
cache holds. A cache is filled in order and can be resumed: ``meta.json``
records how many crops are complete.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import ConcatDataset, DataLoader, Dataset

from .augment import AugmentConfig
from .contract import Contract
from .dataset import PanopticDataset
from .model import PhylloNet

META = "meta.json"
ARRAYS = ("f2", "d4", "tip")


@dataclass(frozen=True)
class CacheShape:
    """Shapes of one cached crop's arrays (channels, height, width)."""

    f2: tuple[int, int, int]
    d4: tuple[int, int, int]
    tip: tuple[int, int, int]

    def of(self, name: str) -> tuple[int, int, int]:
        """The shape of array ``name`` (one of :data:`ARRAYS`)."""
        return getattr(self, name)


def _open(root: Path, shape: CacheShape, total: int, mode: str) -> dict[str, np.memmap]:
    return {k: np.lib.format.open_memmap(root / f"{k}.npy", mode=mode, dtype=np.float16, shape=(total, *shape.of(k)))
            if mode == "w+" else np.load(root / f"{k}.npy", mmap_mode=mode) for k in ARRAYS}


def build(base: PhylloNet, dirs: list[Path], out: Path, contract: Contract, crop: int, passes: int, batch: int,
          seed: int, workers: int) -> Path:
    """Write ``passes`` augmented crops of every training image of ``dirs``, resuming a partial cache."""
    out.mkdir(parents=True, exist_ok=True)
    sets = [PanopticDataset(d, split="train", aug=AugmentConfig(crop=crop), contract=contract, seed=seed,
                            with_tips=True) for d in dirs]
    per_pass = sum(len(s) for s in sets)
    total = per_pass * passes
    if contract.stride != 2:
        raise ValueError(f"the tip cache assumes output stride 2, the contract has {contract.stride}")
    shape: CacheShape | None = None
    meta_path = out / META
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else None
    if meta is not None:
        want = {"crop": crop, "passes": passes, "seed": seed, "data": [str(d) for d in dirs]}
        have = {k: meta[k] for k in want}
        if have != want:
            raise ValueError(f"{meta_path}: cache was built with {have}, asked for {want}")
    done = int(meta["done"]) if meta else 0
    arrays = None
    if meta is not None:
        shape = CacheShape(*(tuple(meta["shapes"][k]) for k in ARRAYS))
        arrays = _open(out, shape, total, "r+")
    t0, written = time.time(), 0
    with torch.no_grad():
        for p in range(done // per_pass, passes):
            for ds in sets:
                ds.set_epoch(p)
            # Unshuffled, so the index in the cache says which image and pass a crop is.
            loader = DataLoader(ConcatDataset(sets), batch_size=batch, shuffle=False, num_workers=workers)
            start = done - p * per_pass
            skip = start // batch
            i = p * per_pass
            for b, (x, t) in enumerate(loader):
                n = x.shape[0]
                if b < skip:
                    i += n
                    continue
                f2, d4 = base.features(x)
                if arrays is None:
                    shape = CacheShape(f2=tuple(f2.shape[1:]), d4=tuple(d4.shape[1:]), tip=tuple(t["tip"].shape[1:]))
                    arrays = _open(out, shape, total, "w+")
                arrays["f2"][i:i + n] = f2.numpy().astype(np.float16)
                arrays["d4"][i:i + n] = d4.numpy().astype(np.float16)
                arrays["tip"][i:i + n] = t["tip"].numpy().astype(np.float16)
                i += n
                written += n
                for a in arrays.values():
                    a.flush()
                meta = {"crop": crop, "passes": passes, "seed": seed, "data": [str(d) for d in dirs], "done": i,
                        "total": total, "shapes": {k: list(shape.of(k)) for k in ARRAYS}}
                meta_path.write_text(json.dumps(meta, indent=1))
                if (i // n) % 20 == 0:
                    print(f"cached {i}/{total} crops, {written / (time.time() - t0):.1f} crops/s", flush=True)
            done = i
    print(f"cache {out}: {done}/{total} crops", flush=True)
    return out


class FeatureCache(Dataset):
    """A complete feature cache as ``(f2, d4, tip)`` float32 tensors, each a random aligned sub-crop.

    ``sub`` is the sub-crop side in input pixels (a multiple of 4; ``None`` keeps the whole
    cached crop): cutting a cached crop is the one augmentation that costs nothing.
    """

    def __init__(self, root: Path, sub: int | None = None, seed: int = 0):
        meta = json.loads((root / META).read_text())
        if meta["done"] < meta["total"]:
            raise ValueError(f"{root / META}: cache holds {meta['done']} of {meta['total']} crops; "
                             "finish it with the same `tips cache` command")
        self.crop = int(meta["crop"])
        self.sub = sub or self.crop
        if self.sub % 4 or self.sub > self.crop:
            raise ValueError(f"sub-crop {self.sub} must be a multiple of 4 and at most the cached crop {self.crop}")
        self.arrays = {k: np.load(root / f"{k}.npy", mmap_mode="r") for k in ARRAYS}
        self.seed = seed
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        """Change the sub-crop draw."""
        self.epoch = epoch

    def __len__(self) -> int:
        return int(self.arrays["tip"].shape[0])

    def __getitem__(self, idx: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        rng = np.random.default_rng([self.seed, self.epoch, idx])
        q = (self.crop - self.sub) // 4
        y, x = (int(v) for v in rng.integers(0, q + 1, 2))
        s4 = self.sub // 4
        f2 = self.arrays["f2"][idx, :, 2 * y:2 * y + 2 * s4, 2 * x:2 * x + 2 * s4]
        d4 = self.arrays["d4"][idx, :, y:y + s4, x:x + s4]
        tip = self.arrays["tip"][idx, :, 2 * y:2 * y + 2 * s4, 2 * x:2 * x + 2 * s4]
        return (torch.from_numpy(np.ascontiguousarray(f2, np.float32)),
                torch.from_numpy(np.ascontiguousarray(d4, np.float32)),
                torch.from_numpy(np.ascontiguousarray(tip, np.float32)))
