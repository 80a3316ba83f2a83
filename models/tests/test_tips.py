"""The leaf-tip head: points through augmentation, tip targets, the loss, training and export."""

import json
import shutil
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
import torch
from PIL import Image

from phyllo_train.augment import AugmentConfig, augment
from phyllo_train.dataset import PanopticDataset
from phyllo_train.export import export_onnx
from phyllo_train.tools.from_onnx import main as from_onnx_main
from phyllo_train.targets import tip_heatmap
from phyllo_train.model import TipHead, TipNet
from phyllo_train.tools.tips import count_peaks, load_base, main, tip_focal_loss

MODELS = Path(__file__).resolve().parent.parent


def _marked(h=300, w=360):
    """A label with one-pixel 'tips' (instance ids 1..4) and their (x, y) points at the pixel centres."""
    lab = np.zeros((h, w), np.int32)
    lab[120:200, 150:160] = 2000  # a stem, so the plant has a body to zoom and crop around
    pts = np.array([[40.5, 30.5], [300.5, 250.5], [170.5, 100.5], [10.5, 280.5]])
    for k, (x, y) in enumerate(pts, 1):
        lab[int(y), int(x)] = 1000 + k
    return lab, pts


def test_points_move_with_the_label_through_every_geometric_op():
    """Scale, flip, top-view rotations, padding and zoom: each point stays on its labelled pixel."""
    lab, pts = _marked()
    img = Image.fromarray(np.zeros((*lab.shape, 3), np.uint8))
    for seed in range(12):
        cfg = AugmentConfig.none(crop=512)  # larger than the label: padding too
        cfg.hflip, cfg.rot90_top = 0.5, True
        # Integer scales keep every one-pixel mark (nearest neighbour) so it can be found again.
        cfg.scale = (2.0, 2.0) if seed % 2 else (1.0, 1.0)
        _, out, _, moved = augment(img, lab, cfg, np.random.default_rng(seed), top_view=seed % 3 == 0,
                                   zoom=(0, 1.0))
        for k, (x, y) in enumerate(moved, 1):
            assert out[int(np.floor(y)), int(np.floor(x))] == 1000 + k, (seed, k, x, y)


def test_points_follow_the_small_plant_zoom():
    lab, pts = _marked()
    img = Image.fromarray(np.zeros((*lab.shape, 3), np.uint8))
    _, out, _, moved = augment(img, lab, AugmentConfig.none(crop=256), np.random.default_rng(0),
                               zoom=(600, 2.0))
    assert out.shape[0] > lab.shape[0]  # enlarged
    for k, (x, y) in enumerate(moved, 1):
        assert out[int(np.floor(y)), int(np.floor(x))] == 1000 + k


def test_tip_heatmap_peaks_at_the_tip_in_output_pixels():
    # Input pixel (x=41, y=21) lies in output pixel (20, 10) at stride 2.
    heat = tip_heatmap(np.array([[41.5, 21.5], [500.0, 500.0]]), (0, 0, 64, 64), stride=2, sigma=1.5)
    assert heat.shape == (1, 32, 32)
    assert heat[0, 10, 20] == 1.0 and np.argmax(heat[0]) == 10 * 32 + 20
    assert (heat == 1.0).sum() == 1  # the far tip leaves nothing in this crop
    # A window moves the tip with it.
    moved = tip_heatmap(np.array([[41.5, 21.5]]), (8, 16, 64, 64), stride=2, sigma=1.5)
    assert moved[0, 6, 12] == 1.0


def test_focal_loss_rewards_sharp_peaks():
    target = torch.from_numpy(tip_heatmap(np.array([[33.0, 33.0]]), (0, 0, 64, 64), 2, 1.5))[None]
    good = torch.where(target >= 1.0, torch.tensor(6.0), torch.tensor(-6.0))
    blurred = torch.logit(target.clamp(0.02, 0.98))
    silent = torch.full_like(target, -6.0)
    lg, lb, ls = (float(tip_focal_loss(v, target)) for v in (good, blurred, silent))
    assert lg < lb and lg < ls
    assert count_peaks(torch.sigmoid(good), 0.3, 5).tolist() == [1]
    assert count_peaks(torch.sigmoid(silent), 0.3, 5).tolist() == [0]


def _with_tips(fixture: Path, tmp: Path) -> Path:
    """A copy of the fixture whose manifest has leaf_tips: each leaf's rightmost-lowest pixel."""
    root = tmp / "with-tips"
    shutil.copytree(fixture, root)
    rows = [json.loads(line) for line in (root / "manifest.jsonl").read_text().splitlines()]
    for r in rows:
        lab = np.array(Image.open(root / r["label"]), np.int64)
        tips = {}
        for v in np.unique(lab[(lab // 1000 == 1) & (lab % 1000 > 0)]):
            ys, xs = np.nonzero(lab == v)
            k = np.argmax(xs * 10000 + ys)
            tips[str(v % 1000)] = [float(xs[k]) + 0.5, float(ys[k]) + 0.5]
        r["leaf_tips"] = tips
    (root / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return root


def test_dataset_gives_one_tip_peak_per_visible_leaf(tmp_path, tiny_dataset, contract):
    root = _with_tips(tiny_dataset, tmp_path)
    ds = PanopticDataset(root, "val", AugmentConfig.none(), contract, with_tips=True)
    x, t = ds[0]
    row = ds.rows[0]
    assert len(row["leaf_tips"]) == row["visible_leaf_count"]
    assert t["tip"].shape == (1, x.shape[1] // contract.stride, x.shape[2] // contract.stride)
    # The same sample's geometry (the dataset seeds it with (seed, epoch, index)): the contract's
    # zoom enlarges this small plant, so only the tips inside the crop give peaks.
    img = Image.open(root / row["image"]).convert("RGB")
    lab = np.array(Image.open(root / row["label"]), np.int32)
    pts = np.array(list(row["leaf_tips"].values()))
    _, _, (y0, x0, h, w), moved = augment(img, lab, AugmentConfig(**{**AugmentConfig.none().__dict__, "crop": 512}),
                                          np.random.default_rng([0, 0, 0]), label_divisor=1000,
                                          zoom=(contract.zoom_plant_height, contract.max_zoom), points=pts)
    inside = ((moved[:, 0] >= x0) & (moved[:, 0] < x0 + w) & (moved[:, 1] >= y0) & (moved[:, 1] < y0 + h)).sum()
    assert inside >= 1
    assert int((t["tip"] >= 1.0).sum()) == inside


def test_dataset_without_tips_is_refused_when_tips_are_asked_for(tiny_dataset, contract):
    try:
        PanopticDataset(tiny_dataset, "train", contract=contract, with_tips=True)
    except ValueError as e:
        assert "leaf_tips" in str(e)
    else:
        raise AssertionError("a manifest without leaf_tips was accepted")


def test_training_then_export_keeps_the_base_outputs_exactly(tmp_path, tiny_dataset, contract):
    """Two training steps on frozen features, then the 4-output export: the first three outputs
    are the base model's, bit for bit up to ONNX Runtime's float noise, and the tip map is in [0, 1]."""
    root = _with_tips(tiny_dataset, tmp_path)
    run = tmp_path / "run"
    assert main(["train", "--base", str(MODELS / "phyllo.onnx"), "--data", str(root), "--out", str(run),
                 "--steps", "2", "--batch", "2", "--crop", "128", "--workers", "0", "--ckpt-every", "2",
                 "--val-images", "1"]) == 0
    log = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    assert log[-1]["step"] == 2 and np.isfinite(log[-1]["val_loss"])
    out = tmp_path / "tips.onnx"
    assert main(["export", "--base", str(MODELS / "phyllo.onnx"), "--head", str(run / "last.pt"),
                 "--out", str(out), "--check-size", "128"]) == 0
    x = np.random.default_rng(0).standard_normal((1, 3, 128, 160), dtype=np.float32)
    got = ort.InferenceSession(str(out)).run(None, {contract.input_name: x})
    base = ort.InferenceSession(str(MODELS / "phyllo.onnx")).run(None, {contract.input_name: x})[:3]
    assert len(got) == 4
    for g, b in zip(got, base):
        np.testing.assert_allclose(g, b, atol=2e-4)
    assert got[3].shape == (1, 1, 64, 80) and 0.0 <= got[3].min() and got[3].max() <= 1.0
    # A tip model is a base for the next tip head, and from_onnx rebuilds its base network.
    t = torch.from_numpy(x)
    with torch.no_grad():
        for a, b in zip(load_base(out, contract)(t), load_base(MODELS / "phyllo.onnx", contract)(t)):
            assert float((a - b).abs().max()) < 1e-4
    assert from_onnx_main([str(out), "--out", str(tmp_path / "rebuilt.pt"), "--head-out", str(tmp_path / "head.pt")]) == 0
    assert set(torch.load(tmp_path / "rebuilt.pt", weights_only=False)["model"]) == set(
        load_base(MODELS / "phyllo.onnx", contract).state_dict())
    # --head-out: the tip head as a `tips train` checkpoint, computing the exported tip map.
    head_ck = torch.load(tmp_path / "head.pt", weights_only=False)
    assert head_ck["width"] == 32 and head_ck["step"] == 2
    head = TipHead(width=head_ck["width"])
    head.load_state_dict(head_ck["head"])
    with torch.no_grad():
        tip = TipNet(load_base(out, contract), head).eval()(t)[3].numpy()
    np.testing.assert_allclose(tip, got[3], atol=1e-4)
    assert from_onnx_main([str(MODELS / "phyllo.onnx"), "--out", str(tmp_path / "r2.pt"),
                           "--head-out", str(tmp_path / "none.pt")]) == 2


def test_frozen_base_is_the_onnx_model(contract):
    base = load_base(MODELS / "phyllo.onnx", contract)
    net = TipNet(base, TipHead()).eval()
    x = torch.randn(1, 3, 64, 64)
    with torch.no_grad():
        four, three = net(x), base(x)
    for a, b in zip(four[:3], three):
        assert torch.equal(a, b)


def test_export_of_a_three_output_model_is_unchanged(tmp_path, contract):
    """export_onnx without output_names still writes the contract's three outputs."""
    base = load_base(MODELS / "phyllo.onnx", contract)
    p = export_onnx(base, tmp_path / "m.onnx", contract, model_name="t", trained=True, training_data="t")
    assert [o.name for o in ort.InferenceSession(str(p)).get_outputs()] == list(contract.output_names)


def test_tip_matching_is_one_to_one_nearest_first(tmp_path):
    from phyllo_train.experiments.tip_match import main as match_main, match_tips

    marked = np.array([[0.0, 0.0], [10.0, 0.0], [100.0, 100.0]])
    predicted = np.array([[4.0, 0.0], [11.0, 0.0], [300.0, 300.0]])
    # (4,0) is nearer to (0,0)... but (11,0)-(10,0) is the nearest pair and goes first; both marked tips match.
    assert match_tips(marked, predicted, 5.0) == (2, 1, 1)
    # One predicted tip cannot serve two marked ones.
    assert match_tips(marked[:2], predicted[:1], 20.0) == (1, 1, 0)
    assert match_tips(marked, np.zeros((0, 2)), 5.0) == (0, 3, 0)
    csv_path = tmp_path / "tips.csv"
    csv_path.write_text('file,leaf_count,tips_xy\na.jpg,2,"[[0, 0], [10, 0]]"\n')
    counts = tmp_path / "counts.jsonl"
    counts.write_text(json.dumps({"file": "/x/a.jpg", "leaf_count": 2, "tips": [[1, 0, 0.9], [50, 0, 0.5]]}) + "\n"
                      + json.dumps({"file": "/x/b.jpg", "error": "corrupt"}) + "\n")
    assert match_main(["--tips", str(csv_path), "--counts", str(counts), "--radius", "5"]) == 0


def test_tip_matching_reads_a_datasets_leaf_tips(tmp_path, tiny_dataset):
    from phyllo_train.experiments.tip_match import main as match_main, read_dataset_tips

    root = _with_tips(tiny_dataset, tmp_path)
    tips = read_dataset_tips(root, "val")
    name, pts = next(iter(tips.items()))
    assert len(pts) >= 1
    counts = tmp_path / "counts.jsonl"
    counts.write_text(json.dumps({"file": f"/x/{name}", "tips": [[*pts[0], 0.9]]}) + "\n")
    assert match_main(["--dataset", str(root), "--counts", str(counts), "--radius", "1"]) == 0


def test_cached_features_are_the_live_ones_and_train_a_wider_head(tmp_path, tiny_dataset, contract):
    """`tips cache` stores exactly what the live loader feeds the head (to float16), it resumes, and a
    wider head trains on it and exports."""
    from phyllo_train.tools.tip_cache import FeatureCache

    root = _with_tips(tiny_dataset, tmp_path)
    cache = tmp_path / "cache"
    args = ["cache", "--base", str(MODELS / "phyllo.onnx"), "--data", str(root), "--out", str(cache),
            "--crop", "128", "--passes", "2", "--batch", "2", "--workers", "0"]
    assert main(args) == 0
    meta = json.loads((cache / "meta.json").read_text())
    n = len(PanopticDataset(root, "train", contract=contract))
    assert meta["done"] == meta["total"] == 2 * n
    # Pass 1, image 0: the dataset's augmentation at epoch 1, through the frozen base.
    ds = PanopticDataset(root, "train", AugmentConfig(crop=128), contract, with_tips=True)
    ds.set_epoch(1)
    x, t = ds[0]
    with torch.no_grad():
        f2, d4 = load_base(MODELS / "phyllo.onnx", contract).features(x[None])
    full = FeatureCache(cache)
    c2, c4, ct = full[n]
    np.testing.assert_allclose(c2.numpy(), f2[0].numpy(), atol=2e-2, rtol=1e-2)
    np.testing.assert_allclose(c4.numpy(), d4[0].numpy(), atol=2e-2, rtol=1e-2)
    np.testing.assert_allclose(ct.numpy(), t["tip"].numpy(), atol=1e-3)
    # A finished cache is not rewritten; a different recipe on the same directory is refused.
    assert main(args) == 0
    try:
        main(args[:-6] + ["--crop", "96", "--passes", "2", "--batch", "2", "--workers", "0"])
    except ValueError as e:
        assert "cache was built with" in str(e)
    else:
        raise AssertionError("a cache of another crop size was reused")
    sub = FeatureCache(cache, sub=64)
    a2, a4, at = sub[0]
    assert a2.shape[1:] == (32, 32) and a4.shape[1:] == (16, 16) and at.shape[1:] == (32, 32)
    run = tmp_path / "run"
    assert main(["train", "--base", str(MODELS / "phyllo.onnx"), "--data", str(root), "--cache", str(cache),
                 "--out", str(run), "--steps", "2", "--batch", "2", "--crop", "128", "--workers", "0",
                 "--ckpt-every", "2", "--val-images", "1", "--width", "16", "--sub-crop", "64"]) == 0
    assert torch.load(run / "last.pt", weights_only=False)["width"] == 16
    out = tmp_path / "tips16.onnx"
    assert main(["export", "--base", str(MODELS / "phyllo.onnx"), "--head", str(run / "last.pt"),
                 "--out", str(out), "--check-size", "128"]) == 0
    assert len(ort.InferenceSession(str(out)).get_outputs()) == 4


def test_count_rules_score_split_variants_from_one_run(tmp_path):
    from phyllo_train.experiments.count_rules import Rule, count, main as rules_main

    leaf = lambda i, area: {"id": i, "class_name": "leaf", "area": area}  # noqa: E731
    rec = {"file": "/x/a.png", "instances": [leaf(1, 50), leaf(2, 5000), {"id": 3, "class_name": "panicle", "area": 9}],
           "tips": [[0, 0, 0.9], [1, 0, 0.6], [2, 0, 0.95], [3, 0, 0.9], [4, 0, 0.9], [5, 0, 0.9], [6, 0, 0.99]],
           "tip_instances": [1, 1, 2, 2, 2, None, 3]}
    assert count(rec, Rule("centres")) == 2
    assert count(rec, Rule("split", 0.5)) == 2 + 3          # every tip on a leaf counts; the panicle's does not
    assert count(rec, Rule("split", 0.7)) == 1 + 3          # 0.6 falls below the threshold
    assert count(rec, Rule("split", 0.5, cap=2)) == 2 + 2
    assert count(rec, Rule("split", 0.5, max_area=100)) == 2 + 1   # the large leaf may not split
    assert count(rec, Rule("split", 0.99)) == 2              # no tips: each leaf still counts once
    assert count(rec, Rule("split", 0.5, min_gap=1.5)) == 1 + 2   # (1,0) is 1 px from (0,0), (3,0) from (2,0)
    counts = tmp_path / "c.jsonl"
    counts.write_text(json.dumps(rec) + "\n" + json.dumps({"file": "/x/b.png", "error": "corrupt"}) + "\n")
    truth = tmp_path / "t.csv"
    truth.write_text("file,leaf_count\na.png,4\nb.png,3\n")
    assert rules_main(["--counts", str(counts), "--truth", str(truth), "--thresholds", "0.5", "--caps", "2"]) == 0


def test_joint_training_trains_every_head_and_exports_four_outputs(tmp_path, tiny_dataset, contract):
    """`train --tips`: the network and a tip head together, from a plain run's checkpoint, then the
    4-output export; hidden tips (--max-tip-gap) get no target, and need leaf_tip_gaps."""
    from phyllo_train import export as export_mod
    from phyllo_train import train as train_mod

    root = _with_tips(tiny_dataset, tmp_path)
    common = ["--data", str(root), "--crop", "64", "--batch", "2", "--workers", "0", "--val-limit", "1",
              "--val-every", "1", "--log-every", "1", "--warmup", "1", "--steps", "1"]
    plain = tmp_path / "plain"
    assert train_mod.main(common + ["--out", str(plain)]) == 0
    joint = tmp_path / "joint"
    assert train_mod.main(common + ["--out", str(joint), "--tips", "--tip-width", "16",
                                    "--init", str(plain / "last.pt")]) == 0
    log = [json.loads(line) for line in (joint / "log.jsonl").read_text().splitlines()]
    assert np.isfinite(log[0]["tip"]) and np.isfinite(log[-1]["val_tip"])
    ck = torch.load(joint / "last.pt", weights_only=False)
    start = torch.load(plain / "last.pt", weights_only=False)["raw_model"]
    moved = [k for k, v in start.items() if v.is_floating_point() and not torch.equal(ck["raw_model"][f"base.{k}"], v)]
    assert moved, "the base network trained too"
    out = tmp_path / "joint.onnx"
    assert export_mod.main(["--checkpoint", str(joint / "last.pt"), "--out", str(out), "--check-size", "64"]) == 0
    assert [o.name for o in onnx.load(str(out)).graph.output] == list(contract.output_names_with_tip)

    # --max-tip-gap refuses a manifest without gaps, and drops the tips beyond it.
    try:
        train_mod.main(common + ["--out", str(tmp_path / "nogaps"), "--tips", "--max-tip-gap", "4"])
    except SystemExit as e:
        assert "leaf_tip_gaps" in str(e)
    else:
        raise AssertionError("a manifest without leaf_tip_gaps was accepted")
    rows = [json.loads(line) for line in (root / "manifest.jsonl").read_text().splitlines()]
    for r in rows:  # every tip but the first is hidden
        r["leaf_tip_gaps"] = {k: (0.0 if i == 0 else 50.0) for i, k in enumerate(r["leaf_tips"])}
    (root / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    aug = AugmentConfig.none()
    kept = PanopticDataset(root, "val", aug, contract, with_tips=True, max_tip_gap=4.0)[0][1]["tip"]
    every = PanopticDataset(root, "val", aug, contract, with_tips=True)[0][1]["tip"]
    assert int((kept >= 1.0).sum()) <= 1 < int((every >= 1.0).sum())


def test_an_untrained_head_exports_beside_the_base_outputs(tmp_path, contract):
    """`tips export --untrained-head` rebuilds the fixture models/phyllo-tips-untrained.onnx from a
    shipped model: the base outputs unchanged and a tip map near CenterNet's 0.01 prior."""
    out = tmp_path / "tips-untrained.onnx"
    assert main(["export", "--base", str(MODELS / "phyllo.onnx"), "--untrained-head", "--out", str(out),
                 "--check-size", "128"]) == 0
    x = np.random.default_rng(1).standard_normal((1, 3, 128, 128), dtype=np.float32)
    got = ort.InferenceSession(str(out)).run(None, {contract.input_name: x})
    base = ort.InferenceSession(str(MODELS / "phyllo.onnx")).run(None, {contract.input_name: x})
    for g, b in zip(got[:3], base):
        np.testing.assert_allclose(g, b, atol=2e-4)
    assert float(got[3].max()) < 0.05
