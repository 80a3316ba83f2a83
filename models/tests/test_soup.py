"""Model soup: weighted means of checkpoints, refused when they do not match."""

import pytest
import torch

from phyllo_train.export import load_checkpoint_model
from phyllo_train.model import build_model
from phyllo_train.experiments.soup import main, soup_state


def test_soup_is_the_weighted_mean_and_keeps_counters(contract):
    a = build_model(contract.num_classes, seed=0).state_dict()
    b = build_model(contract.num_classes, seed=1).state_dict()
    s = soup_state([a, b], [3.0, 1.0])
    for k, v in s.items():
        if v.is_floating_point():
            assert torch.allclose(v, 0.75 * a[k] + 0.25 * b[k], atol=1e-6), k
        else:
            assert torch.equal(v, b[k]), k


def test_soup_refuses_other_networks(contract):
    a = build_model(contract.num_classes, seed=0).state_dict()
    b = build_model(contract.num_classes, seed=0, instance_stride=2).state_dict()
    with pytest.raises(ValueError, match="other layers"):
        soup_state([a, b], [1.0, 1.0])
    with pytest.raises(ValueError, match="weights"):
        soup_state([a, a], [1.0])


def test_soup_cli_writes_an_exportable_checkpoint(tmp_path, contract):
    paths = []
    for seed in (0, 1):
        p = tmp_path / f"{seed}.pt"
        torch.save({"model": build_model(contract.num_classes, seed=seed).state_dict(),
                    "args": {"instance_stride": 4}, "training_data": f"seed {seed}", "step": 10}, p)
        paths.append(p)
    out = tmp_path / "soup.pt"
    assert main([str(paths[0]), str(paths[1]), "--out", str(out)]) == 0
    model, ckpt = load_checkpoint_model(out, contract)
    assert "weight average" in ckpt["training_data"] and "seed 1" in ckpt["training_data"]
    a = torch.load(paths[0], weights_only=False)["model"]
    k = next(k for k, v in a.items() if v.is_floating_point())
    b = torch.load(paths[1], weights_only=False)["model"]
    assert torch.allclose(model.state_dict()[k], 0.5 * (a[k] + b[k]), atol=1e-6)
