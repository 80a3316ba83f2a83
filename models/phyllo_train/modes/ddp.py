"""One training run in several single-threaded CPU processes (``train --procs N``).

On this project's 2-core CPU two single-threaded runs side by side train
1.6x the images of one run on two threads, and one run split over two
single-threaded processes 1.24x (models/EXPERIMENTS.md, "Two processes, one
thread each"; `scripts/experiments/train-procs-speed.sh`): a step's many small depthwise
and BatchNorm ops scale poorly across threads; the split run gives back
part of the gain, most likely to every step waiting for the slower process.
Every process takes its own slice of each step's batch
(:class:`phyllo_train.run_batches.RunBatches` with ``rank``/``world``), the gradients are averaged over the processes once per
step in one flat all-reduce (gloo), and rank 0 alone logs, validates and
writes checkpoints. Each process normalises its own slice in BatchNorm, as
data-parallel training does without synchronised BatchNorm.
"""

from __future__ import annotations

import os
import socket
import sys
from collections.abc import Callable, Iterable

import torch
import torch.distributed as dist
import torch.multiprocessing as mp


def free_port() -> int:
    """A TCP port on the loopback interface that nothing listens on now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _entry(rank: int, main: Callable[..., int], argv: list[str], world: int, port: int) -> None:
    dist.init_process_group("gloo", init_method=f"tcp://127.0.0.1:{port}", rank=rank, world_size=world)
    if rank:
        sys.stdout = open(os.devnull, "w")  # rank 0 speaks for the run; errors still reach stderr
    try:
        code = main(argv, rank=rank, world=world)
    finally:
        dist.destroy_process_group()
    if code:
        raise SystemExit(code)


def spawn(main: Callable[..., int], argv: list[str], world: int) -> int:
    """Runs ``main(argv, rank=r, world=world)`` in ``world`` processes; 0 when all succeed.

    A process that fails ends the run with its error's last line, not a second traceback.
    """
    try:
        mp.spawn(_entry, args=(main, argv, world, free_port()), nprocs=world, join=True)
    except mp.ProcessRaisedException as e:
        lines = str(e).strip().splitlines()
        raise SystemExit(f"training process {e.error_index} failed: {lines[-1] if lines else e}") from None
    except mp.ProcessExitedException as e:
        raise SystemExit(f"training process {e.error_index} exited with code {e.exit_code}") from None
    return 0


def average_gradients(params: Iterable[torch.nn.Parameter], world: int) -> None:
    """Replaces every gradient by its mean over the processes, in one all-reduce."""
    grads = [p.grad for p in params if p.grad is not None]
    if world == 1 or not grads:
        return
    flat = torch.cat([g.reshape(-1) for g in grads])
    dist.all_reduce(flat)
    flat /= world
    offset = 0
    for g in grads:
        g.copy_(flat[offset:offset + g.numel()].view_as(g))
        offset += g.numel()


def broadcast_parameters(module: torch.nn.Module, world: int) -> None:
    """Rank 0's weights and buffers everywhere, so that every process starts alike."""
    if world == 1:
        return
    for t in list(module.parameters()) + list(module.buffers()):
        dist.broadcast(t.data, src=0)


def rank0_value(x: float, world: int) -> float:
    """Rank 0's ``x`` on every process: the clock that ends a timed run must be one clock."""
    if world == 1:
        return x
    t = torch.tensor([x], dtype=torch.float64)
    dist.broadcast(t, src=0)
    return float(t.item())
