"""Where a training step's time goes on this machine, measured side by side in one run::

    python -m phyllo_train.experiments.train_speed --data DIR [--crop 448 --batch 3 --threads 2 --samples 24 --steps 6]

It prints one table: how many augmented samples per second the data pipeline makes in one
process (what one ``--workers`` process adds), with the photometric ops in it and without
them (``train --photometric device``), and also without decoding PNGs (``--preload``), what
those ops then cost batched in the training process, and the optimiser steps of the network in
float32 and under bfloat16 autocast (``train --bf16``) on a fixed batch, alternated so that a
noisy machine slows both alike. A run is bounded by the slower of the two sides, and on a
small CPU both share the same cores.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from ..augment import AugmentConfig
from ..dataset import PanopticDataset
from ..losses import LossWeights
from ..model import ENCODERS, build_model
from ..modes.photometric_torch import finish_batch
from ..train import collate, forward_losses, freeze_encoder, set_train_mode


def loader_rate(ds: PanopticDataset, samples: int) -> float:
    """Augmented samples per second made in this process (its first sample warms caches)."""
    ds[0]
    t = time.perf_counter()
    for i in range(1, samples + 1):
        ds[i % len(ds)]
    return samples / (time.perf_counter() - t)


def device_photometric_times(ds: PanopticDataset, batch: int, rounds: int) -> list[float]:
    """Seconds per batch for :func:`finish_batch` in this process (``ds`` defers its photometric ops)."""
    samples = [ds[i % len(ds)] for i in range(batch)]
    times = []
    for r in range(rounds + 1):
        xs, ts = collate(samples)
        t = time.perf_counter()
        finish_batch(xs, ts, ds.contract)
        if r:  # the first call warms up
            times.append(time.perf_counter() - t)
    return times


def step_times(ds: PanopticDataset, batch: int, steps: int, rounds: int = 2, encoder: str | None = None,
               frozen_blocks: int | None = None) -> dict[bool, list[float]]:
    """Seconds per optimiser step, float32 (False) and bfloat16 autocast (True), alternated,
    of the network with ``encoder`` (default s10's) and its first ``frozen_blocks`` fixed."""
    torch.manual_seed(0)
    model = build_model(ds.contract.num_classes, seed=0, encoder=encoder).to(memory_format=torch.channels_last)
    frozen = freeze_encoder(model, frozen_blocks) if frozen_blocks is not None else []
    set_train_mode(model, False, frozen)
    opt = torch.optim.AdamW([p for p in model.parameters() if p.requires_grad], lr=1e-5)
    xs, ts = collate([ds[i % len(ds)] for i in range(batch)])
    xs = xs.contiguous(memory_format=torch.channels_last)
    weights = LossWeights()
    times: dict[bool, list[float]] = {False: [], True: []}

    def step(bf16: bool) -> None:
        _, loss, _ = forward_losses(model, xs, ts, weights, 1.0, bf16)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    for _ in range(rounds):
        for bf16 in (False, True):
            step(bf16)  # warm-up: oneDNN picks its kernels on the first call
            for _ in range(steps):
                t = time.perf_counter()
                step(bf16)
                times[bf16].append(time.perf_counter() - t)
    return times


def cpu_bf16_flags() -> str:
    """The CPU's bfloat16 instruction sets from /proc/cpuinfo (Linux), or "none"."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            flags = set(f.read().split())
    except OSError:
        return "unknown"
    found = sorted(flags & {"avx512_bf16", "amx_bf16"})
    return ", ".join(found) or "none"


def main(argv=None) -> None:
    """CLI entry point: prints the table."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="a phyllo-gen dataset (its train split)")
    ap.add_argument("--crop", type=int, default=448)
    ap.add_argument("--batch", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2, help="torch threads for the steps (the loader uses one)")
    ap.add_argument("--samples", type=int, default=24, help="samples the loader makes")
    ap.add_argument("--steps", type=int, default=6, help="timed steps per precision and round (two rounds)")
    ap.add_argument("--encoder", choices=ENCODERS, default=None, help="the network's encoder (default: s10's)")
    ap.add_argument("--freeze-encoder", type=int, default=None, metavar="BLOCKS",
                    help="as train's: the pretrained encoder's stem and first BLOCKS blocks fixed")
    args = ap.parse_args(argv)
    ds = PanopticDataset(args.data, "train", AugmentConfig(crop=args.crop), seed=19)
    deferred = PanopticDataset(args.data, "train", AugmentConfig(crop=args.crop), seed=19, defer_photometric=True)
    preloaded = PanopticDataset(args.data, "train", AugmentConfig(crop=args.crop), seed=19, defer_photometric=True)
    preloaded.preload()
    torch.set_num_threads(1)
    kinds = {"all": ds, "deferred": deferred, "preloaded": preloaded}
    rates: dict[str, list[float]] = {k: [] for k in kinds}
    for _ in range(2):  # alternated, so a noisy machine slows all alike
        for k, d in kinds.items():
            rates[k].append(loader_rate(d, args.samples // 2))
    rate, rate_deferred, rate_preloaded = (statistics.median(rates[k]) for k in kinds)
    torch.set_num_threads(args.threads)
    photometric = statistics.median(device_photometric_times(deferred, args.batch, args.steps))
    times = step_times(ds, args.batch, args.steps, encoder=args.encoder, frozen_blocks=args.freeze_encoder)
    fp32, bf16 = (statistics.median(times[k]) for k in (False, True))
    print(f"{args.encoder or 'mobilenet'} encoder"
          + (f" (stem and {args.freeze_encoder} blocks fixed)" if args.freeze_encoder is not None else "")
          + f", {args.crop}² crops, batch {args.batch}, {args.threads} torch threads, "
          f"CPU: {torch.backends.cpu.get_cpu_capability()}, bfloat16 instructions: {cpu_bf16_flags()}")
    print()
    print("| stage | ms per sample | samples/s | relative |")
    print("|---|---:|---:|---:|")
    print(f"| data pipeline, one process (decode, augment, targets) | {1000 / rate:.0f} | {rate:.2f} | |")
    print(f"| data pipeline without photometric ops (`--photometric device`) | {1000 / rate_deferred:.0f} | "
          f"{rate_deferred:.2f} | |")
    print(f"| the same, images decoded once beforehand (`--preload`) | {1000 / rate_preloaded:.0f} | "
          f"{rate_preloaded:.2f} | |")
    print(f"| photometric ops batched in the training process, {args.threads} threads | "
          f"{1000 * photometric / args.batch:.0f} | {args.batch / photometric:.2f} | |")
    print(f"| optimiser step, float32 | {1000 * fp32 / args.batch:.0f} | {args.batch / fp32:.2f} | 1.00 |")
    print(f"| optimiser step, bfloat16 autocast | {1000 * bf16 / args.batch:.0f} | {args.batch / bf16:.2f} | "
          f"{fp32 / bf16:.2f} |")


if __name__ == "__main__":
    main()
