"""val_losses: training losses of checkpoints on one split, one Markdown row each."""

import math

import torch

from phyllo_train.experiments import val_losses
from phyllo_train.model import build_model


def _checkpoint(path, contract, seed):
    state = build_model(contract.num_classes, seed=seed).state_dict()
    torch.save({"model": state, "raw_model": state, "ema": None, "step": 0, "args": {"instance_stride": 4},
                "training_data": "fixture"}, path)


def _rows(out: str) -> dict[str, list[float]]:
    rows = {}
    for line in out.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| ") and cells[0].endswith(".pt"):
            rows[cells[0]] = [float(c) for c in cells[1:]]
    return rows


def test_each_checkpoint_gets_its_losses_and_the_same_weights_the_same_ones(tmp_path, contract, tiny_dataset, capsys):
    a, b = tmp_path / "a.pt", tmp_path / "b.pt"
    _checkpoint(a, contract, seed=1)
    _checkpoint(b, contract, seed=2)
    args = ["--data", str(tiny_dataset), "--split", "val", "--limit", "2", "--batch", "1", "--threads", "1"]
    assert val_losses.main(args + [str(a), str(b), str(a)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("2 images of ")
    assert "| checkpoint | loss | sem | center | offset |" in out
    rows = _rows(out)
    assert set(rows) == {str(a), str(b)} and all(len(r) == 4 for r in rows.values())
    assert all(math.isfinite(v) and v > 0 for r in rows.values() for v in r)
    # Without augmentation a checkpoint's losses are its own: other weights, other losses.
    assert rows[str(a)] != rows[str(b)]
    assert out.count(f"| {a} |") == 2 and len({line for line in out.splitlines() if line.startswith(f"| {a} |")}) == 1


def test_the_focal_column_comes_with_its_weight(tmp_path, contract, tiny_dataset, capsys):
    a = tmp_path / "a.pt"
    _checkpoint(a, contract, seed=1)
    assert val_losses.main(["--data", str(tiny_dataset), "--split", "val", "--limit", "1", "--batch", "1",
                            "--center-focal", "1.0", str(a)]) == 0
    out = capsys.readouterr().out
    assert "| checkpoint | loss | sem | center | offset | focal |" in out
    assert len(_rows(out)[str(a)]) == 5
