"""Rebuilding a checkpoint from an exported ONNX file: exact in eval mode, close in train mode."""

import torch

from phyllo_train.export import export_onnx
from phyllo_train.tools.from_onnx import calibrate_bn, calibration_batches, load_folded, main, max_ort_difference
from phyllo_train.model import build_model


def _trained_like(contract, seed, **layout):
    """A seeded network whose BatchNorms hold non-trivial statistics, as a trained one does
    (a fresh one's all-zero folded biases are exported as graph constants)."""
    model = build_model(contract.num_classes, seed=seed, **layout)
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


WIDE = {"width": (24, 32, 48, 96, 160), "dec": (96, 64, 48, 32), "ins_width": 64}


def test_a_wider_export_is_rebuilt_from_its_metadata_and_trained_on(tmp_path, contract, tiny_dataset):
    import onnx

    from phyllo_train import train
    from phyllo_train.export import ARCHITECTURE_KEY

    wide = _trained_like(contract, 6, **WIDE)
    path = export_onnx(wide, tmp_path / "wide.onnx", contract, model_name="wide", trained=True, training_data="none")
    out = tmp_path / "wide.pt"
    assert main([str(path), "--out", str(out)]) == 0
    ck = torch.load(out, weights_only=False)
    assert tuple(ck["args"]["width"]) == WIDE["width"] and ck["args"]["ins_width"] == 64
    rebuilt = build_model(contract.num_classes, seed=None, **WIDE)
    rebuilt.load_state_dict(ck["raw_model"])
    assert max_ort_difference(rebuilt, path, contract, size=128) < 1e-3

    # A file from before the metadata needs the widths given, and refuses the default layout.
    proto = onnx.load(str(path))
    kept = [p for p in proto.metadata_props if p.key != ARCHITECTURE_KEY]
    del proto.metadata_props[:]
    proto.metadata_props.extend(kept)
    old = tmp_path / "old.onnx"
    onnx.save(proto, str(old))
    assert main([str(old), "--out", str(tmp_path / "bad.pt")]) == 2
    assert main([str(old), "--out", str(tmp_path / "ok.pt"), "--width", "24,32,48,96,160", "--dec", "96,64,48,32",
                 "--ins-width", "64"]) == 0
    # Widths that contradict the metadata are refused.
    assert main([str(path), "--out", str(tmp_path / "clash.pt"), "--width", "16,24,32,64,128"]) == 2

    # train --init takes the layout from the checkpoint: no --width/--dec/--ins-width needed.
    run = tmp_path / "go-on"
    assert train.main(["--data", str(tiny_dataset), "--out", str(run), "--crop", "64", "--batch", "2",
                       "--workers", "0", "--val-limit", "0", "--steps", "1", "--warmup", "1",
                       "--init", str(out)]) == 0
    ck = torch.load(run / "last.pt", map_location="cpu", weights_only=False)
    assert tuple(ck["args"]["width"]) == WIDE["width"] and tuple(ck["args"]["dec"]) == WIDE["dec"]
