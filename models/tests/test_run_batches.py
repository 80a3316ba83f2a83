"""One loader for a whole run serves the same batches, and the same samples, as a loader per epoch."""

import torch

from phyllo_train.augment import AugmentConfig
from phyllo_train.dataset import PanopticDataset
from phyllo_train.run_batches import EpochIndexed, RunBatches, epoch_batches


def test_run_batches_are_the_epochs_batches_in_order_from_any_step():
    n, batch, seed = 11, 3, 7  # 3 batches per epoch, two samples left over each epoch
    per_epoch = n // batch
    want = [[(e, i) for i in b] for e in range(4) for b in epoch_batches(n, batch, seed, e)]
    assert list(RunBatches(n, batch, seed, 0, 12)) == want
    assert list(RunBatches(n, batch, seed, 4, 10)) == want[4:10]  # a resumed run starts mid-epoch
    assert len(RunBatches(n, batch, seed, 4, 10)) == 6 and list(RunBatches(n, batch, seed, 5, 5)) == []
    assert all(len(set(i for _, i in b)) == batch for b in want)
    assert want[0] != want[per_epoch]  # each epoch has its own order


def test_each_process_takes_its_slice_of_every_batch():
    n, batch, seed = 11, 4, 7
    whole = list(RunBatches(n, batch, seed, 2, 9))
    slices = [list(RunBatches(n, batch, seed, 2, 9, rank=r, world=2)) for r in (0, 1)]
    assert [a + b for a, b in zip(*slices)] == whole
    assert all(len(b) == 2 for s in slices for b in s)
    try:
        RunBatches(n, 3, seed, 0, 4, rank=0, world=2)
    except ValueError as e:
        assert "does not split into 2" in str(e)
    else:
        raise AssertionError("an odd batch split in two")


def test_epoch_indexed_addresses_each_set_and_seeds_by_epoch(tiny_dataset, contract):
    cfg = AugmentConfig(crop=64)
    a = PanopticDataset(tiny_dataset, "train", cfg, contract, seed=3, limit=2)
    b = PanopticDataset(tiny_dataset, "train", cfg, contract, seed=4)
    joined = EpochIndexed([a, b])
    assert len(joined) == len(a) + len(b)
    ref_a = PanopticDataset(tiny_dataset, "train", cfg, contract, seed=3, limit=2)
    ref_b = PanopticDataset(tiny_dataset, "train", cfg, contract, seed=4)
    for epoch in (0, 2):
        ref_a.set_epoch(epoch)
        ref_b.set_epoch(epoch)
        torch.testing.assert_close(joined[(epoch, 1)][0], ref_a[1][0])
        torch.testing.assert_close(joined[(epoch, 2)][0], ref_b[0][0])
    assert not torch.equal(joined[(0, 2)][0], joined[(1, 2)][0])  # the epoch changes the augmentation


def test_preloaded_samples_are_the_samples_read_from_disk(tiny_dataset, contract, tmp_path):
    from phyllo_train import train

    cfg = AugmentConfig(crop=64)
    disk = PanopticDataset(tiny_dataset, "train", cfg, contract, seed=2)
    memory = PanopticDataset(tiny_dataset, "train", cfg, contract, seed=2)
    memory.preload(threads=2)
    assert memory.decoded is not None and len(memory.decoded) == len(disk)
    for i in range(len(disk)):
        x, t = disk[i]
        y, u = memory[i]
        torch.testing.assert_close(x, y)
        for k in t:
            torch.testing.assert_close(t[k], u[k])
    run = tmp_path / "pre"
    assert train.main(["--data", str(tiny_dataset), "--out", str(run), "--crop", "64", "--batch", "2",
                       "--workers", "1", "--val-limit", "0", "--steps", "2", "--warmup", "1", "--preload"]) == 0
    assert (run / "last.pt").exists()
