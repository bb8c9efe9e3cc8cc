"""Detector registry, oracles, COCO evaluation and the shipped default detector."""

import numpy as np
import pytest

from fenestra.coco import coco_scores
from fenestra.errors import FenestraError
from fenestra.pipeline.detectors import DETECTORS, DEFAULT_WEIGHTS, DegradeConfig, detect
from fenestra.pipeline.types import Detection
from toy_data import write_toy_dataset
from fenestra.training.evaluate import best_overlaps, detection_to_coco, evaluate, rescored_by_overlap


def _rect_instances(H=480, W=640):
    """Instance map with hand-placed rectangles: id -> (row0, row1, col0, col1) inclusive."""
    rects = {1: (100, 219, 50, 129), 2: (120, 199, 300, 459), 7: (300, 339, 500, 529)}
    inst = np.zeros((H, W), np.uint16)
    for k, (r0, r1, c0, c1) in rects.items():
        inst[r0:r1 + 1, c0:c1 + 1] = k
    return inst, rects


def _iou(a, b):
    return (a & b).sum() / (a | b).sum()


def test_registry_names():
    assert {"oracle", "oracle-degraded", "default", "maskrcnn"} <= set(DETECTORS)
    with pytest.raises(ValueError, match="unknown detector 'nope'"):
        detect("nope", np.zeros((20, 20, 3), np.uint8))


def test_detectors_that_need_the_instance_map_declare_it_and_see_full_resolution():
    """A detector declaring needs_instances refuses to run without the map and gets the image at
    full size even beyond LIMITS.detector_max_side_px: its masks cover the exact rectangles."""
    from fenestra.conventions import LIMITS
    from fenestra.pipeline.detectors import DetectorEntry

    assert all(isinstance(e, DetectorEntry) for e in DETECTORS.values())
    needing = [n for n, e in DETECTORS.items() if e.needs_instances]
    assert needing and len(needing) < len(DETECTORS)
    H, W = LIMITS.detector_max_side_px + 76, LIMITS.detector_max_side_px + 476
    inst = np.zeros((H, W), np.uint16)
    inst[100:300, 200:500] = 1
    inst[H - 200:H - 50, W - 400:W - 100] = 2
    img = np.zeros((H, W, 3), np.uint8)
    for name in needing:
        with pytest.raises(ValueError, match=f"{name}.*needs instances"):
            detect(name, img)
        dets = detect(name, img, score_threshold=0.0, instances=inst)
        assert len(dets) == 2 and all(d.mask.shape == (H, W) and d.origin == (0, 0) for d in dets)
        assert all(max(_iou(d.mask, inst == k) for d in dets) > 0.8 for k in (1, 2))


def test_bad_inputs_are_named():
    inst, _ = _rect_instances()
    with pytest.raises(ValueError, match="uint8"):
        detect("oracle", np.zeros((480, 640, 3), np.float32), instances=inst)
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        detect("oracle", np.zeros((480, 640), np.uint8), instances=inst)
    with pytest.raises(ValueError, match="instances"):
        detect("oracle", np.zeros((480, 640, 3), np.uint8))
    with pytest.raises(ValueError, match="does not match"):
        detect("oracle", np.zeros((400, 640, 3), np.uint8), instances=inst)
    with pytest.raises(ValueError, match="score_threshold"):
        detect("oracle", np.zeros((480, 640, 3), np.uint8), score_threshold=2.0, instances=inst)
    with pytest.raises(ValueError, match="mask_res"):
        DegradeConfig(mask_res=2)


def test_oracle_is_exact():
    inst, rects = _rect_instances()
    dets = detect("oracle", np.zeros((480, 640, 3), np.uint8), instances=inst)
    assert len(dets) == 3
    for det, (k, (r0, r1, c0, c1)) in zip(dets, sorted(rects.items())):
        assert isinstance(det, Detection) and det.score == 1.0 and det.instance_id == k
        assert det.mask.shape == (480, 640) and det.mask.dtype == bool and det.origin == (0, 0)
        assert det.mask.sum() == (r1 - r0 + 1) * (c1 - c0 + 1)
        assert det.mask[r0:r1 + 1, c0:c1 + 1].all()
        # Box on the pixel-edge outline: pixel centres at integers, so edges at +-0.5.
        np.testing.assert_array_equal(det.box, [c0 - 0.5, r0 - 0.5, c1 + 0.5, r1 + 0.5])


def test_oracle_degraded_iou_range_and_determinism():
    inst, rects = _rect_instances()
    img = np.zeros((480, 640, 3), np.uint8)
    a = detect("oracle-degraded", img, instances=inst, config=DegradeConfig(seed=3))
    b = detect("oracle-degraded", img, instances=inst, config=DegradeConfig(seed=3))
    c = detect("oracle-degraded", img, instances=inst, config=DegradeConfig(seed=4))
    assert len(a) == len(b) == len(c) == 3
    ious = []
    for da, db, dc, k in zip(a, b, c, sorted(rects)):
        np.testing.assert_array_equal(da.mask, db.mask)
        assert not np.array_equal(da.mask, dc.mask)
        ious.append(_iou(da.mask, inst == k))
        # Rounded corners: the true corner pixel is lost more often than not; check the mask is
        # not a plain rectangle (its area differs from its box's area).
        x0, y0, x1, y1 = da.box
        assert da.mask.sum() < (x1 - x0) * (y1 - y0)
    # Documented range (DegradeConfig defaults): IoU with the true void in [0.80, 0.99).
    assert all(0.80 <= v < 0.99 for v in ious), ious
    # No degradation at all gives the exact rectangle back.
    exact = detect("oracle-degraded", img, instances=inst,
                   config=DegradeConfig(box_jitter=0, box_margin=0.1, blur_cells=0, edge_noise=0))
    assert min(_iou(d.mask, inst == k) for d, k in zip(exact, sorted(rects))) > 0.97


def test_coco_eval_of_oracle_is_100(tmp_path):
    ds = write_toy_dataset(tmp_path / "toy", n_views=3, seed=5)
    r = evaluate("oracle", ds)
    assert r["n_gt"] == 9 and r["n_det"] == 9
    for iou in ("bbox", "segm"):  # fractions (fenestra.coco.coco_scores)
        assert r[iou]["AP"] == pytest.approx(1.0)
        assert r[iou]["AP75"] == pytest.approx(1.0)
    # The degraded oracle is found at IoU 0.5 but loses AP at strict thresholds.
    d = evaluate("oracle-degraded", ds)
    assert d["segm"]["AP50"] == pytest.approx(1.0)
    assert d["segm"]["AP"] < 1.0 and d["bbox"]["AP"] < 1.0


def test_recall_and_perfect_ranking_against_hand_computed_ap():
    """3 windows in 2 images; exact masks for two (scores 0.8, 0.6), one missed, and a false
    positive scored 0.9. Ranked FP, TP, TP: precision envelope 2/3 up to recall 2/3, so COCO's
    101-point AP = 67 * (2/3) / 101 at every IoU; ranked by overlap: 67 * 1 / 101; R50 = 2/3."""
    from lab.tune import instance_maps_to_coco

    def rect(r0, c0):
        m = np.zeros((60, 80), bool)
        m[r0:r0 + 10, c0:c0 + 12] = True
        return m

    inst1, inst2 = np.zeros((60, 80), np.uint16), np.zeros((60, 80), np.uint16)
    inst1[rect(5, 5)] = 1
    inst2[rect(5, 5)], inst2[rect(30, 40)] = 1, 2
    gt = instance_maps_to_coco([inst1, inst2])
    dets = [(1, rect(5, 5), 0.6), (1, rect(40, 60), 0.9), (2, rect(30, 40), 0.8)]
    res = [detection_to_coco(Detection(mask=m, box=np.array([0, 0, 1, 1], float), score=s), i)
           for i, m, s in dets]
    overlaps = best_overlaps(gt, res)
    assert np.allclose(overlaps, [1.0, 0.0, 1.0])
    got = coco_scores(gt, res, ("segm",))
    best = coco_scores(gt, rescored_by_overlap(res, overlaps), ("segm",))
    assert got["segm_AP"] == pytest.approx(67 * (2 / 3) / 101, abs=1e-8)
    assert got["segm_AP50"] == pytest.approx(got["segm_AP"], abs=1e-11)
    assert best["segm_AP"] == pytest.approx(67 / 101, abs=1e-8)
    assert got["segm_R50"] == pytest.approx(2 / 3) and best["segm_R50"] == pytest.approx(2 / 3)


def test_default_detector_loads_shipped_weights():
    assert DEFAULT_WEIGHTS.is_file(), f"shipped weights missing: {DEFAULT_WEIGHTS}"
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (480, 640, 3), dtype=np.uint8)
    img[100:220, 50:130] = 30  # a dark void-like rectangle on a noisy wall
    dets = detect("default", img, score_threshold=0.0)
    assert isinstance(dets, list)
    for d in dets:
        assert isinstance(d, Detection)
        assert d.mask.shape == (480, 640) and d.mask.dtype == bool and d.mask.any()
        assert d.box.shape == (4,) and 0.0 <= d.score <= 1.0
        ys, xs = np.nonzero(d.mask)
        np.testing.assert_array_equal(d.box, [xs.min() - 0.5, ys.min() - 0.5, xs.max() + 0.5, ys.max() + 0.5])
    scores = [d.score for d in dets]
    assert scores == sorted(scores, reverse=True)


def test_maskrcnn_without_weights_says_how_to_train(tmp_path):
    with pytest.raises(FenestraError, match="fenestra train"):
        detect("maskrcnn", np.zeros((64, 64, 3), np.uint8), weights=tmp_path / "missing.pt")


def test_coco_eval_of_oracle_on_real_renders_is_100(tmp_path):
    """Real IFC house, real raster renders (renders.dataset), real COCOeval: the oracle scores 1 (100 %)."""
    from fenestra.renders.dataset import DatasetConfig, render_dataset
    from fenestra.renders.sampler import SamplerConfig

    ds = render_dataset(DatasetConfig(scene="fzk-haus", n_views=3, seed=11, out_root=str(tmp_path),
                                      sampler=SamplerConfig(width=320, height=240)), progress=False)
    r = evaluate("oracle", ds)
    assert r["n_images"] == 3 and r["n_gt"] >= 3 and r["n_det"] == r["n_gt"]
    assert r["bbox"]["AP"] == pytest.approx(1.0) and r["segm"]["AP"] == pytest.approx(1.0)
    d = evaluate("oracle-degraded", ds)
    assert d["segm"]["AP"] < 1.0


def test_default_detector_finds_windows_in_fresh_renders(tmp_path):
    """Shipped weights on new views (new cameras and look) of the held-out house, real COCOeval."""
    from fenestra.renders.dataset import DatasetConfig, render_dataset

    ds = render_dataset(DatasetConfig(scene="samplehouse4", n_views=6, seed=777, out_root=str(tmp_path)),
                        progress=False)
    r = evaluate("default", ds)
    assert r["n_gt"] >= 6
    assert r["segm"]["AP50"] >= 0.5, r["segm"]


def test_large_photo_masks_come_back_at_full_resolution():
    """A detection on the 4x downscaled copy maps to a crop of the full-size image covering the
    same rectangle (within the half network pixel the resize can move an edge by)."""
    from fenestra.pipeline.detectors import full_resolution, input_scale
    from fenestra.pipeline.types import Detection

    assert input_scale((4000, 6000)) == pytest.approx(1024 / 6000) and input_scale((480, 640)) == 1.0
    small = np.zeros((100, 150), bool)
    small[20:40, 30:80] = True  # full size: rows 80..159, columns 120..319
    d = full_resolution(Detection(small, np.array([29.5, 19.5, 79.5, 39.5]), 0.9), 0.25, (400, 600))
    full = np.zeros((400, 600), bool)
    h, w = d.mask.shape
    full[d.origin[1]:d.origin[1] + h, d.origin[0]:d.origin[0] + w] = d.mask
    want = np.zeros((400, 600), bool)
    want[80:160, 120:320] = True
    assert _iou(full, want) > 0.97 and h * w < 0.1 * full.size
    np.testing.assert_allclose(d.box, [119.5, 79.5, 319.5, 159.5])  # pixel edges map by 1 / scale


def test_large_photo_resize_and_map_back_by_hand():
    """A 3000x2000 photo is seen at 1024x683 (scale 1024 / 3000, so 1 / scale = 2.9296875 exactly);
    a detection on that copy (mask, box, corners) maps back to the numbers worked out by hand:
    points by (v + 0.5) / scale - 0.5, and full pixel j inside iff its centre, at small coordinate
    (j + 0.5) scale - 0.5, interpolates to >= 0.5 between the mask's edge pixels. The same detection
    given sparse (a crop at an origin) maps to the same result."""
    import dataclasses

    from fenestra.pipeline.detectors import downscale, full_resolution, input_scale

    H, W = 2000, 3000
    s = input_scale((H, W))
    assert s == 1024 / 3000 and 1 / s == pytest.approx(2.9296875, abs=1e-12)
    image = np.zeros((H, W, 3), np.uint8)
    image[293:586, 586:1172] = 255  # the full-size void (rows 293..585, columns 586..1171)
    small_image = downscale(image, s)
    assert small_image.shape == (683, 1024, 3)
    small = np.zeros((683, 1024), bool)
    small[100:200, 200:400] = True  # pixel edges x 200..400, y 100..200 on the small image
    assert (small_image[101:199, 201:399] == 255).all() and (small_image[small == 0] < 128).all()
    box = np.array([199.5, 99.5, 399.5, 199.5])
    corners = np.array([[199.5, 99.5], [399.5, 99.5], [399.5, 199.5], [199.5, 199.5]])  # TL TR BR BL
    det = Detection(small, box, 0.9, corners=corners)
    full = full_resolution(det, s, (H, W))

    k = 3000 / 1024  # 1 / scale: pixel edges e map to e k, centres c to (c + 0.5) k - 0.5
    x0, y0, x1, y1 = 200 * k - 0.5, 100 * k - 0.5, 400 * k - 0.5, 200 * k - 0.5
    np.testing.assert_allclose(full.box, [x0, y0, x1, y1], atol=1e-9)
    np.testing.assert_allclose(full.box, [585.4375, 292.46875, 1171.375, 585.4375], atol=1e-9)
    np.testing.assert_allclose(full.corners, [[x0, y0], [x1, y0], [x1, y1], [x0, y1]], atol=1e-9)
    assert full.score == 0.9 and full.label == "window"

    # mask: rows ceil(y0)..floor(y1) = 293..585, columns ceil(x0)..floor(x1) = 586..1171, less at
    # most its four corner pixels (there the two edges' bilinear weights multiply to < 0.5)
    (ox, oy), (h, w) = full.origin, full.mask.shape
    assert 0 <= ox and 0 <= oy and ox + w <= W and oy + h <= H and h * w < 0.04 * H * W  # sparse
    dense = np.zeros((H, W), bool)
    dense[oy:oy + h, ox:ox + w] = full.mask
    want = np.zeros((H, W), bool)
    want[293:586, 586:1172] = True
    assert not (dense & ~want).any()
    missing = np.argwhere(want & ~dense)
    assert len(missing) <= 4 and all(r in (293, 585) and c in (586, 1171) for r, c in missing)

    crop = dataclasses.replace(det, mask=small[90:210, 150:420], origin=(150, 90))
    again = full_resolution(crop, s, (H, W))
    assert again.origin == full.origin and np.array_equal(again.mask, full.mask)
    np.testing.assert_allclose(again.corners, full.corners)
    assert full_resolution(dataclasses.replace(det, corners=None), s, (H, W)).corners is None


def test_learned_detector_on_a_large_photo_returns_sparse_full_resolution_masks():
    """The shipped detector on a 3000x2000 photo (resized for the network): every drawn window is
    found, and each detection is a crop inside the image lying within one window's frame (a window
    split at its mullion counts, and so does a strip beside a pane, as long as every frame has a
    detection of a pane or more: the test is about mapping back, not the network), with its box on
    the crop's outline and its corners (if the detector predicts them) inside that frame."""
    import cv2

    from fenestra.masks import SparseMask

    H, W = 2000, 3000
    image = np.empty((H, W, 3), np.uint8)
    image[:] = (200, 170, 140)
    image = np.clip(image + np.random.default_rng(0).normal(0, 6, image.shape), 0, 255).astype(np.uint8)
    frames = []  # (x0, y0, x1, y1) pixel edges of each white frame
    for r in range(3):
        for c in range(5):
            y, x = 250 + r * 600, 200 + c * 560
            cv2.rectangle(image, (x - 30, y - 30), (x + 330, y + 430), (245, 245, 240), -1)
            cv2.rectangle(image, (x, y), (x + 300, y + 400), (40, 50, 70), -1)
            cv2.line(image, (x + 150, y), (x + 150, y + 400), (245, 245, 240), 16)
            frames.append((x - 30, y - 30, x + 331, y + 431))
    dets = detect("default", image)
    assert len(frames) <= len(dets) <= 2 * len(frames)
    matched = set()
    for d in dets:
        (ox, oy), (h, w) = d.origin, d.mask.shape
        assert 0 <= ox and 0 <= oy and ox + w <= W and oy + h <= H and h * w < 0.05 * H * W
        m = SparseMask.from_crop(d.mask, d.origin, (H, W))
        np.testing.assert_allclose(d.box, m.box(), atol=3.0)  # network px are ~3 full px
        cx, cy = (m.c0 + m.c1) / 2, (m.r0 + m.r1) / 2
        k = next(i for i, (a, b, e, f) in enumerate(frames) if a <= cx < e and b <= cy < f)
        a, b, e, f = frames[k]
        inside = max(0, min(m.c1, e) - max(m.c0, a)) * max(0, min(m.r1, f) - max(m.r0, b))
        assert inside >= 0.9 * (m.c1 - m.c0) * (m.r1 - m.r0)  # the crop lies within that frame
        if d.corners is not None:
            assert np.all((d.corners >= [a - 15, b - 15]) & (d.corners <= [e + 15, f + 15])), d.corners
        if (m.c1 - m.c0) * (m.r1 - m.r0) > 0.3 * (e - a) * (f - b):  # at least one pane of it
            matched.add(k)
    assert len(matched) == len(frames)  # every frame has a detection of a pane or more (a strip may come too)
