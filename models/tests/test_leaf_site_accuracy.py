"""scripts/leaf_site_accuracy.py: which true leaf a leaf site lies on."""

import importlib.util
from pathlib import Path

import numpy as np

_PATH = Path(__file__).resolve().parents[2] / "scripts" / "leaf_site_accuracy.py"
_SPEC = importlib.util.spec_from_file_location("leaf_site_accuracy", _PATH)
ls = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(ls)


def row(date, living, emerged):
    return {"plant": "P", "date": date, "living_leaves": str(living), "leaves_emerged": str(emerged)}


def test_the_new_leaves_of_a_session_are_the_top_living_instances():
    truth = [row("2018-04-10", 4, 4), row("2018-04-11", 4, 4), row("2018-04-12", 5, 5),
             # Leaf 1 died and leaves 6 and 7 came out: living leaves 2..7 are instances 1..6.
             row("2018-04-13", 6, 7)]
    new = ls.true_new_instances(truth)
    assert new[("P", "2018-04-11")] == (set(), 4)
    assert new[("P", "2018-04-12")] == ({5}, 5)
    assert new[("P", "2018-04-13")] == ({5, 6}, 6)
    assert ("P", "2018-04-10") not in new


def test_a_site_is_on_the_leaf_under_its_centre_else_the_most_of_its_box():
    label = np.zeros((40, 40), dtype=np.uint16)
    label[0:20, 0:20] = 1000 + 3  # leaf 3
    label[20:40, 20:40] = 1000 + 7  # leaf 7
    label[30:40, 0:10] = 2000  # stem
    assert ls.leaf_under(label, (5.0, 5.0), [0, 0, 20, 20]) == 3
    # Centre on the background: the box decides.
    assert ls.leaf_under(label, (10.0, 30.0), [18, 18, 40, 40]) == 7
    assert ls.leaf_under(label, (5.0, 35.0), [0, 30, 10, 40]) is None
