"""Combine trained ONNX models into one ONNX model that averages their outputs.

    python -m phyllo_train.experiments.ensemble models/phyllo.onnx other.onnx --out ens.onnx --name phyllo-ens

Each member runs on the same normalised image; the ensemble's ``semantic``
(logits), ``center`` and ``offset`` outputs are the members' weighted means
(and ``tip`` when every member has one). The file is an ordinary phyllo model:
the Rust side loads it unchanged, at the members' summed inference cost.
Averaging outputs, unlike averaging weights (:mod:`phyllo_train.experiments.soup`), needs
no shared training history: members only have to agree on the contract.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import onnx
from onnx import compose, helper, numpy_helper

from ..contract import load_contract
from ..export import stamp_metadata

def _meta(model: onnx.ModelProto) -> dict[str, str]:
    return {p.key: p.value for p in model.metadata_props}


def _normalised(weights: list[float] | None, n: int) -> list[float]:
    """One positive weight per member (equal by default), scaled to sum to one."""
    weights = weights or [1.0] * n
    if len(weights) != n or any(w <= 0 for w in weights):
        raise ValueError("give one positive weight per model")
    total = float(sum(weights))
    return [w / total for w in weights]


def build_ensemble(paths: list[Path], *, name: str, weights: list[float] | None = None) -> onnx.ModelProto:
    """Return one ONNX model whose outputs are the weighted means of the members' outputs.

    Members must share the input name and contract version; only outputs every
    member has are kept. Weights are normalised to sum to one.
    """
    if len(paths) < 2:
        raise ValueError("an ensemble needs at least two models")
    weights = _normalised(weights, len(paths))
    contract = load_contract()

    members = [onnx.load(str(p)) for p in paths]
    metas = [_meta(m) for m in members]
    input_names = {m.graph.input[0].name for m in members}
    if len(input_names) != 1:
        raise ValueError(f"members disagree on the input name: {sorted(input_names)}")
    (input_name,) = input_names
    versions = {meta.get("phyllo.contract_version") for meta in metas}
    if len(versions) != 1:
        raise ValueError(f"members disagree on the contract version: {sorted(map(str, versions))}")
    opsets = {next(o.version for o in m.opset_import if o.domain in ("", "ai.onnx")) for m in members}
    if len(opsets) != 1:
        raise ValueError(f"members use different opsets: {sorted(opsets)}")
    shared = [o for o in contract.output_names_with_tip if all(o in {x.name for x in m.graph.output} for m in members)]
    if not set(contract.output_names) <= set(shared):
        raise ValueError(f"every member needs the outputs {', '.join(contract.output_names)}")

    nodes, inits, value_info = [], [], []
    for k, member in enumerate(members):
        prefixed = compose.add_prefix(member, prefix=f"m{k}/")
        g = prefixed.graph
        for node in g.node:
            node.input[:] = [input_name if i == f"m{k}/{input_name}" else i for i in node.input]
        nodes.extend(g.node)
        inits.extend(g.initializer)
        value_info.extend(g.value_info)

    outputs = []
    template = {o.name: o for o in members[0].graph.output}
    for out in shared:
        terms = []
        for k, w in enumerate(weights):
            scale = f"ens/w{k}/{out}"
            inits.append(numpy_helper.from_array(np.array(w, dtype=np.float32), scale))
            nodes.append(helper.make_node("Mul", [f"m{k}/{out}", scale], [f"ens/{out}{k}"]))
            terms.append(f"ens/{out}{k}")
        nodes.append(helper.make_node("Sum", terms, [out]))
        outputs.append(template[out])

    graph = helper.make_graph(nodes, name, [members[0].graph.input[0]], outputs, initializer=inits,
                              value_info=value_info)
    model = helper.make_model(graph, opset_imports=list(members[0].opset_import))
    model.ir_version = members[0].ir_version
    meta = dict(metas[0])
    member_names = [m.get("phyllo.model_name", Path(p).stem) for m, p in zip(metas, paths)]
    meta.update({
        "phyllo.model_name": name,
        "phyllo.ensemble_members": ",".join(member_names),
        "phyllo.ensemble_weights": ",".join(f"{w:.4f}" for w in weights),
        "phyllo.parameters": str(sum(int(m.get("phyllo.parameters", "0")) for m in metas)),
        "phyllo.training_data": " | ".join(f"{n}: {m.get('phyllo.training_data', '')}"
                                           for n, m in zip(member_names, metas)),
    })
    stamp_metadata(model, meta)
    model.producer_name = "phyllo_train.ensemble"  # unchanged by the move: the files it writes say what they always said
    model.doc_string = f"phyllo {name}: mean of {', '.join(member_names)}"
    onnx.checker.check_model(model)
    return model


def check_ensemble(path: Path, members: list[Path], weights: list[float] | None = None, *,
                   size: tuple[int, int] = (64, 96), atol: float = 1e-4) -> float:
    """Run the ensemble and its members in onnxruntime; return the largest gap to the weighted mean."""
    import onnxruntime as ort

    weights = _normalised(weights, len(members))
    x = np.random.default_rng(0).standard_normal((1, 3, *size)).astype(np.float32)
    ens = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    names = [o.name for o in ens.get_outputs()]
    got = dict(zip(names, ens.run(None, {ens.get_inputs()[0].name: x})))
    worst = 0.0
    want = {n: 0.0 for n in names}
    for w, p in zip(weights, members):
        s = ort.InferenceSession(str(p), providers=["CPUExecutionProvider"])
        outs = dict(zip([o.name for o in s.get_outputs()], s.run(None, {s.get_inputs()[0].name: x})))
        for n in names:
            want[n] = want[n] + w * outs[n]
    for n in names:
        worst = max(worst, float(np.abs(got[n] - want[n]).max()))
    if worst > atol:
        raise AssertionError(f"ensemble differs from the mean of its members by {worst:.2e}")
    return worst


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("models", nargs="+", type=Path, help="member ONNX files (at least two)")
    ap.add_argument("--out", type=Path, required=True, help="ensemble ONNX file to write")
    ap.add_argument("--name", required=True, help="phyllo.model_name of the ensemble")
    ap.add_argument("--weights", type=float, nargs="+", help="one weight per model (default: equal)")
    args = ap.parse_args(argv)
    model = build_ensemble(args.models, name=args.name, weights=args.weights)
    version, want = _meta(model).get("phyllo.contract_version"), str(load_contract().version)
    if version != want:
        raise SystemExit(f"the members follow contract v{version}, models/contract.toml is v{want}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(model, str(args.out))
    worst = check_ensemble(args.out, args.models, args.weights)
    size = args.out.stat().st_size / 1e6
    print(f"wrote {args.out} ({size:.2f} MB, {len(args.models)} members; max gap to the members' mean {worst:.1e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
