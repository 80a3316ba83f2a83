"""Targets: semantic downsampling, centre heatmap, offsets and weights."""

import numpy as np
import torch

from phyllo_train.losses import LossWeights, panoptic_loss, semantic_topk_ce
from phyllo_train.tools.postprocess import decode, find_centers, label_leaf_count
from phyllo_train.targets import crowding_sigmas, downsample_label, make_targets, saddle_pairs, SADDLE_REACH


def test_single_leaf_centre_and_offsets(contract):
    lab = np.zeros((64, 64), np.int32)
    lab[10:20, 4:40] = 1 * contract.label_divisor + 1  # leaf, rows 10..19, cols 4..39
    lab[40:60, 30:34] = 2 * contract.label_divisor      # stem: stuff, no instance
    t = make_targets(lab, contract)
    s = contract.stride
    assert t.semantic.shape == (64 // s, 64 // s)
    assert set(np.unique(t.semantic)) == {0, 1, 2}
    # Centre of mass (14.5, 21.5) in input pixels -> ((14.5 - 0.5) / 2, (21.5 - 0.5) / 2) = (7, 10.5).
    np.testing.assert_allclose(t.centers, [[7.0, 10.5]], atol=1e-5)
    assert t.center.max() == 1.0
    peak = np.unravel_index(t.center[0].argmax(), t.center[0].shape)
    assert abs(peak[0] - 7) <= 0.5 and abs(peak[1] - 10.5) <= 0.5
    # Every leaf pixel + its offset lands on the centre; nothing else has an offset.
    ys, xs = np.nonzero(t.offset_weight[0])
    assert (t.semantic[ys, xs] == 1).all()
    np.testing.assert_allclose(ys + t.offset[0, ys, xs], 7.0, atol=1e-5)
    np.testing.assert_allclose(xs + t.offset[1, ys, xs], 10.5, atol=1e-5)
    assert (t.offset[:, t.offset_weight[0] == 0] == 0).all()
    assert (t.offset_weight[0][t.semantic == 2] == 0).all()
    # Small instance (360 px < 1024) is up-weighted in the semantic loss.
    assert (t.semantic_weight[t.semantic == 1] == 3.0).all()
    assert (t.semantic_weight[t.semantic == 0] == 1.0).all()


def test_downsample_keeps_one_pixel_leaf():
    lab = np.zeros((8, 8), np.int32)
    lab[3, :] = 1001  # a one-pixel-thin leaf on an odd row
    low = downsample_label(lab, 2)
    assert (low[1, :] == 1001).all() and low.sum() == 4 * 1001


def test_split_leaf_is_one_instance(contract):
    """An occluded leaf in two pieces: both pieces point to one centre."""
    lab = np.zeros((64, 64), np.int32)
    lab[20:24, 2:20] = 1001
    lab[20:24, 40:62] = 1001
    lab[2:60, 28:34] = 1002  # the occluder
    t = make_targets(lab, contract)
    assert len(t.centers) == 2
    ys, xs = np.nonzero(t.instances == 1001)
    pts = np.stack([ys + t.offset[0, ys, xs], xs + t.offset[1, ys, xs]], 1)
    assert np.ptp(pts, axis=0).max() < 1e-4


def test_perfect_outputs_decode_to_true_count(contract, tiny_dataset):
    """Targets fed through the Python decoder give back the label's leaf count."""
    from phyllo_train.dataset import read_label, read_manifest

    for row in read_manifest(tiny_dataset):
        lab = read_label(tiny_dataset / row["label"])
        t = make_targets(lab, contract)
        logits = torch.nn.functional.one_hot(torch.from_numpy(t.semantic), contract.num_classes).permute(2, 0, 1).float()
        res = decode(logits, torch.from_numpy(t.center), torch.from_numpy(t.offset), contract)
        assert res.leaf_count == label_leaf_count(lab, contract) == row["visible_leaf_count"]


def test_losses_are_small_for_perfect_outputs(contract):
    lab = np.zeros((64, 64), np.int32)
    lab[10:20, 4:40] = 1001
    t = make_targets(lab, contract)
    ts = {k: torch.from_numpy(getattr(t, k))[None] for k in
          ("semantic", "semantic_weight", "center", "center_weight", "offset", "offset_weight")}
    logits = torch.nn.functional.one_hot(ts["semantic"], 4).permute(0, 3, 1, 2).float() * 20
    total, parts = panoptic_loss((logits, ts["center"], ts["offset"]), ts, LossWeights())
    assert parts["center"] == 0 and parts["offset"] == 0 and parts["sem"] < 1e-6
    # Top-k mining averages only the hardest pixels: never below the plain mean.
    rnd = torch.randn(1, 4, 32, 32)
    assert semantic_topk_ce(rnd, ts["semantic"], ts["semantic_weight"], 0.2) >= semantic_topk_ce(
        rnd, ts["semantic"], ts["semantic_weight"], 1.0)


def test_crop_keeps_the_whole_instance_centre(contract):
    """A leaf cut by the crop window points to the centre of the whole leaf, outside the crop."""
    lab = np.zeros((64, 128), np.int32)
    lab[30:34, 10:110] = 1001  # centre of mass (31.5, 59.5)
    win = (0, 64, 64, 64)      # right half only
    t = make_targets(lab, contract, window=win)
    cy, cx = (31.5 - 0.5) / 2, (59.5 - 64 - 0.5) / 2  # -2.5: left of the crop
    np.testing.assert_allclose(t.centers, [[cy, cx]], atol=1e-5)
    ys, xs = np.nonzero(t.offset_weight[0])
    np.testing.assert_allclose(xs + t.offset[1, ys, xs], cx, atol=1e-5)
    # Only the visible tail of the Gaussian: its peak lies 2.5 px left of the crop.
    assert 0.5 < t.center.max() < 1.0
    # The same leaf seen through the other half of the image agrees on where its centre is.
    t2 = make_targets(lab, contract, window=(0, 0, 64, 64))
    np.testing.assert_allclose(t2.centers[0, 1] - 32, cx, atol=1e-5)


def test_small_centre_weight_covers_small_centres_only(contract):
    lab = np.zeros((128, 128), np.int32)
    lab[10:20, 4:40] = 1 * contract.label_divisor + 1    # 360 px: small
    lab[60:120, 40:100] = 1 * contract.label_divisor + 2  # 3600 px: not small
    plain = make_targets(lab, contract)
    assert (plain.center_weight == 1.0).all()
    t = make_targets(lab, contract, small_center_weight=5.0)
    w = t.center_weight[0]
    r = 2.0 * contract.center_sigma
    (sy, sx), (by, bx) = np.rint(t.centers).astype(int)
    assert w[sy, sx] == 5.0
    gy, gx = np.mgrid[0:w.shape[0], 0:w.shape[1]]
    near_small = (gy - sy) ** 2 + (gx - sx) ** 2 <= r * r
    assert (w[near_small] == 5.0).all() and (w[~near_small] == 1.0).all()
    assert w[by, bx] == 1.0
    # The heatmap itself is the same; only its weight changes.
    np.testing.assert_array_equal(t.center, plain.center)


def test_saddle_weight_covers_the_dip_between_near_centres_only(contract):
    lab = np.zeros((128, 128), np.int32)
    lab[40:48, 30:42] = 1 * contract.label_divisor + 1   # two leaves 6 output px apart
    lab[40:48, 42:54] = 1 * contract.label_divisor + 2
    lab[100:110, 90:110] = 1 * contract.label_divisor + 3  # far from both
    plain = make_targets(lab, contract)
    t = make_targets(lab, contract, saddle_center_weight=6.0)
    np.testing.assert_array_equal(t.center, plain.center)
    w = t.center_weight[0]
    a, b, lone = plain.centers.astype(np.float64)
    my, mx = np.rint((a + b) / 2).astype(int)
    assert w[my, mx] == 6.0
    # The dip is weighted, the peaks themselves and the lone leaf are not.
    for cy, cx in np.rint([a, b, lone]).astype(int):
        assert w[cy, cx] == 1.0
    assert (w == 6.0).sum() <= 3 * 3 * 5
    assert saddle_pairs(plain.centers, SADDLE_REACH * contract.center_sigma).shape == (1, 2, 2)
    assert (make_targets(lab, contract).center_weight == 1.0).all()


def test_crowded_centres_get_narrow_gaussians_and_lone_ones_keep_the_contracts():
    centres = np.array([[10.0, 10.0], [10.0, 15.0], [60.0, 60.0]])
    sig = crowding_sigmas(centres, 4.0, 2.0)
    assert sig[0] == sig[1] == 2.0          # 5 px apart: 5 / 2.5
    assert sig[2] == 4.0                    # alone
    assert (crowding_sigmas(np.array([[0.0, 0.0], [0.0, 1.0]]), 4.0, 1.5) == 1.5).all()  # floor
    assert (crowding_sigmas(centres, 4.0, 4.0) == 4.0).all()  # a floor at the sigma turns it off
    assert crowding_sigmas(centres[:1], 4.0, 2.0).tolist() == [4.0]


def test_crowding_keeps_two_blended_peaks_apart(contract):
    """Two small leaves 6 output px apart: summed at the contract's sigma their Gaussians make
    one peak (what a smooth network learns); narrowed by crowding they stay two."""
    lab = np.zeros((128, 128), np.int32)
    lab[40:48, 30:42] = 1 * contract.label_divisor + 1
    lab[40:48, 42:54] = 1 * contract.label_divisor + 2
    lone = 1 * contract.label_divisor + 3
    lab[100:110, 90:110] = lone
    plain = make_targets(lab, contract)
    crowded = make_targets(lab, contract, center_sigma_min=2.0)
    # The lone leaf's Gaussian is the contract's in both.
    (ly, lx) = np.rint(plain.centers[2]).astype(int)
    np.testing.assert_array_equal(plain.center[0, ly - 8:ly + 9, lx - 8:lx + 9], crowded.center[0, ly - 8:ly + 9, lx - 8:lx + 9])

    def summed(sigmas):
        gy, gx = np.mgrid[0:64, 0:64]
        return sum(np.exp(-((gy - cy) ** 2 + (gx - cx) ** 2) / (2 * s * s)) for (cy, cx), s in zip(np.rint(plain.centers), sigmas))

    def peaks(heat):
        return len(find_centers(torch.from_numpy(heat.astype(np.float32))[None], 0.3, 7, 100))

    assert peaks(summed([contract.center_sigma] * 3)) == 2
    assert peaks(summed(crowding_sigmas(plain.centers.astype(np.float64), contract.center_sigma, 2.0))) == 3
    # Each peak of the target stays exactly 1.
    for cy, cx in np.rint(crowded.centers).astype(int):
        assert crowded.center[0, cy, cx] == 1.0


def test_centre_focal_loss_prefers_two_peaks_to_one_blob():
    """Two small leaves' centres 8 px apart: the blob that merges them costs little MSE, more focal loss."""
    from phyllo_train.losses import center_focal_loss
    from phyllo_train.targets import gaussian_heatmap

    truth = torch.from_numpy(gaussian_heatmap((48, 48), np.array([[24, 20], [24, 28]]), 4.0))[None, None]
    blob = 0.9 * torch.from_numpy(gaussian_heatmap((48, 48), np.array([[24, 24]]), 5.0))[None, None]
    mse = ((blob - truth) ** 2).mean()
    assert mse < 0.01
    assert center_focal_loss(blob, truth) > 1.3 * center_focal_loss(truth, truth)
    # Without a peak at either centre the focal loss pays per missed centre, not per pixel.
    assert center_focal_loss(torch.zeros_like(truth), truth) > 5.0


def test_blade_centre_lies_on_an_arched_leaf_and_a_straight_one_keeps_its_mass_centre(contract):
    """`--center-point blade`: an arch's centre of mass is in the air under it; the blade's own
    nearest pixel is on the arch, and every blade pixel's offset points there."""
    div = contract.label_divisor
    lab = np.zeros((96, 96), np.int32)
    # An arch: two legs and a top bar (an upside-down U), one leaf.
    lab[10:14, 20:76] = div + 1
    lab[10:70, 20:24] = div + 1
    lab[10:70, 72:76] = div + 1
    # A straight leaf, elsewhere.
    lab[80:84, 10:60] = div + 2
    mass = make_targets(lab, contract)
    blade = make_targets(lab, contract, center_point="blade")
    s = contract.stride
    order = np.argsort(mass.centers[:, 0])  # the arch's centre is above the straight leaf's
    arch_mass, arch_blade = mass.centers[order[0]], blade.centers[order[0]]
    # The arch's centre of mass falls between its legs, below its top bar: off the blade.
    my, mx = arch_mass * s + (s - 1) / 2
    assert lab[int(round(my)), int(round(mx))] == 0
    by, bx = arch_blade * s + (s - 1) / 2
    assert lab[int(round(by)), int(round(bx))] == div + 1
    # It is the arch's pixel nearest its centre of mass: the top bar's middle.
    assert 10 <= by < 14 and abs(bx - mx) <= 2
    # The straight leaf's centre of mass is on it, so it stays where it was.
    np.testing.assert_allclose(blade.centers[order[1]], mass.centers[order[1]], atol=1e-5)
    # Every arch pixel points at the blade centre, so decoding still gives two leaves.
    ys, xs = np.nonzero(blade.instances == blade.instances[int(arch_blade[0]), int(arch_blade[1])])
    np.testing.assert_allclose(ys + blade.offset[0, ys, xs], arch_blade[0], atol=1e-4)
    np.testing.assert_allclose(xs + blade.offset[1, ys, xs], arch_blade[1], atol=1e-4)
    logits = torch.nn.functional.one_hot(torch.from_numpy(blade.semantic), contract.num_classes)
    res = decode(logits.permute(2, 0, 1).float(), torch.from_numpy(blade.center), torch.from_numpy(blade.offset),
                 contract)
    assert res.leaf_count == 2


def test_unknown_centre_point_is_refused(contract):
    import pytest

    with pytest.raises(ValueError, match="center_point"):
        make_targets(np.zeros((8, 8), np.int32), contract, center_point="tip")
