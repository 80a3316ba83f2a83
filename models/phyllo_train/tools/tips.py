"""A leaf-tip head on a trained network's frozen features, its training and its export.

    python -m phyllo_train.tools.tips train --base models/phyllo.onnx --data DIR [--data DIR2] --out RUN_DIR
    python -m phyllo_train.tools.tips cache --base models/phyllo.onnx --data DIR --out CACHE --passes 2
    python -m phyllo_train.tools.tips train --base models/phyllo.onnx --data DIR --cache CACHE --out RUN_DIR --width 48
    python -m phyllo_train.tools.tips export --base models/phyllo.onnx --head RUN_DIR/last.pt --out MODEL.onnx

Human annotators count a leaf by marking its tip (``leaf_tips.csv`` of the
real development set is exactly that). The Panoptic-DeepLab centre of a leaf
is its centre of mass, and the centres of young leaves in the whorl lie close
together on the stem, where the network merges them; their tips fan out.
The tip head reads the shipped network's features (stem at stride 2,
decoder at stride 4), which stay frozen: the exported model's semantic,
centre and offset outputs are exactly the base model's, and only a fourth
output, ``tip`` (the contract's ``[outputs] tip``), is added. Training it
costs a forward pass of the base plus a small head, so it fits a CPU session.

The target is a unit Gaussian (``tip_sigma``) at each visible leaf's
apparent tip (phyllo-gen's ``leaf_tips``); the loss is CenterNet's
penalty-reduced focal loss, which keeps peaks sharp where an MSE blurs them.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import onnx
import torch
from torch import nn
from torch.utils.data import ConcatDataset, DataLoader

from ..augment import AugmentConfig
from ..contract import Contract, load_contract
from ..dataset import PanopticDataset
from ..export import check_onnx, export_onnx
from .from_onnx import has_tip_output, load_folded
from ..losses import tip_focal_loss
from ..model import PhylloNet, TipHead, TipNet, build_model, count_parameters
from .tip_cache import FeatureCache, build as build_cache


def load_base(path: str | Path, contract: Contract) -> PhylloNet:
    """The network of an exported ONNX file, rebuilt in PyTorch (eval mode, exact; see ``from_onnx``).

    Of a model that already has a tip head, only the base network is kept.
    """
    base = build_model(contract.num_classes, seed=0)
    load_folded(TipNet(base, TipHead()) if has_tip_output(path, contract) else base, path, contract)
    return base.eval()


def count_peaks(heat: torch.Tensor, threshold: float, kernel: int) -> torch.Tensor:
    """Tip peaks per image of a ``[N, 1, H, W]`` heatmap: local maxima over ``kernel`` above ``threshold``."""
    pooled = nn.functional.max_pool2d(heat, kernel, stride=1, padding=kernel // 2)
    return ((heat >= pooled) & (heat > threshold)).flatten(1).sum(1)


def _loader(dirs: list[Path], split: str, aug: AugmentConfig, contract: Contract, batch: int, seed: int,
            workers: int, shuffle: bool, limit: int | None = None) -> tuple[DataLoader, list[PanopticDataset]]:
    sets = [PanopticDataset(d, split=split, aug=aug, contract=contract, seed=seed, limit=limit, with_tips=True)
            for d in dirs]
    g = torch.Generator().manual_seed(seed)
    loader = DataLoader(ConcatDataset(sets), batch_size=batch, shuffle=shuffle, num_workers=workers,
                        drop_last=shuffle, generator=g, persistent_workers=workers > 0)
    return loader, sets


def evaluate(base: PhylloNet, head: TipHead, loader: DataLoader, contract: Contract) -> dict[str, float]:
    """Mean focal loss and the tip-count error of the crops (peaks vs. tips in the target) on ``loader``."""
    head.eval()
    losses, errs = [], []
    thr, k = contract.raw["postprocess"]["tip_threshold"], contract.raw["postprocess"]["tip_nms_kernel"]
    with torch.no_grad():
        for x, t in loader:
            logits = head(*base.features(x))
            losses.append(float(tip_focal_loss(logits, t["tip"])))
            want = t["tip"].ge(1.0 - 1e-6).flatten(1).sum(1)
            errs.append((count_peaks(torch.sigmoid(logits), thr, k) - want).float())
    head.train()
    e = torch.cat(errs) if errs else torch.zeros(1)
    return {"val_loss": float(np.mean(losses)) if losses else math.nan,
            "val_count_mae": float(e.abs().mean()), "val_count_bias": float(e.mean())}


def train(args: argparse.Namespace) -> int:
    """Train the tip head; resumes from ``RUN_DIR/last.pt``."""
    contract = load_contract(args.contract)
    torch.manual_seed(args.seed)
    if args.threads:
        torch.set_num_threads(args.threads)
    base = load_base(args.base, contract)
    for p in base.parameters():
        p.requires_grad_(False)
    head = TipHead(width=args.width)
    opt = torch.optim.AdamW(head.parameters(), lr=args.lr, weight_decay=1e-4)
    args.out.mkdir(parents=True, exist_ok=True)
    last = args.out / "last.pt"
    step = 0
    if last.exists():
        ckpt = torch.load(last, map_location="cpu", weights_only=False)
        if int(ckpt.get("width", 32)) != args.width:
            raise ValueError(f"{last}: head width {ckpt.get('width', 32)}, asked for --width {args.width}")
        head.load_state_dict(ckpt["head"])
        opt.load_state_dict(ckpt["opt"])
        step = int(ckpt["step"])
        print(f"resuming {last} at step {step}", flush=True)
    (args.out / "args.json").write_text(json.dumps({k: str(v) for k, v in vars(args).items()}, indent=1))
    if args.cache:
        train_sets = [FeatureCache(c, sub=args.sub_crop, seed=args.seed) for c in args.cache]
        g = torch.Generator().manual_seed(args.seed)
        train_loader = DataLoader(ConcatDataset(train_sets), batch_size=args.batch, shuffle=True, drop_last=True,
                                  num_workers=args.workers, generator=g, persistent_workers=args.workers > 0)
    else:
        train_loader, train_sets = _loader(args.data, "train", AugmentConfig(crop=args.crop), contract, args.batch,
                                           args.seed, args.workers, shuffle=True)
    val_loader, _ = _loader(args.data, "val", AugmentConfig.none(crop=args.crop), contract, args.batch,
                            args.seed, 0, shuffle=False, limit=args.val_images)
    print(f"tip head: {count_parameters(head)} parameters on frozen {args.base}; "
          f"{sum(len(s) for s in train_sets)} training {'cached crops' if args.cache else 'images'}", flush=True)
    log = open(args.out / "log.jsonl", "a", encoding="utf-8")
    head.train()
    t0, seen, epoch = time.time(), 0, step // max(len(train_loader), 1)
    while step < args.steps:
        for s in train_sets:
            s.set_epoch(epoch)
        for batch in train_loader:
            lr = args.lr * 0.5 * (1 + math.cos(math.pi * min(step / args.steps, 1.0)))
            for grp in opt.param_groups:
                grp["lr"] = lr
            if args.cache:
                f2, d4, tip = batch
            else:
                x, t = batch
                tip = t["tip"]
                with torch.no_grad():
                    f2, d4 = base.features(x)
            loss = tip_focal_loss(head(f2, d4), tip)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
            seen += f2.shape[0]
            if step % args.log_every == 0:
                rate = seen / (time.time() - t0)
                print(f"step {step}/{args.steps} loss {float(loss.detach()):.4f} lr {lr:.2e} {rate:.1f} img/s", flush=True)
            done = step >= args.steps
            if step % args.ckpt_every == 0 or done:
                rec = {"step": step, "loss": float(loss.detach()), **evaluate(base, head, val_loader, contract)}
                print(json.dumps(rec), flush=True)
                log.write(json.dumps(rec) + "\n")
                log.flush()
                torch.save({"head": head.state_dict(), "opt": opt.state_dict(), "step": step, "width": args.width,
                            "base": str(args.base), "data": [str(d) for d in args.data],
                            "cache": [str(c) for c in args.cache or []]}, last)
            if done:
                break
        epoch += 1
    log.close()
    return 0


def untrained_head_checkpoint(width: int = 32, seed: int = 0) -> dict:
    """A ``train`` checkpoint of a seeded, untrained head (its heatmap stays near 0.01): the
    test fixture ``models/phyllo-tips-untrained.onnx`` is the shipped model with one."""
    state = torch.random.get_rng_state()
    torch.manual_seed(seed)
    head = TipHead(width=width)
    torch.random.set_rng_state(state)
    return {"head": head.state_dict(), "step": 0, "width": width, "data": []}


def head_checkpoint(path: str | Path | None) -> dict:
    """A ``train`` checkpoint of the tip head (``None``: a seeded, untrained head)."""
    if path is None:
        return untrained_head_checkpoint()
    return torch.load(path, map_location="cpu", weights_only=False)


def build_tipnet(base_path: str | Path, ckpt: dict, contract: Contract) -> TipNet:
    """The base network of ``base_path`` (ONNX) with the tip head of a ``train`` checkpoint."""
    head = TipHead(width=int(ckpt.get("width", 32)))
    head.load_state_dict(ckpt["head"])
    return TipNet(load_base(base_path, contract), head).eval()


def export(args: argparse.Namespace) -> int:
    """Export base + tip head to ONNX with four outputs; checked against PyTorch by ONNX Runtime."""
    contract = load_contract(args.contract)
    ckpt = head_checkpoint(args.head)
    net = build_tipnet(args.base, ckpt, contract)
    meta = {p.key: p.value for p in onnx.load(str(args.base)).metadata_props}
    base_name = meta.get(contract.meta_model_name, "base")
    data = (f"{meta.get(contract.meta_training_data, 'unknown')} || tip head ({ckpt['step']} steps): "
            + ", ".join(Path(d).name for d in ckpt.get("data", [])))
    names = contract.output_names_with_tip
    path = export_onnx(net, args.out, contract, model_name=args.name or f"{base_name}-tips", trained=True,
                       training_data=data, output_names=names,
                       extra_meta={"phyllo.base_model": base_name, "phyllo.tip_head_steps": str(ckpt["step"])})
    errs = check_onnx(path, net, contract, output_names=names, size=args.check_size)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, {count_parameters(net.head)} tip-head params on "
          f"{base_name}); ORT vs torch max abs diff: " + ", ".join(f"{k}={v:.2e}" for k, v in errs.items()))
    return 0


def cache(args: argparse.Namespace) -> int:
    """Write the frozen base's features of ``--passes`` augmented crops per training image."""
    contract = load_contract(args.contract)
    if args.threads:
        torch.set_num_threads(args.threads)
    base = load_base(args.base, contract)
    build_cache(base, args.data, args.out, contract, args.crop, args.passes, args.batch, args.seed, args.workers)
    return 0


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.tools.tips", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    tr = sub.add_parser("train", help="train the tip head on frozen features")
    tr.add_argument("--base", type=Path, required=True, help="exported base model (ONNX), e.g. models/phyllo.onnx")
    tr.add_argument("--data", type=Path, action="append", required=True, help="phyllo-gen dataset with leaf_tips (repeatable)")
    tr.add_argument("--out", type=Path, required=True)
    tr.add_argument("--steps", type=int, default=3000)
    tr.add_argument("--batch", type=int, default=8)
    tr.add_argument("--crop", type=int, default=384)
    tr.add_argument("--lr", type=float, default=2e-3)
    tr.add_argument("--seed", type=int, default=0)
    tr.add_argument("--workers", type=int, default=1)
    tr.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    tr.add_argument("--log-every", type=int, default=20)
    tr.add_argument("--ckpt-every", type=int, default=250)
    tr.add_argument("--val-images", type=int, default=48, help="validation images per dataset")
    tr.add_argument("--contract", default=None)
    tr.add_argument("--width", type=int, default=32, help="tip head channels")
    tr.add_argument("--cache", type=Path, action="append", default=None,
                    help="train on a `tips cache` directory instead of live crops (repeatable); "
                         "--data still gives the validation images")
    tr.add_argument("--sub-crop", type=int, default=None,
                    help="random aligned sub-crop of each cached crop (input px, multiple of 4)")
    ca = sub.add_parser("cache", help="store the frozen base's features of augmented training crops")
    ca.add_argument("--base", type=Path, required=True)
    ca.add_argument("--data", type=Path, action="append", required=True)
    ca.add_argument("--out", type=Path, required=True)
    ca.add_argument("--crop", type=int, default=384)
    ca.add_argument("--passes", type=int, default=2, help="augmented crops per training image")
    ca.add_argument("--batch", type=int, default=8)
    ca.add_argument("--seed", type=int, default=0)
    ca.add_argument("--workers", type=int, default=1)
    ca.add_argument("--threads", type=int, default=0)
    ca.add_argument("--contract", default=None)
    ex = sub.add_parser("export", help="export base + tip head to ONNX")
    ex.add_argument("--base", type=Path, required=True)
    heads = ex.add_mutually_exclusive_group(required=True)
    heads.add_argument("--head", type=Path, help="RUN_DIR/last.pt of `train`")
    heads.add_argument("--untrained-head", action="store_true",
                       help="a seeded untrained head (the test fixture models/phyllo-tips-untrained.onnx)")
    ex.add_argument("--out", type=Path, required=True)
    ex.add_argument("--name", default=None, help="phyllo.model_name (default: <base name>-tips)")
    ex.add_argument("--check-size", type=int, default=256)
    ex.add_argument("--contract", default=None)
    args = ap.parse_args(argv)
    return {"train": train, "export": export, "cache": cache}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
