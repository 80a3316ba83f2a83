"""Wrap a trained ONNX model so that it also sees the mirrored image and averages both.

    python -m phyllo_train.flip_tta models/phyllo.onnx --out flip.onnx --name phyllo-s10-flip

Test-time flip augmentation: the wrapped model runs its member on the batch and on
the batch mirrored left to right (one pass over a batch of 2N), mirrors the second
half's outputs back, negates their horizontal offsets (a centre to the right of a
pixel lies to its left in the mirror) and outputs the mean. A side view of a plant
mirrored is another plausible side view, so the two passes disagree only where the
member is unsure. The file is an ordinary phyllo model at twice the inference cost.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import onnx
from onnx import compose, helper, numpy_helper

from .contract import load_contract
from .export import stamp_metadata

_INT64_MAX = np.iinfo(np.int64).max
_INT64_MIN = np.iinfo(np.int64).min


def _const(name: str, values, dtype=np.int64) -> onnx.TensorProto:
    return numpy_helper.from_array(np.asarray(values, dtype=dtype), name)


def build_flip_tta(path: Path, *, name: str) -> onnx.ModelProto:
    """Return an ONNX model whose outputs average ``path``'s outputs on an image and its mirror."""
    contract = load_contract()
    member = onnx.load(str(path))
    meta = {p.key: p.value for p in member.metadata_props}
    input_name = member.graph.input[0].name
    outputs = [o.name for o in member.graph.output]
    if not set(contract.output_names) <= set(outputs):
        raise ValueError(f"{path}: the model needs the outputs {', '.join(contract.output_names)}")

    prefixed = compose.add_prefix(member, prefix="m/")
    g = prefixed.graph
    nodes, inits = [], list(g.initializer)
    inits += [
        _const("tta/zero", [0]), _const("tta/axis0", [0]), _const("tta/axis_w", [3]),
        _const("tta/rev_start", [-1]), _const("tta/rev_end", [_INT64_MIN]), _const("tta/rev_step", [-1]),
        _const("tta/end", [_INT64_MAX]),
        # The offset output is (dy, dx): only dx changes sign under a left-right mirror.
        numpy_helper.from_array(np.array([1.0, -1.0], dtype=np.float32).reshape(1, 2, 1, 1), "tta/mirror_dx"),
        numpy_helper.from_array(np.array(0.5, dtype=np.float32), "tta/half"),
    ]

    def mirror(src: str, dst: str) -> None:
        nodes.append(helper.make_node("Slice", [src, "tta/rev_start", "tta/rev_end", "tta/axis_w", "tta/rev_step"],
                                      [dst]))

    mirror(input_name, "tta/mirrored")
    nodes.append(helper.make_node("Concat", [input_name, "tta/mirrored"], ["tta/both"], axis=0))
    nodes.append(helper.make_node("Shape", [input_name], ["tta/shape"]))
    nodes.append(helper.make_node("Gather", ["tta/shape", "tta/zero"], ["tta/n"], axis=0))
    for node in g.node:
        node.input[:] = ["tta/both" if i == f"m/{input_name}" else i for i in node.input]
    nodes.extend(g.node)

    for out in outputs:
        src = f"m/{out}"
        nodes.append(helper.make_node("Slice", [src, "tta/zero", "tta/n", "tta/axis0"], [f"tta/{out}/plain"]))
        nodes.append(helper.make_node("Slice", [src, "tta/n", "tta/end", "tta/axis0"], [f"tta/{out}/flipped"]))
        mirror(f"tta/{out}/flipped", f"tta/{out}/back")
        back = f"tta/{out}/back"
        if out == contract.output_names[2]:
            nodes.append(helper.make_node("Mul", [back, "tta/mirror_dx"], [f"tta/{out}/back_dx"]))
            back = f"tta/{out}/back_dx"
        nodes.append(helper.make_node("Add", [f"tta/{out}/plain", back], [f"tta/{out}/sum"]))
        nodes.append(helper.make_node("Mul", [f"tta/{out}/sum", "tta/half"], [out]))

    graph = helper.make_graph(nodes, name, [member.graph.input[0]], list(member.graph.output),
                              initializer=inits, value_info=list(g.value_info))
    model = helper.make_model(graph, opset_imports=list(member.opset_import))
    model.ir_version = member.ir_version
    meta.update({
        "phyllo.model_name": name,
        "phyllo.flip_tta_of": meta.get("phyllo.model_name", path.stem),
    })
    stamp_metadata(model, meta)
    model.producer_name = "phyllo_train.flip_tta"
    model.doc_string = f"phyllo {name}: mean of {meta['phyllo.flip_tta_of']} on the image and its mirror"
    onnx.checker.check_model(model)
    return model


def check_flip_tta(path: Path, member: Path, *, size: tuple[int, int] = (64, 96), atol: float = 1e-4) -> float:
    """Compare the wrapped model with two onnxruntime runs of the member; return the largest gap."""
    import onnxruntime as ort

    contract = load_contract()
    x = np.random.default_rng(0).standard_normal((2, 3, *size)).astype(np.float32)
    wrapped = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    plain = ort.InferenceSession(str(member), providers=["CPUExecutionProvider"])
    names = [o.name for o in wrapped.get_outputs()]
    got = dict(zip(names, wrapped.run(None, {wrapped.get_inputs()[0].name: x})))
    a = dict(zip(names, plain.run(None, {plain.get_inputs()[0].name: x})))
    b = dict(zip(names, plain.run(None, {plain.get_inputs()[0].name: x[..., ::-1].copy()})))
    worst = 0.0
    for n in names:
        back = b[n][..., ::-1]
        if n == contract.output_names[2]:
            back = back * np.array([1.0, -1.0], dtype=np.float32).reshape(1, 2, 1, 1)
        worst = max(worst, float(np.abs(got[n] - 0.5 * (a[n] + back)).max()))
    if worst > atol:
        raise AssertionError(f"flip wrapper differs from the mean of the two passes by {worst:.2e}")
    return worst


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model", type=Path, help="trained ONNX model to wrap")
    ap.add_argument("--out", type=Path, required=True, help="wrapped ONNX file to write")
    ap.add_argument("--name", required=True, help="phyllo.model_name of the wrapped model")
    args = ap.parse_args(argv)
    model = build_flip_tta(args.model, name=args.name)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(model, str(args.out))
    worst = check_flip_tta(args.out, args.model)
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e6:.2f} MB; max gap to the two passes' mean {worst:.1e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
