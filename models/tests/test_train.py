"""A few training steps, resume, and export of the trained checkpoint."""

import json

import numpy as np
import onnx
import pytest
import torch

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


def test_stride2_instance_branch_from_stride4_checkpoint(tiny_dataset, tmp_path, contract):
    # A stride-4 run, then a stride-2 run initialised from it with a smaller centre sigma.
    base = tmp_path / "base"
    common = ["--data", str(tiny_dataset), "--crop", "64", "--batch", "2", "--workers", "0",
              "--val-limit", "0", "--log-every", "1", "--warmup", "1", "--steps", "1"]
    assert train.main(common + ["--out", str(base)]) == 0
    s2 = tmp_path / "s2"
    assert train.main(common + ["--out", str(s2), "--init", str(base / "last.pt"), "--instance-stride", "2",
                                "--center-sigma", "2.5"]) == 0
    out = tmp_path / "s2.onnx"
    assert export.main(["--checkpoint", str(s2 / "last.pt"), "--out", str(out), "--check-size", "64"]) == 0
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert "centre sigma 2.5" in meta["phyllo.training_data"]


def test_frozen_batchnorm_trains_the_eval_function(tiny_dataset, tmp_path, contract):
    import torch

    from phyllo_train.model import build_model

    model = build_model(contract.num_classes, seed=3)
    x = torch.randn(2, 3, 64, 64)
    train.set_train_mode(model, freeze_bn=True)
    with torch.no_grad():
        frozen = model(x)[1]
    model.eval()
    with torch.no_grad():
        want = model(x)[1]
    torch.testing.assert_close(frozen, want)
    # Without the freeze, training mode normalises by the batch: another function.
    train.set_train_mode(model, freeze_bn=False)
    with torch.no_grad():
        assert not torch.allclose(model(x)[1], want)

    base = tmp_path / "base"
    common = ["--data", str(tiny_dataset), "--crop", "64", "--batch", "2", "--workers", "0",
              "--val-limit", "1", "--val-every", "1", "--log-every", "1", "--warmup", "1", "--steps", "2"]
    assert train.main(common + ["--out", str(base)]) == 0
    run = tmp_path / "frozen"
    assert train.main(common + ["--out", str(run), "--init", str(base / "last.pt"), "--freeze-bn",
                                "--small-center-weight", "4", "--zoom-height", "320", "--keep-every", "1"]) == 0
    before = torch.load(base / "last.pt", weights_only=False)["raw_model"]
    after = torch.load(run / "last.pt", weights_only=False)
    stats = [k for k in before if k.endswith("running_mean") or k.endswith("running_var")]
    assert stats and all(torch.equal(before[k], after["raw_model"][k]) for k in stats)
    assert (run / "step-000001.pt").exists() and (run / "step-000002.pt").exists()
    note = after["training_data"]
    assert "BatchNorm statistics frozen" in note and "small-instance centre weight 4" in note
    assert "training zoom height 320" in note


def test_crowded_centre_targets_train_and_say_so(tiny_dataset, tmp_path):
    run = tmp_path / "crowd"
    common = ["--data", str(tiny_dataset), "--out", str(run), "--crop", "64", "--batch", "2", "--workers", "0",
              "--val-limit", "0", "--log-every", "1", "--warmup", "1", "--steps", "1"]
    with pytest.raises(SystemExit, match="--center-sigma-min must be positive"):
        train.main(common + ["--center-sigma-min", "0"])
    assert train.main(common + ["--center-sigma-min", "2"]) == 0
    out = tmp_path / "crowd.onnx"
    assert export.main(["--checkpoint", str(run / "last.pt"), "--out", str(out), "--check-size", "64"]) == 0
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert "crowded centres' sigma down to 2 output px" in meta["phyllo.training_data"]


def test_two_processes_train_what_one_process_trains(tiny_dataset, tmp_path):
    """--procs 2 with a batch of 1 each takes the same steps as one process with a batch of 2:
    the same samples, gradients averaged (BatchNorm statistics frozen, so that a slice of
    one normalises as the pair would; plain SGD, so that equal gradients mean equal weights; no
    offset loss, which each process normalises by its own slice's leaf pixels)."""
    common = ["--data", str(tiny_dataset), "--crop", "64", "--workers", "0", "--val-limit", "0",
              "--log-every", "1", "--warmup", "1", "--steps", "3", "--threads", "1", "--freeze-bn",
              "--optimizer", "sgd", "--momentum", "0", "--lr", "0.05", "--ema", "0", "--top-k", "1",
              "--offset-weight", "0"]
    assert train.main(common + ["--out", str(tmp_path / "one"), "--batch", "2"]) == 0
    assert train.main(common + ["--out", str(tmp_path / "two"), "--batch", "1", "--procs", "2"]) == 0
    one = torch.load(tmp_path / "one" / "last.pt", weights_only=False)
    two = torch.load(tmp_path / "two" / "last.pt", weights_only=False)
    assert one["step"] == two["step"] == 3
    for k, v in one["raw_model"].items():
        if v.is_floating_point():
            torch.testing.assert_close(two["raw_model"][k], v, rtol=1e-4, atol=1e-5, msg=k)
    assert float(one["raw_model"]["sem_head.1.bias"].abs().sum()) > 0
    rows = [json.loads(line) for line in (tmp_path / "two" / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in rows] == [1, 2, 3]  # rank 0 alone writes the log
    with pytest.raises(SystemExit, match="--procs must be at least 1"):
        train.main(common + ["--out", str(tmp_path / "bad"), "--procs", "0"])
    missing = tmp_path / "no-such-set"
    with pytest.raises(SystemExit, match="failed: .*no-such-set"):
        train.main(["--data", str(missing), "--out", str(tmp_path / "bad"), "--procs", "2", "--threads", "1"])


def test_sgd_with_centre_focal_loss_trains_and_says_so(tiny_dataset, tmp_path, contract):
    run = tmp_path / "sgd"
    assert train.main(["--data", str(tiny_dataset), "--out", str(run), "--crop", "64", "--batch", "2",
                       "--workers", "0", "--val-limit", "1", "--val-every", "2", "--log-every", "1",
                       "--warmup", "1", "--steps", "2", "--optimizer", "sgd", "--lr", "1e-3",
                       "--center-focal", "0.5"]) == 0
    rows = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    assert all(r["grad_norm"] > 0 and r["focal"] > 0 for r in rows if "grad_norm" in r)
    assert any("val_focal" in r for r in rows)
    out = tmp_path / "sgd.onnx"
    assert export.main(["--checkpoint", str(run / "last.pt"), "--out", str(out), "--check-size", "64"]) == 0
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert "centre focal loss weight 0.5" in meta["phyllo.training_data"]
    assert "SGD momentum 0.9" in meta["phyllo.training_data"]


def test_bf16_autocast_trains_exports_float32_and_says_so(tiny_dataset, tmp_path, contract):
    run = tmp_path / "bf16"
    assert train.main(["--data", str(tiny_dataset), "--out", str(run), "--crop", "64", "--batch", "2",
                       "--workers", "0", "--val-limit", "1", "--val-every", "2", "--log-every", "1",
                       "--warmup", "1", "--steps", "2", "--bf16"]) == 0
    rows = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    assert all(np.isfinite(r["loss"]) and r["grad_norm"] > 0 for r in rows if "grad_norm" in r)
    ck = torch.load(run / "last.pt", weights_only=False)
    assert all(v.dtype != torch.bfloat16 for v in ck["raw_model"].values()), "weights stay float32"
    out = tmp_path / "bf16.onnx"
    assert export.main(["--checkpoint", str(run / "last.pt"), "--out", str(out), "--check-size", "64"]) == 0
    meta = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert "bfloat16 autocast" in meta["phyllo.training_data"]


def test_train_speed_prints_its_table(tiny_dataset, capsys):
    from phyllo_train.experiments import train_speed
    train_speed.main(["--data", str(tiny_dataset), "--crop", "64", "--batch", "2", "--threads", "1",
                      "--samples", "2", "--steps", "1"])
    out = capsys.readouterr().out
    assert "| data pipeline, one process" in out
    assert "| data pipeline without photometric ops" in out and "| photometric ops batched" in out
    assert "| the same, images decoded once beforehand" in out
    assert "| optimiser step, float32 |" in out and "| 1.00 |" in out
    assert "| optimiser step, bfloat16 autocast |" in out


def test_wall_clock_budget_drives_the_schedule_and_ends_the_run(tiny_dataset, tmp_path):
    # The schedule follows whichever of steps and time is further along.
    assert train.schedule_step(10, 1000, 30.0, None) == 10
    assert train.schedule_step(10, 1000, 30.0, 60.0) == 500
    assert train.schedule_step(900, 1000, 30.0, 60.0) == 900
    assert train.schedule_step(10, 1000, 90.0, 60.0) == 1000
    run = tmp_path / "timed"
    args = ["--data", str(tiny_dataset), "--out", str(run), "--crop", "64", "--batch", "2", "--workers", "0",
            "--val-limit", "0", "--log-every", "1", "--warmup", "1", "--steps", "100000", "--minutes", "0.001"]
    assert train.main(args) == 0
    ck = torch.load(run / "last.pt", map_location="cpu", weights_only=False)
    assert 1 <= ck["step"] < 100000  # ended by the 60 ms budget, not the step count


def test_cpu_bf16_support_is_read_from_the_cpu_flags():
    amd = "processor\t: 0\nflags\t\t: fpu sse2 avx2 fma\n"
    sapphire = "processor\t: 0\nflags\t\t: fpu avx2 avx512f avx512_bf16 amx_bf16\n"
    assert train.cpu_has_bf16(amd) is False
    assert train.cpu_has_bf16(sapphire) is True
    assert train.cpu_has_bf16("no flags line here") is None


def test_a_paused_schedule_goes_on_from_its_packed_resume_point(tiny_dataset, tmp_path):
    """--stop-after pauses without bending the schedule (resumed, the run is the uninterrupted one
    exactly); the packed resume point keeps weights exactly and the moments to bfloat16."""
    from phyllo_train.tools import resume_state

    def common(out):
        return ["--data", str(tiny_dataset), "--out", str(out), "--crop", "64", "--batch", "2", "--workers", "0",
                "--val-limit", "0", "--log-every", "1", "--warmup", "2", "--steps", "4", "--seed", "5"]

    def lrs(run):
        return [json.loads(line).get("lr") for line in (run / "log.jsonl").read_text().splitlines()]

    straight = tmp_path / "straight"
    assert train.main(common(straight)) == 0
    paused = tmp_path / "paused"
    assert train.main(common(paused) + ["--stop-after", "1e-9"]) == 0
    first = torch.load(paused / "last.pt", weights_only=False)
    assert first["step"] == 1 and not (paused / "best.pt").exists()

    packed = tmp_path / "resume.pt"
    assert resume_state.main(["pack", str(paused / "last.pt"), "--out", str(packed)]) == 0
    assert packed.stat().st_size < (paused / "last.pt").stat().st_size
    back = resume_state.unpack(torch.load(packed, weights_only=False))
    for part in ("raw_model", "model"):
        for k, v in first[part].items():
            assert torch.equal(back[part][k], v), (part, k)
    for k, st in first["optimizer"]["state"].items():
        for n in ("exp_avg", "exp_avg_sq"):
            assert back["optimizer"]["state"][k][n].dtype == torch.float32
            torch.testing.assert_close(back["optimizer"]["state"][k][n], st[n], rtol=1 / 128, atol=0)

    assert train.main(common(paused)) == 0  # resumes from the unpacked-free last.pt
    a = torch.load(straight / "last.pt", weights_only=False)
    b = torch.load(paused / "last.pt", weights_only=False)
    assert a["step"] == b["step"] == 4
    for k, v in a["raw_model"].items():
        assert torch.equal(b["raw_model"][k], v), k
    assert lrs(paused) == lrs(straight) and len(lrs(straight)) == 4
