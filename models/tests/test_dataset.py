"""Dataset reading and augmentation."""

import numpy as np
import torch

from phyllo_train.augment import AugmentConfig
from phyllo_train.dataset import PanopticDataset, normalise, read_manifest


def test_manifest_and_shapes(tiny_dataset, contract):
    assert len(read_manifest(tiny_dataset, "train")) == 4 and len(read_manifest(tiny_dataset, "val")) == 2
    ds = PanopticDataset(tiny_dataset, "train", AugmentConfig(crop=128), contract)
    x, t = ds[0]
    assert x.shape == (3, 128, 128) and x.dtype == torch.float32
    h = 128 // contract.stride
    assert t["semantic"].shape == (h, h) and t["center"].shape == (1, h, h) and t["offset"].shape == (2, h, h)
    # Offsets live exactly on thing pixels.
    things = (t["semantic"] == 1) | (t["semantic"] == 3)
    assert torch.equal(t["offset_weight"][0] > 0, things)


def test_full_tile_without_augmentation(tiny_dataset, contract):
    ds = PanopticDataset(tiny_dataset, "val", AugmentConfig.none(), contract)
    x, t = ds[0]
    assert x.shape == (3, contract.tile, contract.tile)
    assert t["center"].max() == 1.0


def test_augmentation_is_deterministic_per_epoch(tiny_dataset, contract):
    ds = PanopticDataset(tiny_dataset, "train", AugmentConfig(crop=96), contract, seed=3)
    a, b = ds[1][0], ds[1][0]
    assert torch.equal(a, b)
    ds.set_epoch(1)
    assert not torch.equal(a, ds[1][0])


def test_geometry_keeps_image_and_label_aligned(tiny_dataset, contract):
    """With photometric ops off, leaf pixels stay green and background stays grey after scale/crop/flip."""
    cfg = AugmentConfig.none(crop=192)
    cfg.scale, cfg.hflip, cfg.fg_crop = (0.7, 1.4), 0.5, 1.0
    ds = PanopticDataset(tiny_dataset, "train", cfg, contract)
    mean = torch.tensor(contract.mean)[:, None, None]
    std = torch.tensor(contract.std)[:, None, None]
    for i in range(4):
        x, t = ds[i]
        rgb = (x * std + mean)[:, ::2, ::2]  # input pixel (2i, 2j) at each output pixel
        leaf = t["semantic"] == 1
        bg = t["semantic"] == 0
        green_minus_red = (rgb[1] - rgb[0])
        assert green_minus_red[leaf].median() > 0.2
        assert green_minus_red[bg].abs().median() < 0.05


def test_normalise_follows_contract(contract):
    px = np.full((2, 2, 3), 255, np.uint8)
    out = normalise(px, contract)
    np.testing.assert_allclose(out[:, 0, 0], [(1 - m) / s for m, s in zip(contract.mean, contract.std)], rtol=1e-6)


def test_byte_swapped_labels_are_refused(tiny_dataset, contract, tmp_path):
    import shutil

    import pytest
    from PIL import Image

    bad = tmp_path / "swapped"
    shutil.copytree(tiny_dataset, bad)
    p = bad / "labels" / "0000.png"
    Image.fromarray(np.array(Image.open(p)).astype(np.uint16).byteswap()).save(p)
    with pytest.raises(ValueError, match="byte-swapped"):
        PanopticDataset(bad, "train", AugmentConfig(crop=64), contract)[0]


def test_colour_fringes_shift_only_red_and_blue():
    """The fringe op moves the red and blue planes by at most fringe_px and leaves green alone."""
    from phyllo_train.augment import photometric

    img = np.zeros((32, 32, 3), np.uint8)
    img[:, 15:17] = 200  # a thin grey profile
    cfg = AugmentConfig.none()
    cfg.fringe_p, cfg.fringe_px = 1.0, 1
    moved = 0
    for seed in range(8):
        out = photometric(img, cfg, np.random.default_rng(seed))
        np.testing.assert_array_equal(out[..., 1], img[..., 1])
        for c in (0, 2):
            cols = np.nonzero(out[0, :, c])[0]
            assert cols.min() >= 14 and cols.max() <= 17
            moved += int(not np.array_equal(out[..., c], img[..., c]))
    assert moved > 0


def test_backlight_darkens_only_the_plant():
    """The backlight op darkens labelled plant pixels and leaves the chamber away from them alone."""
    from phyllo_train.augment import photometric

    img = np.full((32, 32, 3), 230, np.uint8)
    img[8:24, 12:20] = (60, 140, 50)  # a leaf
    plant = np.zeros((32, 32), bool)
    plant[8:24, 12:20] = True
    cfg = AugmentConfig.none()
    cfg.backlight_p = 1.0
    out = photometric(img, cfg, np.random.default_rng(0), plant).astype(int)
    assert out[12:20, 14:18].mean() < img[12:20, 14:18].astype(int).mean() * 0.85
    np.testing.assert_array_equal(out[:, :10], img[:, :10])
    np.testing.assert_array_equal(out[:, 22:], img[:, 22:])
    # Without a plant mask the op cannot apply.
    np.testing.assert_array_equal(photometric(img, cfg, np.random.default_rng(0)), img)


def test_zoom_enlarges_small_plants_as_the_daemon_does():
    """The contract's zoom: a plant whose instances span few rows is enlarged
    to the zoom height (margins included), by at most max_zoom; tall plants
    and enlargements under 1.1 are left alone."""
    from PIL import Image

    from phyllo_train.augment import augment, plant_rows, plant_zoom

    lab = np.zeros((514, 614), np.uint16)
    lab[300:376, 300:304] = 2000          # stem: stuff, not measured
    lab[300:360, 290:300] = 1001          # two leaves spanning rows 296..376
    lab[336:376, 304:320] = 1002
    assert plant_rows(lab, 1000) == (300 - 12, 376 + 12)
    assert abs(plant_zoom(lab, 1000, 160, 2.0) - 160 / 100) < 1e-6
    assert plant_zoom(lab, 1000, 320, 2.0) == 2.0
    assert plant_zoom(lab, 1000, 105, 2.0) == 1.0   # 1.05: not worth it
    assert plant_zoom(lab, 1000, 0, 2.0) == 1.0
    assert plant_zoom(np.zeros_like(lab), 1000, 320, 2.0) == 1.0

    img = Image.fromarray(np.full((514, 614, 3), 230, np.uint8))
    cfg = AugmentConfig.none(crop=256)
    _, out, _, _ = augment(img, lab, cfg, np.random.default_rng(0), zoom=(320, 2.0))
    # Both leaves are twice as large, and the instance ids survive.
    assert (out == 1001).sum() == 4 * (lab == 1001).sum()
    assert (out == 1002).sum() == 4 * (lab == 1002).sum()
