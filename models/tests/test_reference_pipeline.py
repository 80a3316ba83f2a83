"""Reference pipeline: same tiling/stitching rules as inference/src."""

import numpy as np

from phyllo_train.reference_pipeline import plant_bbox, prepare, scale_for, stitch, tile_starts


def test_tile_starts_and_scale_match_rust(contract):
    assert tile_starts(512, 512, 128, 2) == [0] and tile_starts(300, 512, 128, 2) == [0]
    s = tile_starts(1300, 512, 128, 2)
    assert s[0] == 0 and s[-1] + 512 == 1300 and all(a + 512 >= b + 128 for a, b in zip(s, s[1:]))
    assert all(v % 2 == 0 for v in s)
    assert abs(scale_for(contract, 2454, 2056) - 0.25) < 1e-6
    assert abs(scale_for(contract, 1227, 1028) - 0.5) < 1e-6
    assert abs(scale_for(contract, 225, 198) - 448 / 225) < 1e-6


def test_plant_bbox_matches_rust_example():
    img = np.full((200, 300, 3), (235, 230, 228), np.uint8)
    img[50:150, 100:140] = (60, 120, 40)
    img[5, 290] = (0, 255, 0)
    assert plant_bbox(img, 0.005, 0, 10) == (100, 50, 140, 150)
    assert plant_bbox(img, 0.005, 8, 10) == (92, 42, 148, 158)


def test_stitching_perfect_tiles_gives_back_the_canvas(contract):
    img = np.full((2056, 2454, 3), (235, 232, 230), np.uint8)
    img[800:1600, 1000:1200] = (50, 120, 40)
    assert len(prepare(contract, img).tiles) == 1  # the plant region fits one tile
    cv = prepare(contract, img, region="full")     # the whole frame
    assert len(cv.tiles) == 4  # 614 x 514: two tile columns, two rows (514 > 512)
    ch, cw = cv.image.shape[:2]
    assert ch % 2 == 0 and cw % 2 == 0 and ch >= 512 and cw >= 512
    s, t = contract.stride, contract.tile // contract.stride
    rng = np.random.default_rng(0)
    full = [rng.standard_normal((k, ch // s, cw // s)).astype(np.float32) for k in (4, 1, 2)]
    outs = [np.stack([f[:, y // s:y // s + t, x // s:x // s + t] for x, y in cv.tiles]) for f in full]
    for a, b in zip(stitch(outs, cv.tiles, cw, ch, s), full):
        np.testing.assert_array_equal(a, b)
