"""The quad head (detector v8, fenestra/pipeline/detectors/quadhead.py): its targets decode back to
the exact quads, adjacent windows stay apart, the mirror average maps a mirrored image's maps
back, corner refinement finds a Gaussian's sub-pixel peak, the ``network`` quad source, and
training the head alone leaves the frozen network bit for bit as it was."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from fenestra.pipeline.detectors.effwin import corner_heatmaps
from fenestra.pipeline.detectors.quadhead import (OFFSET_SCALE_PX, QUAD_STRIDE, QuadDecode, quad_detections,
                                                  quad_mirror_mean, quad_targets, refine_corner)
from fenestra.pipeline.quad import QuadParams
from fenestra.pipeline.reconstruct import fit_quads, visible_quads


def projected_quads(rng: np.random.Generator, n: int, shape: tuple[int, int]) -> np.ndarray:
    """(n, 4, 2) px: rectangles of 1 x 1.5 m seen under a random yaw, TL TR BR BL, laid side by side."""
    H, W = shape
    out = []
    for k in range(n):
        yaw = np.radians(rng.uniform(-35, 35))
        R = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
        x0 = -2.5 + 1.25 * k
        P = np.array([[x0, -0.75, 0], [x0 + 1, -0.75, 0], [x0 + 1, 0.75, 0], [x0, 0.75, 0]]) @ R.T + [0, 0, 8.0]
        f = 0.8 * W
        out.append(np.column_stack([f * P[:, 0] / P[:, 2] + (W - 1) / 2, f * P[:, 1] / P[:, 2] + (H - 1) / 2]))
    return np.asarray(out)


def test_targets_decode_to_the_exact_quads():
    rng = np.random.default_rng(0)
    shape = (256, 320)
    quads = projected_quads(rng, 4, shape)
    t = quad_targets(quads, np.full(len(quads), 10_000), shape)
    dets = quad_detections(t.centre, t.offsets, None, shape)
    assert len(dets) == len(quads)
    got = sorted((d.corners for d in dets), key=lambda q: q[0, 0])
    np.testing.assert_allclose(np.stack(got), quads[np.argsort(quads[:, 0, 0])], atol=1e-3)  # fp32 offsets


def test_adjacent_windows_are_two_detections_and_a_cut_window_keeps_its_whole_quad():
    shape = (128, 128)
    a = np.array([[10.0, 20], [40, 20], [40, 100], [10, 100]])
    b = a + [33.0, 0]  # 3 px apart: one void blob for a mask detector
    cut = np.array([[100.0, 40], [140, 40], [140, 90], [100, 90]])  # reaches past the right edge
    t = quad_targets(np.stack([a, b, cut]), np.array([2400, 2400, 1400]), shape)
    dets = quad_detections(t.centre, t.offsets, None, shape)
    assert len(dets) == 3
    by_x = sorted(dets, key=lambda d: d.corners[0, 0])
    np.testing.assert_allclose(by_x[0].corners, a, atol=1e-3)
    np.testing.assert_allclose(by_x[1].corners, b, atol=1e-3)
    np.testing.assert_allclose(by_x[2].corners, cut, atol=1e-3)
    assert by_x[2].box[2] == pytest.approx(127.5)  # its mask stops at the image's edge
    assert not (by_x[0].mask.any() and by_x[1].origin[0] <= by_x[0].box[2] - 1)  # the masks do not touch


def test_a_window_seen_too_little_is_ignored_not_a_negative():
    q = np.array([[[20.0, 20], [80, 20], [80, 100], [20, 100]]])
    t = quad_targets(q, np.array([100]), (128, 128))  # 100 of ~4800 px seen
    assert t.centre.max() == 0 and t.reg.sum() == 0
    assert t.ignore[10, 10] == 1 and t.ignore[2, 28] == 0


def test_mirror_mean_maps_a_mirrored_images_maps_back():
    rng = np.random.default_rng(1)
    shape = (128, 192)
    W = shape[1]
    quads = projected_quads(rng, 3, shape)
    mirrored = quads.copy()
    mirrored[..., 0] = W - 1 - mirrored[..., 0]
    mirrored = mirrored[:, [1, 0, 3, 2]]  # TL <-> TR, BR <-> BL
    seen = np.full(3, 10_000)

    def maps(q):
        t = quad_targets(q, seen, shape)
        return torch.from_numpy(np.concatenate([t.centre[None], t.offsets]))[None]

    both = torch.cat([maps(quads), maps(mirrored)])
    np.testing.assert_allclose(quad_mirror_mean(both)[0].numpy(), maps(quads)[0].numpy(), atol=1e-5)


def test_refine_corner_finds_a_gaussian_peak_to_a_hundredth_of_a_pixel():
    true = np.array([[[30.37, 40.81], [60.0, 40.0], [60.0, 70.0], [30.0, 70.0]]])
    heat = corner_heatmaps(true, (96, 96))
    p = refine_corner(heat[0], np.array([32.0, 39.0]), radius=4, min_peak=0.1)
    np.testing.assert_allclose(p, true[0, 0], atol=0.01)
    far = refine_corner(heat[0], np.array([80.0, 80.0]), radius=4, min_peak=0.1)  # no peak near: kept
    np.testing.assert_array_equal(far, [80.0, 80.0])


def test_network_quad_source_takes_the_quad_and_hands_cut_windows_to_the_visible_fit():
    shape = (128, 128)
    inside = np.array([[10.3, 20.6], [40.2, 21.0], [40.0, 100.4], [10.1, 99.7]])
    cut = np.array([[100.0, 40], [140, 40], [140, 90], [100, 90]])
    t = quad_targets(np.stack([inside, cut]), np.array([2400, 1400]), shape)
    dets = sorted(quad_detections(t.centre, t.offsets, None, shape), key=lambda d: d.corners[0, 0])
    params = QuadParams(source="network")
    fits = fit_quads(dets, params, shape)
    np.testing.assert_allclose(fits[0].result.quad, inside, atol=1e-3)
    assert fits[1].result.failure.code == "touches_border"
    vis = visible_quads(dets, fits, params, shape)
    assert set(vis) == {1} and vis[1].quad is not None and "right" in vis[1].cut
    assert vis[1].quad[:, 0].max() == pytest.approx(127.5, abs=0.6)  # the visible part ends at the edge


def test_decode_drops_non_convex_and_tiny_quads():
    shape = (64, 64)
    c = np.zeros((16, 16), np.float32)
    c[8, 8] = 0.9
    off = np.zeros((8, 16, 16), np.float32)
    centre = np.array([8 * QUAD_STRIDE + 1.5] * 2)
    bow_tie = np.array([[-10, -10], [10, 10], [10, -10], [-10, 10]], float)  # TL TR BR BL crossing
    off[:, 8, 8] = (bow_tie / OFFSET_SCALE_PX).reshape(-1)
    assert quad_detections(c, off, None, shape) == []
    off[:, 8, 8] = (np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) / OFFSET_SCALE_PX).reshape(-1)
    assert quad_detections(c, off, None, shape, QuadDecode(min_side_px=3.0)) == []
    assert len(quad_detections(c, off, None, shape, QuadDecode(min_side_px=1.0))) == 1
    assert np.allclose(quad_detections(c, off, None, shape, QuadDecode(min_side_px=1.0))[0].corners.mean(0), centre)


def test_training_the_head_alone_keeps_the_network_bit_for_bit(tmp_path):
    from fenestra.pipeline.detectors import DEFAULT_WEIGHTS
    from fenestra.training.dataset import WindowQuads
    from fenestra.training.recipes.effwin import effwin_batch, effwin_build, effwin_losses
    from fenestra.training.train import TrainConfig

    cfg = TrainConfig(arch="effwin", effwin_backbone="efficientnet-lite2", effwin_quad_head=True,
                      init_weights=str(DEFAULT_WEIGHTS), train_only="quad", crop_hw=(128, 128), batch_size=2,
                      lr=1e-2)
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (160, 160, 3), dtype=np.uint8)
    inst = np.zeros((160, 160), np.uint16)
    inst[40:120, 30:70], inst[40:120, 80:120] = 1, 2
    quads = np.array([[[29.5, 39.5], [69.5, 39.5], [69.5, 119.5], [29.5, 119.5]],
                      [[79.5, 39.5], [119.5, 39.5], [119.5, 119.5], [79.5, 119.5]]])
    item = (image, inst, quads.astype(np.float32), WindowQuads(np.array([1, 2]), quads))
    model, opt = effwin_build(cfg)
    before = {k: v.clone() for k, v in model.state_dict().items()}
    batch = effwin_batch([item], cfg, rng)
    assert batch[3].shape == (2, 11, 32, 32)
    parts = effwin_losses(model, batch, cfg)
    assert set(parts) == {"quad_centre", "quad_offsets", "loss"} and torch.isfinite(parts["loss"])
    opt.zero_grad()
    parts["loss"].backward()
    opt.step()
    after = model.state_dict()
    changed = {k for k in before if not torch.equal(before[k], after[k])}
    assert changed and all(k.startswith("quad.") for k in changed)


def test_ship_weights_sends_each_effwin_file_to_its_own_detector():
    from pathlib import Path

    from lab.ship import shipping_detector

    assert shipping_detector(Path("out/train/quadnet.pt"), {"arch": "effwin"}) == "quadnet"
    assert shipping_detector(Path("out/train/default.pt"), {"arch": "effwin"}) == "default"
    assert shipping_detector(Path("out/train/retrain.pt"), {"arch": "effwin"}) == "default"
    assert shipping_detector(Path("out/train/winnet.pt"), {"arch": "winnet"}) == "winnet"


def peak_maps(peaks, cells: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """(centre (cells, cells), offsets (8, cells, cells)) with a peak of probability p at each cell
    (i, j) whose offsets point to quad q (4, 2) px: peaks = [((i, j), q, p), ...]."""
    c = np.zeros((cells, cells), np.float32)
    off = np.zeros((8, cells, cells), np.float32)
    for (i, j), q, p in peaks:
        c[i, j] = p
        cell = np.array([QUAD_STRIDE * j + 1.5, QUAD_STRIDE * i + 1.5])
        off[:, i, j] = ((q - cell) / OFFSET_SCALE_PX).reshape(-1)
    return c, off


def test_a_second_peak_on_one_window_is_dropped_but_a_neighbour_is_kept():
    window = np.array([[20.0, 10], [44, 10], [44, 80], [20, 80]])
    part = np.array([[22.0, 40], [46, 40], [46, 86], [22, 86]])  # a peak low on the window: a shifted part of it
    neighbour = window + [28.0, 0]  # 4 px to the right
    c, off = peak_maps([((11, 7), window, 0.9), ((15, 8), part, 0.7), ((11, 14), neighbour, 0.8)])
    dets = quad_detections(c, off, None, (96, 96))
    assert len(dets) == 2
    np.testing.assert_allclose(dets[0].corners, window, atol=1e-4)
    np.testing.assert_allclose(dets[1].corners, neighbour, atol=1e-4)


def test_two_stacked_parts_of_one_window_are_one_detection():
    top = np.array([[20.0, 10], [44, 10], [44, 50], [20, 50]])
    bottom = np.array([[20.0, 44], [44, 44], [44, 80], [20, 80]])  # overlaps the top part by 6 of its 40 rows
    c, off = peak_maps([((7, 7), top, 0.9), ((14, 7), bottom, 0.8)])
    dets = quad_detections(c, off, None, (96, 96))
    assert len(dets) == 1
    np.testing.assert_allclose(dets[0].corners, top, atol=1e-4)


def test_quad_losses_weigh_the_offsets_per_sample():
    """The offsets' L1 counts on regression cells only, per sample weight: a real photo's box
    (weight 0: centres only, the shipped recipe) adds nothing; the centre loss counts every sample."""
    from fenestra.training.recipes.effwin import quad_losses

    t = torch.zeros(2, 11, 8, 8)
    t[:, 0, 4, 4] = 1.0  # a centre in each sample
    t[:, 9, 4, 4] = 1.0  # its regression cell
    t[:, 1:9, 4, 4] = 0.5  # target offsets
    q = torch.zeros(2, 9, 8, 8)  # predicted offsets 0: L1 = 8 x 0.5 = 4 per cell
    exact_only = quad_losses(q, t, torch.tensor([1.0, 0.0]))
    both = quad_losses(q, t, torch.tensor([1.0, 1.0]))
    assert float(exact_only["quad_offsets"]) == pytest.approx(4.0) and float(both["quad_offsets"]) == pytest.approx(4.0)
    q[1, 1:9, 4, 4] = 0.5  # the second sample now right: only the first's error counts where both weigh
    assert float(quad_losses(q, t, torch.tensor([1.0, 1.0]))["quad_offsets"]) == pytest.approx(2.0)
    assert float(quad_losses(q, t, torch.tensor([0.0, 1.0]))["quad_offsets"]) == pytest.approx(0.0)
    assert float(exact_only["quad_centre"]) == pytest.approx(float(both["quad_centre"]))
