"""Per-source input statistics: colours of wall and plant, and the wall's roughness."""

import numpy as np
from PIL import Image

from phyllo_train.experiments import domain_stats


def test_roughness_sees_noise_and_green_over_red_sees_the_plant():
    rng = np.random.default_rng(0)
    flat = np.full((64, 64, 3), 230, np.uint8)
    plant = np.zeros((64, 64), bool)
    plant[20:40, 28:36] = True
    flat[plant] = (60, 110, 40)
    noisy = np.clip(flat + rng.normal(0, 6, flat.shape), 0, 255).astype(np.uint8)
    noisy[plant] = (60, 110, 40)
    a, b = domain_stats.image_stats(flat, plant), domain_stats.image_stats(noisy, plant)
    names = list(domain_stats.STATS)
    assert a[names.index("wall roughness")] == 0.0
    assert b[names.index("wall roughness")] > 3.0
    assert a[names.index("plant G−R")] == 50.0 and a[names.index("wall G")] == 230.0
    assert domain_stats.image_stats(flat, np.zeros((64, 64), bool)) is None


def test_cli_prints_a_row_per_source(tiny_dataset, tmp_path, capsys):
    assert domain_stats.main(["--images", str(tiny_dataset / "images"), "--augmented", str(tiny_dataset),
                              "--limit", "3", "--crop", "128"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("| source | images | wall R")
    assert lines[2].startswith("| images | 3 | ") and lines[3].startswith(f"| {tiny_dataset.name}, augmented 128² crops |")
    bad = tmp_path / "bad"
    bad.mkdir()
    Image.new("RGB", (8, 8)).save(bad / "a.png")
    (bad / "b.png").write_bytes(b"\x89PNG truncated")
    assert domain_stats.main(["--images", str(bad)]) == 2


def test_the_noise_knobs_roughen_the_augmented_crops(tiny_dataset):
    from phyllo_train.augment import AugmentConfig

    def roughness(noise_p, sigma):
        cfg = AugmentConfig(crop=128, noise_p=noise_p, noise_sigma=sigma, jpeg_p=0.0, blur_p=0.0)
        rp = domain_stats.reference_pipeline()
        rows = [domain_stats.image_stats(img, rp.plant_colour(img))
                for img in domain_stats.augmented_crops(tiny_dataset, 3, 128, cfg)]
        return np.median([r[list(domain_stats.STATS).index("wall roughness")] for r in rows if r is not None])

    assert roughness(1.0, (8.0, 8.0)) > roughness(0.0, (8.0, 8.0)) + 3.0


def test_a_bad_noise_range_is_refused(capsys):
    import pytest

    for bad in ("3", "5,2", "a,b"):
        with pytest.raises(SystemExit):
            domain_stats.main(["--images", ".", "--noise-sigma", bad])
    assert "--noise-sigma" in capsys.readouterr().err
