"""fenestra/training/augment.py's street-level augmentations (issue #23 item 4): the oblique-view warp moves
corner labels with the pixels, each new step is off by default (same random stream), and a pasted
neighbouring facade brings its own windows."""
from dataclasses import replace

import numpy as np
import pytest

from fenestra.training.augment import (AugmentConfig, motion_kernel, neighbour_strip, perspective_homography, photometric,
                              random_scale_crop)

OBLIQUE = replace(AugmentConfig(), scale_range=(1.0, 1.0), hflip_prob=0.0, perspective_prob=1.0)


def _project(H: np.ndarray, p: np.ndarray) -> np.ndarray:
    q = H @ np.array([p[0], p[1], 1.0])
    return q[:2] / q[2]


@pytest.mark.parametrize("seed", range(4))
def test_perspective_homography_keeps_the_centre_and_its_scale(seed):
    """The image centre stays put and a small square there keeps its area (finite differences)."""
    h, w = 300, 400
    H = perspective_homography(h, w, OBLIQUE, np.random.default_rng(seed))
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    assert np.allclose(_project(H, c), c, atol=1e-6)
    e = 0.5
    a = _project(H, c + [e, 0]) - _project(H, c - [e, 0])
    b = _project(H, c + [0, e]) - _project(H, c - [0, e])
    assert abs(a[0] * b[1] - a[1] * b[0] - (2 * e) ** 2) < 1e-3
    assert not np.allclose(H / H[2, 2], np.eye(3), atol=1e-3)  # it does warp


def test_perspective_homography_turns_the_facade_by_the_yaw():
    """A pure yaw of +-yaw_deg makes one vertical edge shorter than the other: the facade recedes."""
    cfg = replace(OBLIQUE, yaw_deg=40.0, pitch_deg=(0.0, 0.0), roll_deg=0.0)
    h, w = 300, 400
    ratios = []
    for seed in range(8):
        H = perspective_homography(h, w, cfg, np.random.default_rng(seed))
        left = np.linalg.norm(_project(H, [0, 0]) - _project(H, [0, h - 1]))
        right = np.linalg.norm(_project(H, [w - 1, 0]) - _project(H, [w - 1, h - 1]))
        ratios.append(max(left, right) / min(left, right))
    assert max(ratios) > 1.2  # at |yaw| near 40 deg one side is clearly shorter


@pytest.mark.parametrize("seed", range(6))
def test_oblique_crop_moves_points_with_the_pixels(seed):
    """A marked block's centre, warped by CropWarp.points, lands on the block's warped pixels."""
    img = np.zeros((240, 320, 3), np.uint8)
    inst = np.zeros((240, 320), np.int32)
    inst[110:116, 150:156] = 1  # centre (152.5, 112.5): near the image centre, kept by the warp
    _, ins, warp = random_scale_crop(img, inst, (128, 128), OBLIQUE, np.random.default_rng(seed))
    ys, xs = np.nonzero(ins)
    p = warp.points(np.array([152.5, 112.5]))
    if xs.size:
        assert warp.H is not None
        assert abs(p[0] - xs.mean()) < 0.75 and abs(p[1] - ys.mean()) < 0.75, (p, xs.mean(), ys.mean())


def test_new_steps_draw_nothing_when_off():
    """Defaults: a crop and its photometric step give the pixels and leave the random stream
    exactly where the code before these steps did (figures pinned from fenestra/training/augment.py at
    5f253ee, run on the same input), so configs without the new steps train on the same batches."""
    img = np.random.default_rng(1).integers(0, 255, (80, 100, 3), dtype=np.uint8)
    inst = np.zeros((80, 100), np.int32)
    inst[20:40, 30:60] = 1
    cfg, rng = AugmentConfig(), np.random.default_rng(5)
    out, ins, warp = random_scale_crop(img, inst, (64, 64), cfg, rng)
    ph = photometric(out, cfg, rng)
    same, same_inst, pasted = neighbour_strip(img, inst, img, inst, cfg, rng)
    assert warp.H is None and same is img and same_inst is inst and not pasted.any()
    assert (int(out.astype(np.int64).sum()), int(ins.sum()), int(ph.astype(np.int64).sum())) == (1568285, 644, 1508861)
    assert rng.random() == 0.9358663535243149


def test_constant_pad_leaves_no_mirrored_window():
    """A crop larger than the scaled photo: 'reflect' mirrors the window into unlabelled pixels,
    'constant' fills a flat colour."""
    img = np.full((40, 40, 3), 200, np.uint8)
    img[5:15, 5:35] = 20  # a dark window at the top
    inst = np.zeros((40, 40), np.int32)
    inst[5:15, 5:35] = 1
    cfg = replace(AugmentConfig(), scale_range=(1.0, 1.0), hflip_prob=0.0)
    for pad, mirrored in (("reflect", True), ("constant", False)):
        out, ins, _ = random_scale_crop(img, inst, (64, 64), replace(cfg, pad=pad), np.random.default_rng(0))
        dark_unlabelled = (out.mean(axis=2) < 30) & (ins == 0)
        assert dark_unlabelled.any() == mirrored, pad
    with pytest.raises(ValueError, match="pad"):
        AugmentConfig(pad="wrap")


def test_motion_kernel_is_a_normalised_line():
    k = motion_kernel(7, 0.0)
    assert k.shape == (7, 7) and abs(k.sum() - 1) < 1e-6
    assert (k[3] > 0).sum() == 7 and k[[0, 1, 2, 4, 5, 6]].sum() == 0  # the middle row only
    kv = motion_kernel(5, 90.0)
    assert (kv[:, 2] > 0).sum() == 5 and abs(kv.sum() - 1) < 1e-6


def test_neighbour_strip_pastes_an_edge_strip_with_its_windows():
    img = np.full((64, 96, 3), 100, np.uint8)
    inst = np.zeros((64, 96), np.int32)
    inst[10:30, 40:60] = 1
    inst[35:50, 40:60] = 2
    other = np.full((64, 96, 3), 30, np.uint8)
    o_inst = np.zeros((64, 96), np.int32)
    o_inst[:, :] = 0
    o_inst[5:20, 0:96] = 1  # a window band across the whole other crop
    cfg = replace(AugmentConfig(), neighbour_prob=1.0, neighbour_frac=(0.25, 0.25))
    for seed in range(6):
        out, ins, pasted = neighbour_strip(img, inst, other, o_inst, cfg, np.random.default_rng(seed))
        cols = np.nonzero(pasted.any(axis=0))[0]
        assert len(cols) == 24 and (cols[0] == 0 or cols[-1] == 95)  # a quarter, at one edge
        assert pasted[:, cols].all() and (out[pasted] == 30).all() and (out[~pasted] == 100).all()
        assert set(np.unique(ins[pasted])) == {0, 3}  # the other crop's window, id shifted past 2
        assert (ins[~pasted] == inst[~pasted]).all()
    with pytest.raises(ValueError, match="other crop"):
        neighbour_strip(img, inst, other[:10], o_inst[:10], cfg, np.random.default_rng(0))


def test_real_augment_table_overrides_augment_for_the_photos_only(tmp_path):
    """[real_augment] holds only the keys in which the photos' augmentation differs from [augment];
    sample_augment gives it to real photos (no corners) and [augment] to renders."""
    from fenestra.training.recipes.effwin import sample_augment
    from fenestra.training.train import load_config

    cfg_path = tmp_path / "c.toml"
    cfg_path.write_text('[train]\narch = "effwin"\n[augment]\nwhite_balance = 0.2\nshadow_prob = 0.4\n'
                        '[real_augment]\nperspective_prob = 0.5\nshadow_prob = 0.0\n')
    cfg = load_config(cfg_path)
    assert cfg.augment.perspective_prob == 0.0 and cfg.augment.shadow_prob == 0.4
    real = cfg.real_augment
    assert (real.perspective_prob, real.shadow_prob, real.white_balance) == (0.5, 0.0, 0.2)
    photo, render = (None, None, None), (None, None, np.zeros((0, 4, 2)))
    assert sample_augment(photo, cfg) is real and sample_augment(render, cfg) is cfg.augment
    cfg_path.write_text('[train]\narch = "effwin"\n[augment]\nwhite_balance = 0.2\n')
    plain = load_config(cfg_path)
    assert plain.real_augment is None and sample_augment(photo, plain) is plain.augment
    cfg_path.write_text('[train]\narch = "effwin"\n[real_augmentation]\npad = "constant"\n')
    with pytest.raises(ValueError, match="real_augmentation"):
        load_config(cfg_path)
    cfg_path.write_text('[train]\narch = "effwin"\n[real_augment]\nyaw = 3.0\n')
    with pytest.raises(ValueError, match="yaw"):
        load_config(cfg_path)
