"""Re-scoring eval output under the every-visible-leaf truth rule."""

import json

import numpy as np

from phyllo_train.tools.truth_rules import main, metrics, parse_per_image


def test_parse_and_metrics():
    lines = ["d/images/a.png\t0\ttrue 3\tpredicted 4\n", "noise\n", "d/images/b.png\t36\ttrue 5\tpredicted 5\n"]
    assert parse_per_image(lines) == {"d/images/a.png": (3, 4), "d/images/b.png": (5, 5)}
    m = metrics(np.array([3, 5]), np.array([4, 5]))
    assert m["exact"] == 0.5 and m["within1"] == 1.0 and m["bias"] == 0.5
    assert abs(m["rmse"] - np.sqrt(0.5)) < 1e-12


def test_main_scores_both_rules(tmp_path, capsys):
    rows = [{"image": "images/a.png", "label": "labels/a.png", "split": "val", "visible_leaf_count": 4},
            {"image": "images/b.png", "label": "labels/b.png", "split": "val", "visible_leaf_count": 6}]
    (tmp_path / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    per = tmp_path / "per.txt"
    per.write_text(f"{tmp_path}/images/a.png\t0\ttrue 3\tpredicted 4\n{tmp_path}/images/b.png\t0\ttrue 5\tpredicted 6\n")
    assert main(["--dataset", str(tmp_path), str(per)]) == 0
    out = capsys.readouterr().out
    assert "| as phyllo eval ran (--truth-min-pixels) | 2 | 0.0% | 100.0% | 1.000 | 1.000 | +1.000 |" in out
    assert "| every visible leaf | 2 | 100.0% | 100.0% | 0.000 | 0.000 | +0.000 |" in out


def test_tip_gap_rule_counts_leaves_whose_tip_is_seen(tmp_path, capsys):
    rows = [{"image": "images/a.png", "label": "labels/a.png", "split": "val", "visible_leaf_count": 3,
             "leaf_tip_gaps": {"1": 0.0, "2": 3.5, "3": 20.0}},
            {"image": "images/b.png", "label": "labels/b.png", "split": "val", "visible_leaf_count": 0}]
    (tmp_path / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    per = tmp_path / "per.txt"
    per.write_text(f"{tmp_path}/images/a.png\t0\ttrue 3\tpredicted 2\n{tmp_path}/images/b.png\t0\ttrue 0\tpredicted 0\n")
    assert main(["--dataset", str(tmp_path), str(per), "--tip-gaps", "4,30"]) == 0
    out = capsys.readouterr().out
    assert "| leaves whose tip is seen (tip gap <= 4 px) | 2 | 100.0% | 100.0% | 0.000 | 0.000 | +0.000 |" in out
    assert "| leaves whose tip is seen (tip gap <= 30 px) | 2 | 50.0% | 100.0% | 0.707 | 0.500 | -0.500 |" in out
    assert "tip gaps of 3 leaves (px)" in out and "/ 3.5 /" in out


def test_tip_gap_rule_refuses_a_manifest_without_gaps(tmp_path):
    rows = [{"image": "images/a.png", "label": "labels/a.png", "split": "val", "visible_leaf_count": 2}]
    (tmp_path / "manifest.jsonl").write_text(json.dumps(rows[0]) + "\n")
    per = tmp_path / "per.txt"
    per.write_text(f"{tmp_path}/images/a.png\t0\ttrue 2\tpredicted 2\n")
    try:
        main(["--dataset", str(tmp_path), str(per), "--tip-gaps", "4"])
    except SystemExit as e:
        assert "leaf_tip_gaps" in str(e)
    else:
        raise AssertionError("expected a clear refusal")
