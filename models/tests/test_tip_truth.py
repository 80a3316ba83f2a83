"""The tip truth rule: seen tips count, the whorl's furled leaves count once."""

import pytest

from phyllo_train.tip_truth import MAX_TIP_GAP, person_count, person_tips, tip_targets


def row(tips, gaps, furl=None):
    r = {"leaf_tips": tips, "leaf_tip_gaps": gaps}
    if furl is not None:
        r["leaf_furl"] = furl
    return r


def test_open_leaves_with_seen_tips_count_hidden_ones_do_not():
    r = row({"1": [10, 90], "2": [40, 60], "3": [70, 50]}, {"1": 1.0, "2": MAX_TIP_GAP + 0.5, "3": 3.0},
            {"1": 0.0, "2": 0.0, "3": 0.2})
    assert sorted(person_tips(r)) == ["1", "3"]
    assert person_count(r) == 2


def test_the_whorls_furled_leaves_are_one_point_the_highest_tip():
    r = row({"1": [10, 90], "2": [50, 30], "3": [52, 12], "4": [51, 20]}, {k: 1.0 for k in "1234"},
            {"1": 0.0, "2": 0.9, "3": 1.0, "4": 0.6})
    tips = person_tips(r)
    assert sorted(tips) == ["1", "3"], "leaf 3's tip is the highest of the whorl"
    assert tips["3"] == [52, 12]


def test_a_whorl_whose_tips_are_all_hidden_adds_nothing():
    r = row({"1": [10, 90], "2": [50, 30]}, {"1": 1.0, "2": 40.0}, {"1": 0.0, "2": 1.0})
    assert person_count(r) == 1


def test_older_manifests_without_furl_count_every_seen_tip():
    r = row({"1": [1, 2], "2": [3, 4]}, {"1": 0.5, "2": 0.5})
    assert person_count(r) == 2


def test_visible_rule_keeps_every_tip_unless_a_gap_is_given():
    r = row({"1": [1, 2], "2": [3, 4]}, {"1": 0.5, "2": 30.0}, {"1": 1.0, "2": 1.0})
    assert sorted(tip_targets(r, "visible", None)) == ["1", "2"]
    assert sorted(tip_targets(r, "visible", 12.0)) == ["1"]
    assert sorted(tip_targets(r, "person", None)) == ["1"]
    with pytest.raises(ValueError, match="unknown tip rule"):
        tip_targets(r, "centres", None)
