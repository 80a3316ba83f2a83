"""Export the network to ONNX with the contract stamped into its metadata.

    python -m phyllo_train.export --untrained --out models/phyllo-untrained.onnx
    python -m phyllo_train.export --checkpoint RUN_DIR/best.pt --out models/phyllo.onnx

Every export is checked: onnx.checker, input/output names and dynamic axes as
the contract says, metadata present, and onnxruntime agreeing with PyTorch on
a batch (and on a non-square size, to exercise the dynamic H, W).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np
import onnx
import torch

from .contract import Contract, load_contract
from .model import TipNet, architecture_kwargs, build_model, count_parameters, with_tip_head

OPSET = 17
ARCHITECTURE_KEY = "phyllo.architecture"


def export_onnx(model: torch.nn.Module, out: str | Path, contract: Contract, *, model_name: str,
                trained: bool, training_data: str, extra_meta: dict[str, str] | None = None,
                output_names: tuple[str, ...] | None = None) -> Path:
    """Write ``model`` to ``out`` as ONNX (opset 17, dynamic N/H/W) with phyllo metadata.

    ``output_names`` default to the contract's three; a model with the leaf-tip
    head passes ``contract.output_names_with_tip``.
    """
    names = tuple(output_names or contract.output_names)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    model = model.eval().cpu()
    dummy = torch.zeros(1, 3, contract.tile, contract.tile)
    axes = {contract.input_name: {0: "N", 2: "H", 3: "W"}}
    for name in names:
        # Named separately from the input's: they are H/stride, W/stride.
        axes[name] = {0: "N", 2: "H_out", 3: "W_out"}
    with warnings.catch_warnings():
        # The TorchScript exporter is deprecated but needs no onnxscript and gives a plain,
        # constant-folded graph (BN folded into Conv) that ONNX Runtime optimises well.
        warnings.simplefilter("ignore")
        torch.onnx.export(
            model, (dummy,), str(out), dynamo=False, opset_version=OPSET,
            input_names=[contract.input_name], output_names=list(names),
            dynamic_axes=axes, do_constant_folding=True,
        )
    proto = onnx.load(str(out))
    meta = {
        contract.meta_contract_version: str(contract.version),
        contract.meta_model_name: model_name,
        contract.meta_trained: "true" if trained else "false",
        contract.meta_training_data: training_data,
        "phyllo.parameters": str(count_parameters(model)),
        "phyllo.output_stride": str(contract.stride),
    }
    base = model.base if isinstance(model, TipNet) else model
    if hasattr(base, "architecture"):
        # from_onnx rebuilds a wider network from this, so a GPU run can continue from its export.
        meta[ARCHITECTURE_KEY] = json.dumps(base.architecture())
    meta.update(extra_meta or {})
    stamp_metadata(proto, meta)
    proto.producer_name = "phyllo_train"
    proto.doc_string = f"phyllo {model_name}: Panoptic-DeepLab-style semantic/center/offset heads at stride {contract.stride}"
    onnx.checker.check_model(proto)
    onnx.save(proto, str(out))
    return out


def stamp_metadata(proto: onnx.ModelProto, meta: dict[str, str]) -> None:
    """Replace ``proto``'s metadata with ``meta`` (the keys phyllo reads, see the contract)."""
    del proto.metadata_props[:]
    for k, v in meta.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = k, v


def check_onnx(path: str | Path, model: torch.nn.Module, contract: Contract, *, atol: float = 1e-3,
               seed: int = 0, size: int | None = None,
               output_names: tuple[str, ...] | None = None) -> dict[str, float]:
    """Check names, dynamic axes and metadata, and that ORT matches PyTorch; returns max abs errors.

    Runs a batch of 2 square ``size`` tiles (default: the contract's tile) and one
    non-square image, so the dynamic N, H and W are all exercised.
    """
    import onnxruntime as ort

    names = tuple(output_names or contract.output_names)
    proto = onnx.load(str(path))
    ins = [i.name for i in proto.graph.input]
    outs = [o.name for o in proto.graph.output]
    if ins != [contract.input_name] or outs != list(names):
        raise AssertionError(f"graph names {ins} -> {outs} differ from the contract")
    dims = [d.dim_param or d.dim_value for d in proto.graph.input[0].type.tensor_type.shape.dim]
    if dims != ["N", 3, "H", "W"]:
        raise AssertionError(f"input dims {dims} are not [N, 3, H, W]")
    meta = {p.key: p.value for p in proto.metadata_props}
    for key in (contract.meta_contract_version, contract.meta_model_name, contract.meta_trained,
                contract.meta_training_data):
        if key not in meta:
            raise AssertionError(f"metadata key {key} missing")
    if meta[contract.meta_contract_version] != str(contract.version):
        raise AssertionError("contract version mismatch in metadata")

    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(seed)
    errs: dict[str, float] = {}
    model = model.eval().cpu()
    t = size or contract.tile
    for shape in ((2, 3, t, t), (1, 3, t - 64 if t > 64 else 2 * t, t + 64)):
        x = rng.standard_normal(shape, dtype=np.float32)
        got = sess.run(list(names), {contract.input_name: x})
        with torch.no_grad():
            want = [w.numpy() for w in model(torch.from_numpy(x))]
        for name, g, w in zip(names, got, want):
            exp_shape = (shape[0], w.shape[1], shape[2] // contract.stride, shape[3] // contract.stride)
            if g.shape != exp_shape or w.shape != exp_shape:
                raise AssertionError(f"{name}: ORT {g.shape}, torch {w.shape}, expected {exp_shape}")
            err = float(np.max(np.abs(g - w)))
            # Relative to the output's scale: offsets are tens of pixels once trained.
            scale = max(1.0, float(np.max(np.abs(w))))
            if err > atol * scale:
                raise AssertionError(f"{name}: ORT and PyTorch differ by {err} at shape {shape}")
            errs[name] = max(errs.get(name, 0.0), err)
    return errs


def load_checkpoint_model(path: str | Path, contract: Contract) -> tuple[torch.nn.Module, dict]:
    """Build the network and load weights from a training checkpoint; returns (model, checkpoint)."""
    ckpt = torch.load(str(path), map_location="cpu", weights_only=False)
    args = ckpt.get("args") or {}
    model = build_model(contract.num_classes, seed=None, **architecture_kwargs(args))
    if args.get("tips"):
        model = with_tip_head(model, int(args.get("tip_width", 32)))
    model.load_state_dict(ckpt["model"])
    return model, ckpt


def main(argv: list[str] | None = None) -> int:
    """CLI entry point."""
    ap = argparse.ArgumentParser(prog="python -m phyllo_train.export", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--untrained", action="store_true", help="export seeded random weights (phyllo.trained=false)")
    src.add_argument("--checkpoint", type=Path, help="training checkpoint (.pt) to export (phyllo.trained=true)")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=0, help="init seed for --untrained")
    ap.add_argument("--name", default=None, help="phyllo.model_name (default: phyllo-untrained / phyllo-lite)")
    ap.add_argument("--training-data", default=None, help="phyllo.training_data text (default: from the checkpoint)")
    ap.add_argument("--contract", default=None, help="contract.toml (default: models/contract.toml)")
    ap.add_argument("--check-size", type=int, default=None, help="tile side for the ORT-vs-torch check (default: contract tile)")
    args = ap.parse_args(argv)

    contract = load_contract(args.contract)
    extra: dict[str, str] = {}
    if args.untrained:
        model = build_model(contract.num_classes, seed=args.seed)
        name = args.name or "phyllo-untrained"
        data = args.training_data or f"none (random init, torch seed {args.seed})"
        trained = False
    else:
        model, ckpt = load_checkpoint_model(args.checkpoint, contract)
        name = args.name or "phyllo-lite"
        data = args.training_data or ckpt.get("training_data", "unknown")
        trained = True
        extra["phyllo.train_steps"] = str(ckpt.get("step", ""))
    names = contract.output_names_with_tip if isinstance(model, TipNet) else contract.output_names
    path = export_onnx(model, args.out, contract, model_name=name, trained=trained, training_data=data,
                       extra_meta=extra, output_names=names)
    errs = check_onnx(path, model, contract, size=args.check_size, output_names=names)
    size_mb = path.stat().st_size / 1e6
    print(f"wrote {path} ({size_mb:.2f} MB, {count_parameters(model)} params, contract v{contract.version}, "
          f"trained={trained}); ORT vs torch max abs diff: " + ", ".join(f"{k}={v:.2e}" for k, v in errs.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
