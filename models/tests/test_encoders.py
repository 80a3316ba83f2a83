"""The ImageNet-pretrained EfficientNet-Lite0 encoder: strict loading, its input normalisation, export."""

from pathlib import Path

import pytest
import torch

from phyllo_train.encoders import EfficientNetLite, images_01, load_pretrained, normalisation_gaps, pretrained_path
from phyllo_train.export import check_onnx, export_onnx, load_checkpoint_model
from phyllo_train.model import architecture_kwargs, build_model, count_parameters
from phyllo_train.train import param_groups

DEV = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "unl-maize-dev"


def test_wheel_weights_load_strictly_and_change_the_encoder(contract):
    enc = EfficientNetLite(contract.mean, contract.std)
    before = enc._blocks[3]._depthwise_conv.weight.detach().clone()
    assert load_pretrained(enc) == 288  # every encoder tensor; the file's classifier left out
    state = torch.load(pretrained_path(), map_location="cpu", weights_only=True)
    assert torch.equal(enc._blocks[3]._depthwise_conv.weight, state["_blocks.3._depthwise_conv.weight"])
    assert not torch.equal(before, enc._blocks[3]._depthwise_conv.weight)


@pytest.mark.skipif(not (DEV / "crops").is_dir(), reason="real dev images not present")
def test_real_images_fit_the_tensorflow_normalisation_best(contract):
    """The weights came from TensorFlow: real images normalised to [-1, 1] match the pretrained
    BatchNorm statistics better than under ImageNet mean/std, which the wrapper then maps from."""
    files = sorted((DEV / "crops").glob("*.jpg"))[:10] + sorted((DEV / "images").glob("*.jpg"))[:10]
    x01 = images_01(files)
    gaps = normalisation_gaps(x01)
    tf, imagenet = gaps["[-1, 1] (TensorFlow)"], gaps["ImageNet mean/std"]
    assert tf[0] < 0.8 * imagenet[0] and tf[1] < 0.8 * imagenet[1], gaps
    # And the wrapper's mapping itself: contract input back to (pixel - 127) / 128.
    mean, std = torch.tensor(contract.mean).view(1, 3, 1, 1), torch.tensor(contract.std).view(1, 3, 1, 1)
    enc = EfficientNetLite(contract.mean, contract.std)
    got = (x01 - mean) / std * enc.in_scale + enc.in_shift
    assert torch.allclose(got, (x01 * 255 - 127) / 128, atol=1e-5)


def test_network_on_the_encoder_exports_and_reloads(tmp_path, contract):
    model = build_model(contract.num_classes, seed=0, encoder="efficientnet-lite0")
    load_pretrained(model.encoder)
    assert 2_500_000 < count_parameters(model) < 4_000_000
    assert architecture_kwargs(model.architecture())["encoder"] == "efficientnet-lite0"
    path = export_onnx(model, tmp_path / "lite.onnx", contract, model_name="t", trained=False, training_data="none")
    assert max(check_onnx(path, model, contract, size=128).values()) < 1e-3
    assert path.stat().st_size < 20_000_000
    ck = {"model": model.state_dict(), "args": {"encoder": "efficientnet-lite0"}}
    torch.save(ck, tmp_path / "c.pt")
    again, _ = load_checkpoint_model(tmp_path / "c.pt", contract)
    x = torch.randn(1, 3, 64, 64)
    with torch.no_grad():
        assert torch.equal(model.eval()(x)[0], again.eval()(x)[0])


def test_encoder_learning_rate_is_scaled_and_the_decoder_is_not(contract):
    model = build_model(contract.num_classes, seed=0, encoder="efficientnet-lite0")
    groups = param_groups(model, 1e-4, 0.5)
    enc = {id(p) for p in model.encoder.parameters()}
    for g in groups:
        inside = {id(p) in enc for p in g["params"]}
        assert len(inside) == 1
        assert g["lr_scale"] == (0.5 if inside == {True} else 1.0)
    assert sum(len(g["params"]) for g in groups) == len(list(model.parameters()))


def test_from_onnx_rebuilds_the_pretrained_network(tmp_path, contract):
    """A later stage resumes from the committed export: the encoder's BatchNorms unfold too."""
    from phyllo_train.tools import from_onnx

    model = build_model(contract.num_classes, seed=0, encoder="efficientnet-lite0")
    load_pretrained(model.encoder)
    # As after training: the decoder's folded biases differ (identical zero ones would be
    # shared by the exporter, which from_onnx refuses).
    torch.manual_seed(1)
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d) and m.eps == 1e-5:
            m.running_mean.normal_(0, 0.1)
    path = export_onnx(model, tmp_path / "lite.onnx", contract, model_name="t", trained=False, training_data="none")
    assert from_onnx.main([str(path), "--out", str(tmp_path / "r" / "best.pt")]) == 0
    again, _ = load_checkpoint_model(tmp_path / "r" / "best.pt", contract)
    assert again.encoder_name == "efficientnet-lite0"
    x = torch.randn(1, 3, 64, 64)
    with torch.no_grad():
        for a, b in zip(model.eval()(x), again.eval()(x)):
            assert torch.allclose(a, b, atol=1e-4)


def test_freezing_the_encoder_start_fixes_its_weights_and_statistics(contract):
    from phyllo_train.train import freeze_encoder, set_train_mode

    model = build_model(contract.num_classes, seed=0, encoder="efficientnet-lite0")
    frozen = freeze_encoder(model, 3)
    set_train_mode(model, False, frozen)
    assert not any(p.requires_grad for m in frozen for p in m.parameters())
    assert all(p.requires_grad for p in model.encoder._blocks[3].parameters())
    assert not model.encoder._bn0.training and not model.encoder._blocks[2]._bn1.training
    assert model.encoder._blocks[3]._bn1.training and model.aspp.training
    before = model.encoder._blocks[1]._bn1.running_mean.clone()
    model(torch.randn(2, 3, 64, 64))
    assert torch.equal(before, model.encoder._blocks[1]._bn1.running_mean)


def test_the_committed_stage_resumes_through_from_onnx(tmp_path):
    """models/phyllo-e40.onnx is where the pretrained-encoder model's next stage starts
    (EXPERIMENTS.md): it must rebuild into a training checkpoint that computes what it does."""
    from phyllo_train.tools import from_onnx

    committed = Path(__file__).resolve().parents[1] / "phyllo-e40.onnx"
    assert committed.stat().st_size < 20_000_000
    assert from_onnx.main([str(committed), "--out", str(tmp_path / "best.pt")]) == 0  # checks against ORT
    ck = torch.load(tmp_path / "best.pt", map_location="cpu", weights_only=False)
    assert ck["args"]["encoder"] == "efficientnet-lite0"
