"""Per-source input statistics: colours of wall and plant, and the wall's roughness."""

import numpy as np
from PIL import Image

from phyllo_train import domain_stats


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
