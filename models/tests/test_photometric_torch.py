"""The device-side photometric augmentation repeats the loader's, op for op."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from PIL import Image, ImageFilter

from phyllo_train import train
from phyllo_train.augment import AugmentConfig, PhotometricDraw, apply_photometric, draw_photometric
from phyllo_train.dataset import PanopticDataset, normalise
from phyllo_train.modes.photometric_torch import apply_batch, finish_batch
from phyllo_train.train import collate


@pytest.fixture(scope="module")
def crop(tiny_dataset):
    """A 256² crop of a fixture image with some texture, and its plant mask."""
    img = np.asarray(Image.open(tiny_dataset / "images" / "0000.png").convert("RGB"))[100:356, 100:356]
    rng = np.random.default_rng(0)
    img = np.clip(img.astype(int) + rng.integers(-20, 20, size=img.shape), 0, 255).astype(np.uint8)
    img = np.asarray(Image.fromarray(img).filter(ImageFilter.GaussianBlur(1.0))).copy()
    return img, img[..., 1] > img[..., 0] + 30


def _both(img: np.ndarray, plant: np.ndarray, d: PhotometricDraw) -> tuple[np.ndarray, np.ndarray]:
    cpu = apply_photometric(img, d, plant).astype(np.float64)
    dev = apply_batch(torch.from_numpy(img).permute(2, 0, 1)[None], torch.from_numpy(d.to_vector())[None],
                      torch.from_numpy(plant)[None])[0].permute(1, 2, 0).numpy()
    return cpu, dev.astype(np.float64)


@pytest.mark.parametrize("draw", [
    PhotometricDraw(backlight=True, backlight_gain=0.5, backlight_desaturate=0.3),
    PhotometricDraw(white_balance=(1.1, 0.9, 1.05), brightness=1.2, contrast=0.8),
    PhotometricDraw(gradient=0.2, gradient_angle=1.0, gamma=0.8),
    PhotometricDraw(fringe=(1, -1, 0, 1)),
])
def test_colour_and_illumination_ops_match_the_loader_to_one_level(crop, draw):
    img, plant = crop
    cpu, dev = _both(img, plant, draw)
    assert np.abs(cpu - img).mean() > 1.0  # the op does something
    assert np.abs(cpu - dev).max() <= 1.0


@pytest.mark.parametrize("draw", [
    PhotometricDraw(hsv=True, hue=0.03, saturation=1.3),
    PhotometricDraw(blur_sigma=0.8),
    PhotometricDraw(blur_sigma=1.5),
    PhotometricDraw(jpeg_quality=35),
    PhotometricDraw(jpeg_quality=60),
    PhotometricDraw(jpeg_quality=95),
])
def test_hsv_blur_and_jpeg_stay_within_a_level_on_average(crop, draw):
    # These differ in detail (PIL's 8-bit HSV, box-approximated blur, libjpeg's
    # chroma upsampling): the mean difference must stay well under the op's effect.
    img, plant = crop
    cpu, dev = _both(img, plant, draw)
    change = np.abs(cpu - img).mean()
    assert change > 0.7
    assert np.abs(cpu - dev).mean() < 0.9 * change
    assert np.abs(cpu - dev).mean() < 1.0


def test_noise_has_the_drawn_sigma_and_follows_its_seed(crop):
    img, plant = crop
    flat = np.full_like(img, 128)
    d = PhotometricDraw(noise_sigma=6.0, noise_seed=11)
    _, dev = _both(flat, plant, d)
    assert 5.4 < (dev - 128).std() < 6.6
    _, again = _both(flat, plant, d)
    np.testing.assert_array_equal(dev, again)
    _, other = _both(flat, plant, dataclasses.replace(d, noise_seed=12))
    assert not np.array_equal(dev, other)


def test_a_batch_applies_each_row_to_its_own_image(crop):
    img, plant = crop
    draws = [PhotometricDraw(), PhotometricDraw(brightness=0.5), PhotometricDraw(jpeg_quality=40)]
    batch = torch.from_numpy(np.stack([img] * 3)).permute(0, 3, 1, 2)
    out = apply_batch(batch, torch.from_numpy(np.stack([d.to_vector() for d in draws])),
                      torch.from_numpy(np.stack([plant] * 3)))
    for i, d in enumerate(draws):
        _, alone = _both(img, plant, d)
        np.testing.assert_allclose(out[i].permute(1, 2, 0).numpy(), alone, atol=1.0)


def test_deferred_dataset_gives_the_same_sample_finished_on_the_device(tiny_dataset, contract):
    # Noise off: its fields come from different generators on the two paths.
    cfg = dataclasses.replace(AugmentConfig(crop=128), noise_p=0.0)
    near = PanopticDataset(tiny_dataset, "train", cfg, contract, seed=5)
    far = PanopticDataset(tiny_dataset, "train", cfg, contract, seed=5, defer_photometric=True)
    for i in range(len(near)):
        x, t = near[i]
        raw, tf = far[i]
        assert raw.dtype == torch.uint8 and tf["plant"].dtype == torch.bool
        for k in t:
            torch.testing.assert_close(t[k], tf[k])
        batched = {k: v[None] for k, v in tf.items()}
        xs = finish_batch(raw[None], batched, contract)[0]
        assert "photometric" not in batched and "plant" not in batched
        # Every op at once (PIL's 8-bit HSV rounds flat grey one level off): within two levels.
        level = float(1.0 / 255 / min(contract.std))
        assert (xs - x).abs().mean() < 2 * level


def test_draws_follow_the_config(contract):
    rng = np.random.default_rng(0)
    assert draw_photometric(AugmentConfig.none(), rng).to_vector().tolist() == PhotometricDraw().to_vector().tolist()
    cfg = dataclasses.replace(AugmentConfig(), backlight_p=1.0, jpeg_p=1.0, noise_p=1.0, blur_p=1.0, fringe_p=1.0)
    d = draw_photometric(cfg, rng)
    assert d.backlight and d.blur_sigma > 0 and d.noise_sigma > 0 and 35 <= d.jpeg_quality <= 95
    assert not draw_photometric(cfg, rng, with_plant=False).backlight
    assert len(d.to_vector()) == PhotometricDraw.FIELDS
    # The loader path is unchanged by the split: rgb equals normalise(apply(draw)).
    img = np.random.default_rng(1).integers(0, 255, (64, 64, 3), dtype=np.uint8)
    a = normalise(apply_photometric(img, d), contract)
    assert a.shape == (3, 64, 64)


def test_training_with_device_photometric_runs_and_resumes(tiny_dataset, tmp_path):
    run = tmp_path / "dev"
    args = ["--data", str(tiny_dataset), "--out", str(run), "--crop", "64", "--batch", "2", "--workers", "1",
            "--val-limit", "0", "--log-every", "1", "--warmup", "1", "--photometric", "device"]
    assert train.main(args + ["--steps", "2"]) == 0
    assert train.main(args + ["--steps", "3"]) == 0  # resumes from last.pt
    ck = torch.load(run / "last.pt", map_location="cpu", weights_only=False)
    assert ck["step"] == 3
    # Each log line says what share of the time the network waited for the loader.
    import json
    rows = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    steps = [r for r in rows if "rate" in r]
    assert [r["step"] for r in steps] == [1, 2, 3] and all(0.0 <= r["data_wait"] <= 1.0 for r in steps)
    xs, ts = collate([PanopticDataset(tiny_dataset, "train", AugmentConfig(crop=64), defer_photometric=True)[i]
                      for i in range(2)])
    assert xs.dtype == torch.uint8 and ts["photometric"].shape == (2, PhotometricDraw.FIELDS)
