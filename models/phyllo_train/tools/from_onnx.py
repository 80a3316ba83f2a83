"""Rebuild a training checkpoint from an exported ONNX model.

    python -m phyllo_train.tools.from_onnx models/phyllo.onnx --out runs/s10-onnx/best.pt \
        [--calibrate /work/data/train-s2 --images 64]

A wider network (``train --width/--dec/--ins-width``) is rebuilt as its
export's ``phyllo.architecture`` metadata says, so training can go on from
any committed export, e.g. one a GPU call brought back.

Training checkpoints are not committed; the shipped ONNX file is. Without
this, continuing from the shipped model means rerunning its whole recipe
(hours on a CPU). Export folds each BatchNorm into the convolution before
it, so the ONNX file holds, per convolution, W' = W·γ/σ and b' = β − μ·γ/σ.
Those are loaded into the same network, Conv by Conv in execution order
(shapes are checked), and every BatchNorm is set so that in eval mode it
adds b' and nothing else: the rebuilt model computes what the ONNX file
computes (checked against ONNX Runtime on every run).

Training mode normalises by batch statistics instead, which an identity
BatchNorm would get badly wrong. With ``--calibrate`` the BatchNorms take the
per-channel mean μ_c and variance v_c of their inputs on that dataset's
images: running_mean = μ_c, running_var = v_c, γ = sqrt(v_c + ε),
β = b' + μ_c. Eval mode is still exact, and a training batch whose
statistics are close to the dataset's sees nearly the same function, so
fine-tuning starts from the shipped model instead of from a jolt.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import onnx
import torch
from onnx import numpy_helper
from torch import nn

from ..contract import Contract, load_contract
from ..export import ARCHITECTURE_KEY, check_onnx
from ..model import PhylloNet, TipHead, TipNet, architecture_kwargs, build_model


def has_tip_output(path: str | Path, contract: Contract) -> bool:
    """Whether the ONNX file has the contract's optional leaf-tip output (a :class:`TipNet`)."""
    return contract.tip_name in [o.name for o in onnx.load(str(path)).graph.output]


def architecture_of(path: str | Path, meta: dict[str, str], given: dict) -> dict:
    """``build_model`` keyword arguments for the network in ``path`` (whose metadata is ``meta``):
    its ``phyllo.architecture``, else ``given`` (``width``/``dec``/``ins_width`` as ``train`` takes
    them; None: default)."""
    stamped = meta.get(ARCHITECTURE_KEY)
    if stamped is not None:
        kw = architecture_kwargs(json.loads(stamped))
        if any(v is not None for v in given.values()):
            wanted = architecture_kwargs(given)
            clash = [k for k, v in wanted.items() if k != "instance_stride" and v is not None and v != kw[k]]
            if clash:
                raise ValueError(f"{path}: its metadata says {', '.join(f'{k}={kw[k]}' for k in clash)}, "
                                 f"not what was given")
    else:
        kw = architecture_kwargs(given)
    if kw["instance_stride"] != 4:
        raise ValueError(f"{path}: instance heads at stride {kw['instance_stride']}; only stride 4 can be rebuilt")
    return kw


def onnx_convs(path: str | Path) -> list[tuple[str, np.ndarray, np.ndarray | None]]:
    """(node name, weight, bias) of every Conv in the graph, in graph order."""
    proto = onnx.load(str(path))
    inits = {i.name: numpy_helper.to_array(i) for i in proto.graph.initializer}
    convs = []
    for node in proto.graph.node:
        if node.op_type != "Conv":
            continue
        if any(name and name not in inits for name in node.input[1:]):
            raise ValueError(f"{path}: Conv {node.name} takes its weight or bias from the graph, not an initializer")
        bias = inits[node.input[2]] if len(node.input) > 2 and node.input[2] else None
        convs.append((node.name, inits[node.input[1]], bias))
    return convs


def conv_order(model: nn.Module, contract: Contract) -> list[nn.Conv2d]:
    """The model's Conv2d modules in the order one forward pass runs them (the exporter's order)."""
    seen: list[nn.Conv2d] = []
    hooks = [m.register_forward_hook(lambda mod, _i, _o: seen.append(mod))
             for m in model.modules() if isinstance(m, nn.Conv2d)]
    try:
        with torch.no_grad():
            model.eval()(torch.zeros(1, 3, contract.tile, contract.tile))
    finally:
        for h in hooks:
            h.remove()
    return seen


def following_bn(model: nn.Module) -> dict[nn.Conv2d, nn.BatchNorm2d]:
    """Each Conv2d that a BatchNorm2d directly follows in an ``nn.Sequential`` (``conv_bn``'s layout),
    or that a module names in its ``conv_bn_pairs()`` (the pretrained encoder's blocks)."""
    pairs: dict[nn.Conv2d, nn.BatchNorm2d] = {}
    for seq in model.modules():
        if hasattr(seq, "conv_bn_pairs"):
            pairs.update(dict(seq.conv_bn_pairs()))
        if isinstance(seq, nn.Sequential):
            kids = list(seq.children())
            for a, b in zip(kids, kids[1:]):
                if isinstance(a, nn.Conv2d) and isinstance(b, nn.BatchNorm2d):
                    pairs[a] = b
    return pairs


def load_folded(model: PhylloNet, path: str | Path, contract: Contract) -> int:
    """Loads the ONNX file's folded weights into ``model`` (identity BatchNorms); returns the Conv count."""
    convs = onnx_convs(path)
    order = conv_order(model, contract)
    if len(convs) != len(order):
        raise ValueError(f"{path}: {len(convs)} Conv nodes, but the network runs {len(order)} convolutions "
                         "(another architecture?)")
    bns = following_bn(model)
    with torch.no_grad():
        for (name, w, b), conv in zip(convs, order):
            if tuple(w.shape) != tuple(conv.weight.shape):
                raise ValueError(f"{path}: Conv {name} has weight {w.shape}, the network expects "
                                 f"{tuple(conv.weight.shape)} at this point")
            conv.weight.copy_(torch.from_numpy(w.copy()))
            bias = torch.from_numpy(b.copy()) if b is not None else torch.zeros(w.shape[0])
            bn = bns.get(conv)
            if bn is None:
                if conv.bias is None:
                    if b is not None and np.any(b != 0):
                        raise ValueError(f"{path}: Conv {name} has a bias, the network's has none")
                else:
                    conv.bias.copy_(bias)
                continue
            if conv.bias is not None:
                raise ValueError(f"Conv before {bn} unexpectedly has a bias")
            # eval: (z - 0) / sqrt((1 - eps) + eps) * 1 + b' = z + b'
            bn.running_mean.zero_()
            bn.running_var.fill_(1.0 - bn.eps)
            bn.weight.fill_(1.0)
            bn.bias.copy_(bias)
    return len(convs)


def calibrate_bn(model: PhylloNet, batches: list[torch.Tensor]) -> None:
    """Re-expresses every BatchNorm around its inputs' statistics on ``batches``; eval output is unchanged.

    The statistics are what BatchNorm itself would keep from these batches: the
    mean of the batch means and the mean of the *per-batch* variances. The
    variance over all pixels at once is larger by the spread of the batch means
    (a crop of white wall against one of leaves), and a network re-expressed
    around it would amplify every normalised activation in training mode by
    that ratio, so the first fine-tuning steps would train a different
    function from the shipped one.
    """
    sums: dict[nn.BatchNorm2d, list[torch.Tensor]] = {}

    def record(mod: nn.BatchNorm2d, inputs: tuple[torch.Tensor, ...], _out: torch.Tensor) -> None:
        z = inputs[0].detach().double()
        acc = sums.setdefault(mod, [torch.zeros(z.shape[1], dtype=torch.float64),
                                    torch.zeros(z.shape[1], dtype=torch.float64), torch.zeros((), dtype=torch.float64)])
        acc[0] += z.mean(dim=(0, 2, 3))
        acc[1] += z.var(dim=(0, 2, 3), unbiased=False)
        acc[2] += 1

    bns = [m for m in model.modules() if isinstance(m, nn.BatchNorm2d)]
    hooks = [m.register_forward_hook(record) for m in bns]
    try:
        with torch.no_grad():
            model.eval()
            for x in batches:
                model(x)
    finally:
        for h in hooks:
            h.remove()
    with torch.no_grad():
        for bn in bns:
            if bn not in sums:
                continue
            s, vs, n = sums[bn]
            mean = s / n
            var = (vs / n).clamp_min(0.0)
            # Current eval map: (z - m0) / sqrt(v0 + eps) * g0 + b0 = a*z + c.
            a = bn.weight.double() / torch.sqrt(bn.running_var.double() + bn.eps)
            c = bn.bias.double() - a * bn.running_mean.double()
            gamma = a * torch.sqrt(var + bn.eps)
            bn.running_mean.copy_(mean.float())
            bn.running_var.copy_(var.float())
            bn.weight.copy_(gamma.float())
            bn.bias.copy_((a * mean + c).float())


def calibration_batches(data: Path, contract: Contract, images: int, batch: int = 3, seed: int = 0,
                        crop: int = 448) -> list[torch.Tensor]:
    """Training-style crops (the train split's augmentation) of ``images`` images from ``data``.

    Use the fine-tuning run's batch size and crop: BatchNorm's statistics are per batch.
    """
    from ..augment import AugmentConfig
    from ..dataset import PanopticDataset

    ds = PanopticDataset(data, "train", AugmentConfig(crop=crop), contract, seed=seed, limit=images)
    xs = [ds[i][0] for i in range(len(ds))]
    return [torch.stack(xs[i:i + batch]) for i in range(0, len(xs), batch)]


def max_ort_difference(model: nn.Module, path: str | Path, contract: Contract, size: int = 256) -> float:
    """Largest absolute difference between ONNX Runtime on ``path`` and ``model`` (export's check; raises past its tolerance)."""
    return max(check_onnx(path, model, contract, size=size).values())


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.tools.from_onnx", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("onnx", type=Path, help="an ONNX file exported by phyllo_train.export (stride-4 instance heads)")
    ap.add_argument("--out", type=Path, required=True, help="checkpoint to write (.pt), usable as --init")
    ap.add_argument("--calibrate", type=Path, default=None, help="a phyllo-gen dataset whose train images set the BatchNorm statistics")
    ap.add_argument("--images", type=int, default=96, help="images for --calibrate")
    ap.add_argument("--batch", type=int, default=3, help="calibration batch size: the fine-tuning run's --batch")
    ap.add_argument("--crop", type=int, default=448, help="calibration crop side: the fine-tuning run's --crop")
    ap.add_argument("--head-out", type=Path, default=None,
                    help="with a tip model: also write its tip head as a `phyllo_train.tools.tips train` checkpoint "
                         "(for `train --tips --init-tip-head`)")
    ap.add_argument("--width", default=None,
                    help="encoder channels (train --width) of a file exported before the architecture was "
                         "stamped in its metadata; newer files say it themselves")
    ap.add_argument("--dec", default=None, help="decoder channels (train --dec), as --width")
    ap.add_argument("--ins-width", type=int, default=None, help="instance branch channels (train --ins-width), as --width")
    ap.add_argument("--contract", default=None, help="contract.toml (default: models/contract.toml)")
    args = ap.parse_args(argv)

    contract = load_contract(args.contract)
    try:
        meta = {p.key: p.value for p in onnx.load(str(args.onnx)).metadata_props}
        arch = architecture_of(args.onnx, meta, {"width": args.width, "dec": args.dec, "ins_width": args.ins_width})
        model = build_model(contract.num_classes, seed=0, **arch)
    except (ValueError, OSError) as e:
        print(f"from_onnx: {e}", file=sys.stderr)
        return 2
    try:
        # A model with a tip head is rebuilt whole and checked whole; the checkpoint keeps
        # the base network only (phyllo_train.tools.tips trains the head on top of it again).
        tip = has_tip_output(args.onnx, contract)
        net = TipNet(model, TipHead()) if tip else model
        n = load_folded(net, args.onnx, contract)
    except (ValueError, OSError) as e:
        print(f"from_onnx: {e}", file=sys.stderr)
        return 2
    if args.calibrate is not None:
        calibrate_bn(model, calibration_batches(args.calibrate, contract, args.images, batch=args.batch,
                                                crop=args.crop))
    try:
        names = contract.output_names_with_tip if tip else contract.output_names
        diff = max(check_onnx(args.onnx, net, contract, size=256, output_names=names).values())
    except AssertionError as e:
        print(f"from_onnx: the rebuilt model does not compute what {args.onnx} does: {e}", file=sys.stderr)
        return 1
    if args.head_out is not None:
        if not tip:
            print(f"from_onnx: {args.onnx} has no tip output, so no head for --head-out", file=sys.stderr)
            return 2
        args.head_out.parent.mkdir(parents=True, exist_ok=True)
        torch.save({"head": net.head.state_dict(), "width": net.head.out.in_channels,
                    "step": int(meta.get("phyllo.tip_head_steps", 0) or 0), "from_onnx": str(args.onnx)},
                   args.head_out)
    state = model.state_dict()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({
        "model": state, "raw_model": state, "ema": None, "step": 0, "best": float("inf"),
        "args": {**model.architecture(), "from_onnx": str(args.onnx)},
        "training_data": meta.get(contract.meta_training_data, "unknown"),
        "contract_version": contract.version,
        "from_onnx": {"file": str(args.onnx), "model_name": meta.get(contract.meta_model_name, "")},
    }, args.out)
    print(f"wrote {args.out}: {n} convolutions from {args.onnx} ({meta.get(contract.meta_model_name, '?')}); "
          f"BatchNorm {'calibrated on ' + str(args.calibrate) if args.calibrate else 'identity'}; "
          f"ONNX Runtime vs rebuilt model max abs diff {diff:.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
