"""Distillation: a teacher's centre heatmap replaces the side views' label targets, never the top views'."""

import json

import onnx
import torch

from phyllo_train import export, train
from phyllo_train.model import build_model
from phyllo_train.modes import distill


def test_teacher_replaces_side_view_targets_only(contract):
    teacher = build_model(contract.num_classes, seed=5).eval()
    xs = torch.randn(2, 3, 64, 64)
    ts = {
        "center": torch.zeros(2, 1, 32, 32),
        "offset": torch.full((2, 2, 32, 32), 3.0),
        "center_weight": torch.ones(2, 1, 32, 32),
        "top_view": torch.tensor([0.0, 1.0]),
    }
    with torch.no_grad():
        _, want_center, want_offset = teacher(xs)
    got = distill.teacher_targets(teacher, xs, ts, "center")
    torch.testing.assert_close(got["center"][0], want_center[0])
    assert torch.equal(got["center"][1], ts["center"][1])  # the top view keeps its label
    assert torch.equal(got["offset"], ts["offset"])  # centre mode leaves the offsets alone
    both = distill.teacher_targets(teacher, xs, ts, "center+offset")
    torch.testing.assert_close(both["offset"][0], want_offset[0])
    assert torch.equal(both["offset"][1], ts["offset"][1])
    assert torch.equal(both["center_weight"], ts["center_weight"])  # no peak weight asked
    peaked = distill.teacher_targets(teacher, xs, ts, "center", peak_weight=10.0)
    torch.testing.assert_close(peaked["center_weight"][0], 1 + 10 * want_center[0].clamp(0, 1))
    assert torch.equal(peaked["center_weight"][1], ts["center_weight"][1])


def test_training_with_a_teacher_loads_it_frozen_and_says_so(tiny_dataset, tmp_path, contract):
    common = ["--data", str(tiny_dataset), "--crop", "64", "--batch", "2", "--workers", "0",
              "--val-limit", "0", "--log-every", "1", "--warmup", "1", "--steps", "1"]
    assert train.main(common + ["--out", str(tmp_path / "teacher")]) == 0
    teacher_ckpt = tmp_path / "teacher" / "last.pt"
    teacher = distill.load_teacher(teacher_ckpt, contract, torch.device("cpu"))
    assert not teacher.training and not any(p.requires_grad for p in teacher.parameters())
    student = tmp_path / "student"
    assert train.main(common + ["--out", str(student), "--teacher", str(teacher_ckpt),
                                "--distill", "center+offset"]) == 0
    loss = json.loads((student / "log.jsonl").read_text().splitlines()[-1])["loss"]
    assert loss == loss and loss > 0  # finite: the teacher's targets reached the losses
    out = tmp_path / "student.onnx"
    assert export.main(["--checkpoint", str(student / "last.pt"), "--out", str(out), "--check-size", "64"]) == 0
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert "center+offset targets from teacher" in meta["phyllo.training_data"]
