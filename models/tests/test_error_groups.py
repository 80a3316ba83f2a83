"""Count errors split by truth range, plant age and preset (phyllo_train.experiments.error_groups)."""

import json

from phyllo_train.experiments.error_groups import groups, main


def _images():
    # (file, truth, predicted): errors 0, -2, +1, -3
    return [
        {"file": "/d/images/p0_0.png", "truth": 5, "predicted": 5},
        {"file": "/d/images/p1_0.png", "truth": 14, "predicted": 12},
        {"file": "/d/images/p2_0.png", "truth": 9, "predicted": 10},
        {"file": "/d/images/p3_0.png", "truth": 8, "predicted": 5},
    ]


def _manifest():
    rows = [("p0_0", "btx623", 30.0), ("p1_0", "maize-late", 70.0), ("p2_0", "maize", 40.0),
            ("p3_0", "pawaga", 79.5)]
    return {f"images/{n}.png": {"image": f"images/{n}.png", "preset": p, "age_days": a} for n, p, a in rows}


def test_groups_split_errors_by_truth_age_and_preset():
    g = groups(_images(), [(4, 11), (13, 99)], _manifest())
    assert g["all"] == [0, -2, 1, -3]
    assert g["truth 4–11"] == [0, 1, -3]
    assert g["truth 13–99"] == [-2]
    assert g["plant 8 weeks old or younger"] == [0, 1]
    assert g["plant older than 8 weeks"] == [-2, -3]
    assert g["late maize older than 8 weeks"] == [-2]
    # Sorghum from day 62 on flowers; old maize does not.
    assert g["flowering sorghum (day 62 on)"] == [-3]


def test_main_prints_one_row_per_group(tmp_path, capsys):
    run = tmp_path / "run.json"
    run.write_text(json.dumps({"images": _images()}))
    assert main([str(run), "--truth", "4-11", "12-15"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[2] == "| all | 4 | 25.0 / 50.0 / 1.871 / -1.00 |"
    assert out[3] == "| truth 4–11 | 3 | 33.3 / 66.7 / 1.826 / -0.67 |"
    assert out[4] == "| truth 12–15 | 1 | 0.0 / 0.0 / 2.000 / -2.00 |"
    assert len(out) == 5
