"""Growing a narrow network's checkpoint into a wider one keeps its output."""

import pytest
import torch

from phyllo_train.model import architecture_kwargs, build_model, count_parameters, grow_state
from phyllo_train.train import init_weights


def _with_stats(model, seed):
    g = torch.Generator().manual_seed(seed)
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.copy_(torch.randn(m.num_features, generator=g) * 0.3)
            m.running_var.copy_(torch.rand(m.num_features, generator=g) + 0.5)
            m.bias.data.copy_(torch.randn(m.num_features, generator=g) * 0.2)
    return model.eval()


@pytest.mark.parametrize("width", [None, (24, 32, 48, 96, 160)])
def test_wider_network_starts_as_the_narrow_network(contract, width):
    narrow = _with_stats(build_model(contract.num_classes, seed=0), 1)
    wide = build_model(contract.num_classes, seed=7, dec=(80, 56, 40, 32), ins_width=64, width=width)
    assert count_parameters(wide) > count_parameters(narrow) + 20_000
    assert init_weights(wide, narrow.state_dict()) == []
    x = torch.randn(2, 3, 64, 96)
    with torch.no_grad():
        for a, b in zip(narrow(x), wide.eval()(x)):
            assert a.shape == b.shape
            assert float((a - b).abs().max()) < 1e-4 * max(1.0, float(a.abs().max()))
    # The added capacity is live: training moves the output away from the narrow network's.
    opt = torch.optim.SGD(wide.parameters(), lr=0.05)
    wide.train()
    for _ in range(3):
        opt.zero_grad()
        sum(t.square().mean() for t in wide(x)).backward()
        opt.step()
    small = narrow.state_dict()
    grown = [p.detach() for n, p in wide.named_parameters()
             if p.ndim == 4 and p.shape[1] > small[n].shape[1]]  # zeroed where they read added channels
    assert grown and any(float(p[:, -1].abs().sum()) > 0 for p in grown)


def test_grow_refuses_a_narrower_target(contract):
    wide = build_model(contract.num_classes, seed=0, ins_width=48)
    narrow = build_model(contract.num_classes, seed=0)
    with pytest.raises(ValueError, match="cannot grow"):
        grow_state(narrow, wide.state_dict())


def test_architecture_comes_back_from_saved_args():
    # Older checkpoints name no encoder: the original (mobilenet) layout.
    assert architecture_kwargs(None) == {"instance_stride": 4, "dec": None, "width": None, "ins_width": None,
                                         "encoder": None}
    kw = architecture_kwargs({"instance_stride": 4, "dec": [80, 56, 40, 32], "ins_width": 64,
                              "width": [24, 32, 48, 96, 160]})
    assert kw == {"instance_stride": 4, "dec": (80, 56, 40, 32), "width": (24, 32, 48, 96, 160), "ins_width": 64,
                  "encoder": None}
    assert count_parameters(build_model(4, seed=0, **kw)) > count_parameters(build_model(4, seed=0)) + 200_000
