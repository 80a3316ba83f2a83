"""The tip truth rule: seen tips count, one per visible point."""

import pytest

from phyllo_train.tip_truth import MAX_TIP_GAP, MERGE_PX, open_count, person_count, person_tips, tip_targets


def row(tips, gaps, furl=None):
    r = {"leaf_tips": tips, "leaf_tip_gaps": gaps}
    if furl is not None:
        r["leaf_furl"] = furl
    return r


def test_seen_tips_count_hidden_ones_do_not():
    r = row({"1": [10, 90], "2": [40, 60], "3": [70, 50]}, {"1": 1.0, "2": MAX_TIP_GAP + 0.5, "3": 3.0})
    assert sorted(person_tips(r)) == ["1", "3"]
    assert person_count(r) == 2


def test_furled_leaves_standing_out_count_like_any_other_and_coinciding_tips_once():
    r = row({"1": [10, 90], "2": [50, 30], "3": [52, 12], "4": [52 + MERGE_PX / 2, 12.5]},
            {k: 1.0 for k in "1234"}, {"1": 0.0, "2": 0.9, "3": 1.0, "4": 1.0})
    tips = person_tips(r)
    assert sorted(tips) == ["1", "2", "3"], "leaf 4's tip coincides with leaf 3's, the higher one"
    assert open_count(r) == 1, "expanded leaves only: the whorl's three are left out"


def test_older_manifests_without_furl_count_every_leaf_as_open():
    r = row({"1": [1, 2], "2": [30, 4]}, {"1": 0.5, "2": 0.5})
    assert person_count(r) == open_count(r) == 2


def test_visible_rule_keeps_every_tip_unless_a_gap_is_given():
    r = row({"1": [1, 2], "2": [30, 4]}, {"1": 0.5, "2": 30.0})
    assert sorted(tip_targets(r, "visible", None)) == ["1", "2"]
    assert sorted(tip_targets(r, "visible", 12.0)) == ["1"]
    assert sorted(tip_targets(r, "person", None)) == ["1"]
    with pytest.raises(ValueError, match="unknown tip rule"):
        tip_targets(r, "centres", None)
