"""Rebuilding a checkpoint from an exported ONNX file: exact in eval mode, close in train mode."""

import torch

from phyllo_train.export import export_onnx
from phyllo_train.from_onnx import calibrate_bn, calibration_batches, load_folded, main, max_ort_difference
from phyllo_train.model import build_model


def _trained_like(contract, seed):
    """A seeded network whose BatchNorms hold non-trivial statistics, as a trained one does."""
    model = build_model(contract.num_classes, seed=seed)
    g = torch.Generator().manual_seed(seed)
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            c = m.num_features
            m.running_mean.copy_(torch.randn(c, generator=g) * 0.3)
            m.running_var.copy_(torch.rand(c, generator=g) + 0.5)
            m.weight.data.copy_(torch.rand(c, generator=g) + 0.5)
            m.bias.data.copy_(torch.randn(c, generator=g) * 0.2)
    return model.eval()


def test_rebuilt_model_computes_what_the_onnx_file_does(tmp_path, contract):
    src = _trained_like(contract, seed=3)
    path = export_onnx(src, tmp_path / "m.onnx", contract, model_name="t", trained=True, training_data="none")
    rebuilt = build_model(contract.num_classes, seed=9)  # other random weights, all overwritten
    assert load_folded(rebuilt, path, contract) == 63
    assert max_ort_difference(rebuilt, path, contract, size=128) < 1e-3
    x = torch.randn(2, 3, 96, 128)
    with torch.no_grad():
        for a, b in zip(src(x), rebuilt.eval()(x)):
            assert float((a - b).abs().max()) < 1e-3 * max(1.0, float(a.abs().max()))


def test_calibrated_batchnorm_keeps_eval_and_nearly_keeps_train_mode(tmp_path, contract, tiny_dataset):
    src = _trained_like(contract, seed=4)
    path = export_onnx(src, tmp_path / "m.onnx", contract, model_name="t", trained=True, training_data="none")
    identity = build_model(contract.num_classes, seed=0)
    load_folded(identity, path, contract)
    calibrated = build_model(contract.num_classes, seed=0)
    load_folded(calibrated, path, contract)
    batches = calibration_batches(tiny_dataset, contract, images=4, batch=2)
    calibrate_bn(calibrated, batches)
    assert max_ort_difference(calibrated, path, contract, size=128) < 1e-3

    x = batches[0]
    with torch.no_grad():
        want = src.eval()(x)[0]
        off_identity = float((identity.train()(x)[0] - want).abs().mean())
        off_calibrated = float((calibrated.train()(x)[0] - want).abs().mean())
    # Batch statistics of a calibration batch are close to the calibration set's:
    # the calibrated network barely moves when switched to training mode.
    assert off_calibrated < 0.25 * off_identity, (off_calibrated, off_identity)


def test_cli_writes_an_init_checkpoint_and_refuses_another_architecture(tmp_path, contract):
    path = export_onnx(_trained_like(contract, seed=5), tmp_path / "m.onnx", contract, model_name="t5",
                       trained=True, training_data="seed five")
    out = tmp_path / "run" / "best.pt"
    assert main([str(path), "--out", str(out)]) == 0
    ck = torch.load(out, weights_only=False)
    assert ck["training_data"] == "seed five" and ck["from_onnx"]["model_name"] == "t5"
    model = build_model(contract.num_classes, seed=None)
    model.load_state_dict(ck["raw_model"])

    other = build_model(contract.num_classes, seed=0, instance_stride=2)
    bad = export_onnx(other, tmp_path / "s2.onnx", contract, model_name="s2", trained=True, training_data="none")
    assert main([str(bad), "--out", str(tmp_path / "bad.pt")]) == 2
    assert not (tmp_path / "bad.pt").exists()
