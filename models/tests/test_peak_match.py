"""Peak agreement between two heatmaps, and the head-swap helpers."""

import pytest
import torch

from phyllo_train import head_swap, peak_match
from phyllo_train.postprocess import count_agreement


def test_peaks_match_within_the_radius_only():
    ref = torch.tensor([[10, 10], [30, 30]])
    other = torch.tensor([[12, 9], [30, 34], [50, 50]])
    assert peak_match.matched(ref, other, 2) == 1  # (12, 9) is 2 px from (10, 10); (30, 34) is 4 px away
    assert peak_match.matched(other, ref, 2) == 1
    assert peak_match.matched(ref, other[:0], 2) == 0


def test_near_mask_covers_a_square_round_each_peak():
    mask = peak_match.near_mask(torch.tensor([[5, 5]]), (20, 20), 2)
    assert mask.sum() == 25 and mask[3, 7] and not mask[2, 5]
    assert not peak_match.near_mask(torch.zeros((0, 2), dtype=torch.long), (8, 8), 2).any()


def test_head_swap_reads_threshold_specs_and_scores_errors():
    path, thr = head_swap.parse_spec("runs/x:y/last.pt:0.15")
    assert str(path) == "runs/x:y/last.pt" and thr == 0.15
    with pytest.raises(SystemExit):
        head_swap.parse_spec("last.pt")
    exact, within1, rmse, bias = count_agreement([0, 1, -2, 0])
    assert (exact, within1, bias) == (0.5, 0.75, -0.25)
    assert rmse == pytest.approx((5 / 4) ** 0.5)
