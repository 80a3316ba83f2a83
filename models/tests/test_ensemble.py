"""Output ensembles: one ONNX file that runs every member and averages their outputs."""

import numpy as np
import onnx
import onnxruntime as ort
import pytest

from phyllo_train.experiments.ensemble import build_ensemble, main
from phyllo_train.export import export_onnx
from phyllo_train.model import build_model, with_tip_head


def _export(tmp_path, contract, seed, *, tips=False, name=None):
    model = build_model(contract.num_classes, seed=seed)
    names = None
    if tips:
        model = with_tip_head(model)
        names = contract.output_names_with_tip
    return export_onnx(model, tmp_path / f"{name or seed}.onnx", contract, model_name=f"member-{seed}",
                       trained=False, training_data=f"seed {seed}", output_names=names)


def _run(path, x):
    s = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return dict(zip([o.name for o in s.get_outputs()], s.run(None, {s.get_inputs()[0].name: x})))


def test_ensemble_is_the_weighted_mean_of_its_members(tmp_path, contract):
    a, b = _export(tmp_path, contract, 0), _export(tmp_path, contract, 1)
    out = tmp_path / "ens.onnx"
    assert main([str(a), str(b), "--out", str(out), "--name", "ens-test", "--weights", "1", "3"]) == 0
    x = np.random.default_rng(3).standard_normal((2, 3, 64, 96)).astype(np.float32)
    got, ra, rb = _run(out, x), _run(a, x), _run(b, x)
    assert list(got) == list(contract.output_names)
    for name in contract.output_names:
        assert got[name].shape == ra[name].shape
        # Untrained centre and offset heads start near zero, so the tolerance scales with them.
        scale = float(np.abs(ra[name]).max())
        np.testing.assert_allclose(got[name], 0.25 * ra[name] + 0.75 * rb[name], atol=1e-5 * scale)
        # The members differ, so the mean is neither of them.
        assert np.abs(ra[name] - rb[name]).max() > 1e-3 * scale
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert meta["phyllo.model_name"] == "ens-test"
    assert meta["phyllo.ensemble_members"] == "member-0,member-1"
    assert meta["phyllo.ensemble_weights"] == "0.2500,0.7500"
    assert meta["phyllo.contract_version"] == str(contract.version)


def test_ensemble_keeps_only_the_outputs_every_member_has(tmp_path, contract):
    plain = _export(tmp_path, contract, 0)
    tipped = _export(tmp_path, contract, 1, tips=True, name="tips")
    assert [o.name for o in build_ensemble([plain, tipped], name="e").graph.output] == list(contract.output_names)
    both = build_ensemble([tipped, tipped], name="e2")
    assert [o.name for o in both.graph.output] == list(contract.output_names_with_tip)


def test_ensemble_refuses_members_of_other_contracts(tmp_path, contract):
    a, b = _export(tmp_path, contract, 0), _export(tmp_path, contract, 1)
    proto = onnx.load(str(b))
    next(p for p in proto.metadata_props if p.key == "phyllo.contract_version").value = "999"
    onnx.save(proto, str(b))
    with pytest.raises(ValueError, match="contract version"):
        build_ensemble([a, b], name="e")
    with pytest.raises(ValueError, match="at least two"):
        build_ensemble([a], name="e")
