"""AdaBN: BatchNorm statistics re-estimated on unlabelled images, cut as the daemon cuts them."""

import numpy as np
import onnx
import torch

from phyllo_train import export
from phyllo_train.experiments import adapt_bn
from phyllo_train.model import build_model


def _checkpoint(path, contract):
    """A from_onnx-style checkpoint whose BatchNorms hold statistics far from any image's."""
    model = build_model(contract.num_classes, seed=7)
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.fill_(5.0)
            m.running_var.fill_(9.0)
    state = model.state_dict()
    torch.save({"model": state, "raw_model": state, "ema": None, "step": 0, "args": {"instance_stride": 4},
                "training_data": "fixture"}, path)
    return model


def _bns(model):
    return [m for m in model.modules() if isinstance(m, torch.nn.BatchNorm2d)]


def test_first_layers_take_the_images_statistics_and_the_rest_keep_theirs(tmp_path, contract, tiny_dataset):
    _checkpoint(tmp_path / "in.pt", contract)
    out = tmp_path / "ada.pt"
    assert adapt_bn.main(["--checkpoint", str(tmp_path / "in.pt"), "--images", str(tiny_dataset / "images"),
                          "--out", str(out), "--layers", "2", "--batch", "2"]) == 0
    model, ck = export.load_checkpoint_model(out, contract)
    bns = _bns(model)
    # The first BatchNorm follows the stem convolution of the normalised tiles: its new
    # mean is what that convolution gives on them, nowhere near the planted 5.0.
    tiles = torch.from_numpy(np.concatenate(adapt_bn.daemon_tiles(adapt_bn.image_paths([tiny_dataset / "images"]))))
    with torch.no_grad():
        z = model.stem[0][0](tiles)
    assert torch.allclose(bns[0].running_mean, z.mean(dim=(0, 2, 3)), atol=0.05)
    assert not torch.allclose(bns[1].running_mean, torch.full_like(bns[1].running_mean, 5.0))
    assert all(torch.all(bn.running_mean == 5.0) and torch.all(bn.running_var == 9.0) for bn in bns[2:])
    assert "2 BatchNorm layers' statistics adapted (AdaBN) to 6 unlabelled images" in ck["training_data"]

    onnx_path = tmp_path / "ada.onnx"
    assert export.main(["--checkpoint", str(out), "--out", str(onnx_path), "--check-size", "64"]) == 0
    meta = {p.key: p.value for p in onnx.load(str(onnx_path)).metadata_props}
    assert "AdaBN" in meta["phyllo.training_data"]


def test_a_dataset_is_read_through_its_manifest_and_a_bad_image_is_named(tmp_path, contract, tiny_dataset):
    assert len(adapt_bn.image_paths([tiny_dataset])) == 6
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "half.jpg").write_bytes(b"\xff\xd8\xff\xe0 not a whole jpeg")
    _checkpoint(tmp_path / "in.pt", contract)
    assert adapt_bn.main(["--checkpoint", str(tmp_path / "in.pt"), "--images", str(bad),
                          "--out", str(tmp_path / "x.pt")]) == 2
    assert not (tmp_path / "x.pt").exists()
