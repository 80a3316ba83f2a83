"""A few training steps, resume, and export of the trained checkpoint."""

import json

import onnx

from phyllo_train import export, train


def test_train_resume_export(tiny_dataset, tmp_path, contract):
    run = tmp_path / "run"
    common = ["--data", str(tiny_dataset), "--out", str(run), "--crop", "64", "--batch", "2", "--workers", "0",
              "--val-limit", "1", "--val-every", "2", "--log-every", "1", "--warmup", "1"]
    assert train.main(common + ["--steps", "2"]) == 0
    assert (run / "last.pt").exists() and (run / "best.pt").exists()
    assert train.main(common + ["--steps", "3"]) == 0  # resumes at step 2
    steps = [json.loads(line)["step"] for line in (run / "log.jsonl").read_text().splitlines()]
    assert max(steps) == 3 and steps.count(1) == 1
    out = tmp_path / "trained.onnx"
    assert export.main(["--checkpoint", str(run / "last.pt"), "--out", str(out), "--check-size", "64"]) == 0
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert meta["phyllo.trained"] == "true"
    assert "4 train" in meta["phyllo.training_data"]
