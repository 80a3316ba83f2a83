"""The batches of a whole training run, for one DataLoader whose workers live as long as the run.

A loader made afresh each epoch starts its workers cold: every worker
assembles a whole batch before the first one arrives, so on a GPU fed by
many workers each epoch begins with the network idle for about a batch's
worth of one worker's time (16 × 70 ms at 512²). Here every sample is
addressed by ``(epoch, index)`` instead, so one loader with persistent
workers serves every epoch, and each sample's augmentation is still seeded
by ``(seed, epoch, index)`` as before: the run sees exactly the batches
that per-epoch loaders gave it.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterator, Sequence

import numpy as np
from torch.utils.data import Dataset, Sampler


def epoch_batches(n: int, batch: int, seed: int, epoch: int) -> list[list[int]]:
    """Deterministic shuffled batches of one epoch (drop_last so BN never sees a batch of 1)."""
    perm = np.random.default_rng([seed, 1_000_003, epoch]).permutation(n)
    return [perm[i:i + batch].tolist() for i in range(0, n - batch + 1, batch)]


class EpochIndexed(Dataset):
    """Several datasets with ``set_epoch`` as one, indexed by ``(epoch, index)``.

    ``index`` runs over the datasets one after another (as ``ConcatDataset``);
    the epoch is set on the owning dataset before each sample, in whichever
    worker loads it.
    """

    def __init__(self, sets: Sequence[Dataset]):
        self.sets = list(sets)
        self.ends = list(np.cumsum([len(s) for s in self.sets]))

    def __len__(self) -> int:
        return int(self.ends[-1]) if self.ends else 0

    def __getitem__(self, key: tuple[int, int]):
        epoch, idx = key
        if not 0 <= idx < len(self):
            raise IndexError(f"sample {idx} of {len(self)}")
        k = bisect.bisect_right(self.ends, idx)
        local = idx - (int(self.ends[k - 1]) if k else 0)
        ds = self.sets[k]
        ds.set_epoch(epoch)
        return ds[local]


class RunBatches(Sampler):
    """Batches of ``(epoch, index)`` keys for steps ``start`` .. ``total - 1`` of a run,
    epoch after epoch, each epoch shuffled by :func:`epoch_batches`.

    With ``world`` > 1 each step's batch is split into ``world`` equal slices and
    this sampler yields slice ``rank`` (:mod:`phyllo_train.modes.ddp`): together the
    processes see exactly the batches one process would.
    """

    def __init__(self, n: int, batch: int, seed: int, start: int, total: int, rank: int = 0, world: int = 1):
        if batch % world:
            raise ValueError(f"a batch of {batch} does not split into {world} equal slices")
        self.n, self.batch, self.seed, self.start, self.total = n, batch, seed, start, total
        self.rank, self.slice = rank, batch // world
        self.per_epoch = n // batch
        if self.per_epoch == 0:
            raise ValueError(f"{n} samples is fewer than one batch of {batch}")

    def __len__(self) -> int:
        return max(0, self.total - self.start)

    def __iter__(self) -> Iterator[list[tuple[int, int]]]:
        step = self.start
        while step < self.total:
            epoch = step // self.per_epoch
            for b in epoch_batches(self.n, self.batch, self.seed, epoch)[step % self.per_epoch:]:
                if step >= self.total:
                    return
                yield [(epoch, i) for i in b[self.rank * self.slice:(self.rank + 1) * self.slice]]
                step += 1
