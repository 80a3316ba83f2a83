"""ONNX export: names, dynamic axes, metadata, ORT == PyTorch; and the committed untrained model."""

from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort

from phyllo_train.export import check_onnx, export_onnx
from phyllo_train.model import build_model, count_parameters

MODELS = Path(__file__).resolve().parent.parent


def _meta(path):
    return {p.key: p.value for p in onnx.load(str(path)).metadata_props}


def test_export_roundtrip(tmp_path, contract):
    model = build_model(contract.num_classes, seed=0)
    assert 250_000 < count_parameters(model) < 1_000_000
    path = export_onnx(model, tmp_path / "m.onnx", contract, model_name="test", trained=False, training_data="none")
    errs = check_onnx(path, model, contract, size=128)  # raises on mismatch
    assert max(errs.values()) < 1e-3
    meta = _meta(path)
    assert meta["phyllo.contract_version"] == str(contract.version)
    assert meta["phyllo.trained"] == "false" and meta["phyllo.model_name"] == "test"
    assert "phyllo.training_data" in meta
    assert onnx.load(str(path)).opset_import[0].version >= 17


def test_seeded_init_is_deterministic(contract):
    a = build_model(contract.num_classes, seed=0).state_dict()
    b = build_model(contract.num_classes, seed=0).state_dict()
    assert all(np.array_equal(a[k].numpy(), b[k].numpy()) for k in a)


def test_committed_untrained_model(contract):
    path = MODELS / "phyllo-untrained.onnx"
    assert path.stat().st_size < 5_000_000
    meta = _meta(path)
    assert meta["phyllo.contract_version"] == str(contract.version) and meta["phyllo.trained"] == "false"
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    assert [i.name for i in sess.get_inputs()] == [contract.input_name]
    assert [o.name for o in sess.get_outputs()] == list(contract.output_names)
    x = np.zeros((3, 3, 64, 96), np.float32)  # dynamic N, H, W
    sem, cen, off = sess.run(None, {contract.input_name: x})
    assert sem.shape == (3, 4, 32, 48) and cen.shape == (3, 1, 32, 48) and off.shape == (3, 2, 32, 48)


def test_stride2_instance_branch_starts_as_upsampling(contract):
    import torch

    from phyllo_train.train import init_weights

    s4 = build_model(contract.num_classes, seed=0).eval()
    s2 = build_model(contract.num_classes, seed=1, instance_stride=2).eval()
    assert sorted({k.split(".")[0] for k in init_weights(s2, s4.state_dict())}) == ["ins_up2"]
    x = torch.randn(1, 3, 64, 64)
    with torch.no_grad():
        a, b = s4(x), s2(x)
    # Same outputs, same shapes; the semantic path is untouched.
    assert all(u.shape == v.shape for u, v in zip(a, b))
    assert torch.allclose(a[0], b[0])
