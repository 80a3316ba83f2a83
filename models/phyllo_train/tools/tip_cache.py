"""Frozen base features of augmented crops, stored once so the tip head can train for many epochs.

    python -m phyllo_train.tools.tips cache --base models/phyllo.onnx --data DIR [--data DIR2] --out CACHE --passes 2

The base never changes while the tip head trains, so each augmented crop's
features (stem at stride 2, decoder at stride 4) and tip target are
computed once and written to disk as float16 memory maps. On two cores this
trains the head 1.4 times as fast as live crops (5.3 against 3.8 crops/s
at batch 8, 384²; models/EXPERIMENTS.md, "Leaf tips"): the head's own backward pass at stride 2
costs more than the base's forward. Each pass over the training images uses
a new augmentation draw (the dataset's epoch), so ``--passes`` sets how
many views of each image the cache holds. A cache is filled in order and
can be resumed: ``meta.json`` records how many crops are complete.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import ConcatDataset, DataLoader, Dataset, Subset

from ..augment import AugmentConfig
from ..contract import Contract
from ..dataset import PanopticDataset
from ..model import PhylloNet

META = "meta.json"
ARRAYS = ("f2", "d4", "tip")


def build(base: PhylloNet, dirs: list[Path], out: Path, contract: Contract, crop: int, passes: int, batch: int,
          seed: int, workers: int) -> Path:
    """Write ``passes`` augmented crops of every training image of ``dirs``, resuming a partial cache."""
    if contract.stride != 2:
        raise ValueError(f"the tip cache assumes output stride 2, the contract has {contract.stride}")
    out.mkdir(parents=True, exist_ok=True)
    sets = [PanopticDataset(d, split="train", aug=AugmentConfig(crop=crop), contract=contract, seed=seed,
                            with_tips=True) for d in dirs]
    per_pass = sum(len(s) for s in sets)
    recipe = {"crop": crop, "passes": passes, "seed": seed, "data": [str(d) for d in dirs], "total": per_pass * passes}
    meta_path = out / META
    done, arrays = 0, None
    if meta_path.exists():
        meta = json.loads(meta_path.read_text())
        have = {k: meta.get(k) for k in recipe}
        if have != recipe:
            raise ValueError(f"{meta_path}: cache was built with {have}, asked for {recipe}")
        done = int(meta["done"])
        arrays = {k: np.load(out / f"{k}.npy", mmap_mode="r+") for k in ARRAYS}
    t0, written = time.time(), 0
    with torch.no_grad():
        for p in range(done // per_pass, passes):
            for ds in sets:
                ds.set_epoch(p)
            # Unshuffled, so the index in the cache says which image and pass a crop is;
            # a resumed pass starts at its first missing crop.
            todo = Subset(ConcatDataset(sets), range(done - p * per_pass, per_pass))
            loader = DataLoader(todo, batch_size=batch, shuffle=False, num_workers=workers)
            for b, (x, t) in enumerate(loader, 1):
                f2, d4 = base.features(x)
                crops = {"f2": f2.numpy(), "d4": d4.numpy(), "tip": t["tip"].numpy()}
                if arrays is None:
                    arrays = {k: np.lib.format.open_memmap(out / f"{k}.npy", mode="w+", dtype=np.float16,
                                                           shape=(recipe["total"], *v.shape[1:]))
                              for k, v in crops.items()}
                n = x.shape[0]
                for k, v in crops.items():
                    arrays[k][done:done + n] = v.astype(np.float16)
                    arrays[k].flush()
                done += n
                written += n
                # Written after the crops are flushed, so a resume never trusts a crop not on disk.
                meta_path.write_text(json.dumps({**recipe, "done": done}, indent=1))
                if b % 20 == 0:
                    print(f"cached {done}/{recipe['total']} crops, {written / (time.time() - t0):.1f} crops/s",
                          flush=True)
    print(f"cache {out}: {done}/{recipe['total']} crops", flush=True)
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
