"""Test-time flip: one ONNX file that averages a model's outputs on an image and its mirror."""

import numpy as np
import onnx
import onnxruntime as ort

from phyllo_train.export import export_onnx
from phyllo_train.flip_tta import main
from phyllo_train.model import build_model


def _run(path, x):
    s = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return dict(zip([o.name for o in s.get_outputs()], s.run(None, {s.get_inputs()[0].name: x})))


def test_flip_wrapper_averages_the_image_and_its_mirror(tmp_path, contract):
    model = build_model(contract.num_classes, seed=0)
    member = export_onnx(model, tmp_path / "m.onnx", contract, model_name="member", trained=False,
                         training_data="seed 0")
    out = tmp_path / "flip.onnx"
    assert main([str(member), "--out", str(out), "--name", "flip-test"]) == 0
    x = np.random.default_rng(3).standard_normal((2, 3, 64, 96)).astype(np.float32)
    got, plain, mirrored = _run(out, x), _run(member, x), _run(member, x[..., ::-1].copy())
    sem, center, offset = contract.output_names
    assert list(got) == [sem, center, offset]
    for name in (sem, center):
        scale = float(np.abs(plain[name]).max())
        np.testing.assert_allclose(got[name], 0.5 * (plain[name] + mirrored[name][..., ::-1]), atol=1e-5 * scale)
    # Offsets point at the leaf's centre: in the mirror dx changes sign, dy does not.
    back = mirrored[offset][..., ::-1]
    scale = float(np.abs(plain[offset]).max())
    np.testing.assert_allclose(got[offset][:, 0], 0.5 * (plain[offset][:, 0] + back[:, 0]), atol=1e-5 * scale)
    np.testing.assert_allclose(got[offset][:, 1], 0.5 * (plain[offset][:, 1] - back[:, 1]), atol=1e-5 * scale)
    # A random net is not mirror-symmetric, so the wrapper is not the member.
    assert np.abs(got[center] - plain[center]).max() > 1e-3 * float(np.abs(plain[center]).max())
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert meta["phyllo.model_name"] == "flip-test"
    assert meta["phyllo.flip_tta_of"] == "member"
    assert meta["phyllo.contract_version"] == str(contract.version)
