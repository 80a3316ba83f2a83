"""Which head makes one network count worse than another: their outputs swapped, head by head.

    python -m phyllo_train.head_swap --data /work/data/own300 --split all --limit 120 \\
        runs/s10-onnx/best.pt:0.3 runs/e40-s4/last.pt:0.15

Both checkpoints (their exported, EMA weights) run on the same whole tiles
without augmentation; each image is then decoded by the Python decoder with
the semantic logits, the centre heatmap and the offsets taken from network
A or B in all eight combinations. A centre heatmap is scaled by the
contract's threshold over its network's own (``PATH:THRESHOLD``), so each
heatmap is cut where its network is counted. The row whose count moves most
when one head is swapped names the head to fix. No small-plant zoom, as in
:mod:`phyllo_train.val_losses`, so the counts sit below `phyllo eval`'s.
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import torch

from .augment import AugmentConfig
from .contract import load_contract
from .dataset import PanopticDataset, read_label
from .export import load_checkpoint_model
from .postprocess import count_agreement, decode, label_leaf_count
from .train import collate


def parse_spec(spec: str) -> tuple[Path, float]:
    """``PATH:THRESHOLD`` -> (path, threshold); the threshold is required."""
    path, sep, thr = spec.rpartition(":")
    if not sep:
        raise SystemExit(f"{spec}: give CHECKPOINT:THRESHOLD")
    return Path(path), float(thr)


@torch.no_grad()
def outputs(path: Path, ds: PanopticDataset, batch: int, scale: float,
            bf16: bool = False) -> list[tuple[torch.Tensor, ...]]:
    """Per image: (semantic, centre x ``scale``, offset) of the checkpoint's network,
    under bfloat16 autocast with ``bf16`` (as `train --bf16` runs it)."""
    model, _ = load_checkpoint_model(path, ds.contract)
    model.eval()
    res = []
    for i in range(0, len(ds), batch):
        xs, _ = collate([ds[j] for j in range(i, min(len(ds), i + batch))])
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            sem, ctr, off = (o.float() for o in model(xs.contiguous(memory_format=torch.channels_last)))
        res += [(sem[b], ctr[b] * scale, off[b]) for b in range(len(xs))]
    return res


def pair_parser(prog: str, doc: str, first: str, second: str, limit: int) -> argparse.ArgumentParser:
    """The command line shared by the tools that compare two networks on whole tiles:
    the two ``CHECKPOINT:CENTRE_THRESHOLD`` specs and the dataset options."""
    ap = argparse.ArgumentParser(prog=prog, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    for spec in (first, second):  # "dest: what it is"
        dest, _, what = spec.partition(": ")
        ap.add_argument(dest, help=f"{what}: CHECKPOINT:CENTRE_THRESHOLD")
    ap.add_argument("--data", type=Path, required=True, help="phyllo-gen dataset")
    ap.add_argument("--split", default="val", help="manifest split, or 'all'")
    ap.add_argument("--limit", type=int, default=limit, help="first N images of the split")
    ap.add_argument("--threads", type=int, default=2)
    return ap


def open_tiles(args: argparse.Namespace, contract) -> PanopticDataset:
    """The dataset :func:`pair_parser`'s options named, without augmentation; sets the torch threads."""
    torch.set_num_threads(args.threads)
    return PanopticDataset(args.data, None if args.split == "all" else args.split, AugmentConfig.none(), contract,
                           limit=args.limit)


def main(argv: list[str] | None = None) -> int:
    """CLI entry point: prints a Markdown table, one row per combination of heads."""
    ap = pair_parser("python -m phyllo_train.head_swap", __doc__, "a: network A", "b: network B", limit=120)
    ap.add_argument("--batch", type=int, default=4)
    ap.add_argument("--bf16", action="store_true",
                    help="run both networks under bfloat16 autocast, as training with --bf16 sees them")
    args = ap.parse_args(argv)
    contract = load_contract()
    ds = open_tiles(args, contract)
    cut = float(contract.raw["postprocess"]["center_threshold"])
    nets = {}
    for name, spec in (("A", args.a), ("B", args.b)):
        path, thr = parse_spec(spec)
        nets[name] = outputs(path, ds, args.batch, cut / thr, args.bf16)
        print(f"{name} = {path} (centre threshold {thr:g}{', bfloat16 autocast' if args.bf16 else ''})")
    truth = [label_leaf_count(read_label(ds.root / row["label"]), contract) for row in ds.rows]
    print(f"\n{len(ds)} images of {args.data} ({args.split})\n")
    print("| semantic | centre | offset | exact | within ±1 | RMSE | bias |\n|---|---|---|---:|---:|---:|---:|")
    for combo in itertools.product("AB", repeat=3):
        errs = []
        for i, t in enumerate(truth):
            heads = [nets[src][i][k] for k, src in enumerate(combo)]
            errs.append(decode(*heads, contract).leaf_count - t)
        ex, w1, rmse, bias = count_agreement(errs)
        print(f"| {' | '.join(combo)} | {100 * ex:.1f} % | {100 * w1:.1f} % | {rmse:.3f} | {bias:+.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
