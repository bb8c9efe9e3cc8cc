"""Detector registry, oracles, COCO evaluation and the shipped default detector."""

import numpy as np
import pytest

from fenestra.data import coco_scores
from fenestra.errors import FenestraError
from pipeline.detectors import DETECTORS, DEFAULT_WEIGHTS, DegradeConfig, detect
from pipeline.types import Detection
from toy_data import write_toy_dataset
from training.evaluate import best_overlaps, detection_to_coco, evaluate, rescored_by_overlap


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
    from pipeline.detectors import DetectorEntry

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
    for iou in ("bbox", "segm"):  # fractions (fenestra.data.coco_scores)
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
    from training.tune import instance_maps_to_coco

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
    from renders.dataset import DatasetConfig, render_dataset
    from renders.sampler import SamplerConfig

    ds = render_dataset(DatasetConfig(scene="fzk-haus", n_views=3, seed=11, out_root=str(tmp_path),
                                      sampler=SamplerConfig(width=320, height=240)), progress=False)
    r = evaluate("oracle", ds)
    assert r["n_images"] == 3 and r["n_gt"] >= 3 and r["n_det"] == r["n_gt"]
    assert r["bbox"]["AP"] == pytest.approx(1.0) and r["segm"]["AP"] == pytest.approx(1.0)
    d = evaluate("oracle-degraded", ds)
    assert d["segm"]["AP"] < 1.0


def test_default_detector_finds_windows_in_fresh_renders(tmp_path):
    """Shipped weights on new views (new cameras and look) of the held-out house, real COCOeval."""
    from renders.dataset import DatasetConfig, render_dataset

    ds = render_dataset(DatasetConfig(scene="samplehouse4", n_views=6, seed=777, out_root=str(tmp_path)),
                        progress=False)
    r = evaluate("default", ds)
    assert r["n_gt"] >= 6
    assert r["segm"]["AP50"] >= 0.5, r["segm"]


def test_large_photo_masks_come_back_at_full_resolution():
    """A detection on the 4x downscaled copy maps to a crop of the full-size image covering the
    same rectangle (within the half network pixel the resize can move an edge by)."""
    from pipeline.detectors import full_resolution, input_scale
    from pipeline.types import Detection

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
