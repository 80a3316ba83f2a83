"""The NMS floor: leaves a max-pool window hides even under a perfect heatmap."""

import numpy as np

from phyllo_train.experiments.nms_floor import leaf_centres, lost_to_window


def test_close_small_leaf_is_lost_to_a_wide_window_only(contract):
    div = contract.label_divisor
    lab = np.zeros((64, 64), np.int32)
    lab[10:30, 10:30] = contract.leaf * div + 1   # 400 px, centre (19.5, 19.5)
    lab[20:26, 32:38] = contract.leaf * div + 2   # 36 px, centre (22.5, 34.5)
    lab[50:60, 50:60] = 2 * div                   # stem: not a leaf
    centres, areas = leaf_centres(lab, contract)
    np.testing.assert_allclose(centres, [[19.5, 19.5], [22.5, 34.5]])
    np.testing.assert_array_equal(areas, [400, 36])
    out = centres / 2  # 7.5 output px apart in x
    assert lost_to_window(out, areas, 7) == 0
    assert lost_to_window(out, areas, 15) == 0  # half-width 7 < 7.5
    assert lost_to_window(out, areas, 17) == 1


def test_no_leaves():
    c, a = leaf_centres(np.zeros((8, 8), np.int32), type("C", (), {"label_divisor": 1000, "leaf": 1})())
    assert c.shape == (0, 2) and lost_to_window(c, a, 7) == 0
