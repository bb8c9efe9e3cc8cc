"""bench.metrics and bench.matching against values computed by hand (synthetic inputs)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fenestra.bench import matching, metrics
from fenestra.coco import coco_result, gt_annotation
from fenestra.masks import SparseMask, instance_masks
from fenestra.conventions import look_at, make_K, project


def _rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_x(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


SQUARE = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])


def test_corner_errors_hand_values():
    # shifts of (3, 4) -> 5 px, 0, (0, 2) -> 2, (-1, 0) -> 1
    est = SQUARE + np.array([[3.0, 4.0], [0.0, 0.0], [0.0, 2.0], [-1.0, 0.0]])
    np.testing.assert_allclose(metrics.corner_errors_px(est, SQUARE), [5.0, 0.0, 2.0, 1.0])
    assert metrics.mean_corner_error_px(est, SQUARE) == pytest.approx(2.0)


def test_corner_errors_bad_shape_names_value():
    with pytest.raises(ValueError, match="quad_est.*\\(3, 2\\)"):
        metrics.corner_errors_px(SQUARE[:3], SQUARE)
    with pytest.raises(ValueError, match="quad_gt.*non-finite"):
        metrics.corner_errors_px(SQUARE, SQUARE * np.nan)


def test_aspect_error():
    assert metrics.aspect_error_rel(1.1, 1.0) == pytest.approx(0.1)
    assert metrics.aspect_error_rel(1.5, 2.0) == pytest.approx(0.25)
    with pytest.raises(ValueError, match="aspect_gt.*-1"):
        metrics.aspect_error_rel(1.0, -1.0)


def test_gt_window_pose_front_view():
    # A 1.2 m wide, 1.5 m tall window in the wall plane y = 0 (outward normal -y), seen by a
    # camera at y = -5 looking +y. Window x (world +x) -> camera x; window y (world +z) ->
    # camera -y; window z (world -y) -> camera -z.
    bl = np.array([2.0, 0.0, 1.0])
    C = np.array([bl + [0, 0, 1.5], bl + [1.2, 0, 1.5], bl + [1.2, 0, 0], bl])
    R, t = look_at(eye=[2.6, -5.0, 1.75], target=[2.6, 0.0, 1.75])
    R_wc, t_wc = metrics.gt_window_pose(R, t, C)
    np.testing.assert_allclose(R_wc, np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    # BL is 0.6 m left of and 0.75 m below the optical axis, 5 m ahead: camera (-0.6, 0.75, 5)
    np.testing.assert_allclose(t_wc, [-0.6, 0.75, 5.0], atol=1e-12)
    # and the pose reproduces the corners: window-frame corners -> same pixels as the world ones
    K = make_K(500.0, cx=320.0, cy=240.0)
    local = np.array([[0, 1.5, 0], [1.2, 1.5, 0], [1.2, 0, 0], [0, 0, 0]], dtype=float)
    np.testing.assert_allclose(project(K, R_wc, t_wc, local), project(K, R, t, C), atol=1e-9)


def test_rotation_and_normal_errors():
    R_gt = np.diag([1.0, -1.0, -1.0])
    # rotating about the window normal (camera z) by 7 deg: 7 deg geodesic, 0 normal error
    R_spin = _rot_z(7.0) @ R_gt
    assert metrics.rotation_error_deg(R_spin, R_gt) == pytest.approx(7.0)
    assert metrics.normal_error_deg(R_spin, R_gt) == pytest.approx(0.0, abs=1e-6)
    # tilting about camera x by 12 deg: both errors are 12 deg
    R_tilt = _rot_x(12.0) @ R_gt
    assert metrics.rotation_error_deg(R_tilt, R_gt) == pytest.approx(12.0)
    assert metrics.normal_error_deg(R_tilt, R_gt) == pytest.approx(12.0)
    with pytest.raises(ValueError, match="R_est is not a rotation"):
        metrics.normal_error_deg(2 * R_gt, R_gt)


def test_translation_error_rescales_by_true_height():
    # pose solved with a 1 m scale parameter; the true window is 1.5 m tall: t scales by 1.5
    t_gt = np.array([0.3, -0.6, 6.0])
    assert metrics.translation_error_m(t_gt / 1.5, 1.0, t_gt, 1.5) == pytest.approx(0.0)
    # 4 m along z at unit scale becomes 6 m, off by 0.5 m from 6.5 m
    assert metrics.translation_error_m([0, 0, 4.0], 1.0, [0, 0, 6.5], 1.5) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="height_used_m.*0"):
        metrics.translation_error_m(t_gt, 0.0, t_gt, 1.5)


def test_quad_iou_hand_values():
    shifted = SQUARE + [5.0, 0.0]  # overlap 50, union 150
    assert metrics.quad_iou(SQUARE, shifted) == pytest.approx(1 / 3)
    assert metrics.quad_iou(SQUARE, SQUARE) == pytest.approx(1.0)
    assert metrics.quad_iou(SQUARE, SQUARE + 100.0) == 0.0
    bowtie = SQUARE[[0, 1, 3, 2]]  # self-intersecting: repaired, not crashing
    assert 0.0 <= metrics.quad_iou(bowtie, SQUARE) <= 1.0


def test_mask_iou_hand_values():
    a = np.zeros((10, 10), bool)
    b = np.zeros((10, 10), bool)
    a[:, :6] = True  # 60 px
    b[:, 4:] = True  # 60 px, overlap 20 -> IoU 20 / 100
    assert metrics.mask_iou(a, b) == pytest.approx(0.2)
    assert metrics.mask_iou(np.zeros_like(a), np.zeros_like(a)) == 0.0
    with pytest.raises(ValueError, match="\\(10, 10\\) and \\(5, 5\\)"):
        metrics.mask_iou(a, np.zeros((5, 5), bool))


def test_recall_and_stats_treat_nan_as_failure():
    e = np.array([0.5, 1.0, 1.5, 3.0, 20.0, np.nan, np.nan, 4.0, 0.1, 9.0])
    r = metrics.recall_at(e, (1.0, 2.0, 5.0, 10.0))
    assert r == {1.0: pytest.approx(0.3), 2.0: pytest.approx(0.4), 5.0: pytest.approx(0.6),
                 10.0: pytest.approx(0.7)}
    s = metrics.error_stats(e)
    finite = [0.1, 0.5, 1.0, 1.5, 3.0, 4.0, 9.0, 20.0]
    assert s["n"] == 10 and s["n_valid"] == 8 and s["fail_rate"] == pytest.approx(0.2)
    assert s["median"] == pytest.approx((1.5 + 3.0) / 2)
    assert s["max"] == 20.0
    # numpy's linear p90 of 8 sorted values: position 0.9 * 7 = 6.3 -> 9 + 0.3 * (20 - 9)
    assert s["p90"] == pytest.approx(9.0 + 0.3 * 11.0)
    assert math.isnan(metrics.error_stats([np.nan])["median"])


def _box_mask(x0, y0, x1, y1, shape=(40, 60)):
    m = np.zeros(shape, bool)
    m[y0:y1, x0:x1] = True
    return m


def test_matching_hungarian_one_to_one():
    gt = [_box_mask(0, 0, 10, 10), _box_mask(20, 0, 30, 10), _box_mask(40, 20, 50, 30)]
    det = [
        _box_mask(21, 0, 31, 10),  # GT 1, IoU 90/110
        _box_mask(0, 0, 10, 10),  # GT 0 exactly
        _box_mask(0, 0, 10, 9),  # a duplicate of GT 0 (IoU 0.9): loses to the exact one
        _box_mask(40, 20, 45, 25),  # GT 2 with IoU 25/100 < 0.5: not a match
    ]
    iou = matching.iou_matrix(det, gt)
    assert iou.shape == (4, 3)
    assert iou[0, 1] == pytest.approx(90 / 110)
    assert iou[3, 2] == pytest.approx(0.25)
    m = matching.match(iou)
    assert [(d, g) for d, g, _ in m.pairs] == [(1, 0), (0, 1)]
    assert m.missed_gt == (2,)
    assert m.false_positives == (2, 3)
    assert m.det_for_gt()[1][0] == 0


def test_matching_prefers_global_optimum_over_greedy():
    # greedy on the best pair (0.9) would leave 0.0 for the other; Hungarian takes 0.8 + 0.7
    iou = np.array([[0.9, 0.8], [0.7, 0.0]])
    m = matching.match(iou)
    assert sorted((d, g) for d, g, _ in m.pairs) == [(0, 1), (1, 0)]


def test_matching_empty_and_bad_input():
    m = matching.match_masks([], [_box_mask(0, 0, 5, 5)])
    assert m.pairs == () and m.missed_gt == (0,) and m.false_positives == ()
    with pytest.raises(ValueError, match="det_masks\\[0\\] has shape \\(5, 5\\)"):
        matching.iou_matrix([np.zeros((5, 5), bool)], [_box_mask(0, 0, 5, 5)])
    with pytest.raises(ValueError, match="min_iou.*1.5"):
        matching.match(np.zeros((1, 1)), 1.5)


def test_detection_ap_hand_values():
    """COCO AP on hand-made masks: exact detections -> 1; half the windows found -> 51/101
    (COCO's 101-point interpolation: precision 1 up to recall 0.5, 0 beyond)."""
    from fenestra.bench.detection_ap import coco_ap

    gts, dts = [], []
    for i in range(4):
        m = SparseMask.from_dense(_box_mask(5 * i, 0, 5 * i + 4, 6))
        gts.append(gt_annotation("v", m.rle(), m.box(), m.area))
        dts.append(coco_result("v", 1.0, m.box(), m.rle()))
    assert gts[1]["bbox"] == [5.0, 0.0, 4.0, 6.0]  # COCO (pixel edges at integers) of columns 5-8, rows 0-5
    assert coco_ap(gts, dts)["segm_AP"] == pytest.approx(1.0)
    assert coco_ap(gts, dts)["bbox_AP"] == pytest.approx(1.0)
    assert coco_ap(gts, dts[:2])["segm_AP"] == pytest.approx(51 / 101)
    assert coco_ap(gts, [])["segm_AP"] == 0.0


def _dense_iou(det: list[np.ndarray], gt: list[np.ndarray]) -> np.ndarray:
    """Reference IoU: full-image masks, every pair, float32 ratio (the implementation replaced)."""
    out = np.zeros((len(det), len(gt)))
    for i, d in enumerate(det):
        for j, g in enumerate(gt):
            inter, union = np.sum(d & g), np.sum(d | g)
            out[i, j] = np.float32(inter) / np.float32(max(union, 1)) if union else 0.0
    return out


def test_sparse_iou_equals_dense_reference_bit_for_bit():
    """Random blobby masks, overlapping and not, empty ones included: identical IoU to the last bit."""
    rng = np.random.default_rng(3)
    H, W = 90, 120
    inst = np.zeros((H, W), np.int32)
    for k in range(1, 9):
        x0, y0 = rng.integers(0, W - 10), rng.integers(0, H - 10)
        inst[y0:y0 + rng.integers(3, 30), x0:x0 + rng.integers(3, 40)] = k
    inst[rng.random((H, W)) < 0.02] = 0  # holes
    ids = [1, 2, 3, 4, 5, 6, 7, 8, 40]  # 40 is absent from the map: an empty mask
    gt_dense = [inst == k for k in ids]
    det_dense = [np.roll(m, (int(rng.integers(-4, 5)), int(rng.integers(-4, 5))), axis=(0, 1))
                 for m in gt_dense[:6]] + [np.zeros((H, W), bool), rng.random((H, W)) < 0.3]
    gt_sparse = instance_masks(inst, ids)
    assert [m.area for m in gt_sparse] == [int(m.sum()) for m in gt_dense]
    for s, d in zip(gt_sparse, gt_dense):
        assert np.array_equal(s.dense(), d)
    ref = _dense_iou(det_dense, gt_dense)
    got = matching.iou_matrix(det_dense, gt_sparse)
    assert np.array_equal(got, ref)
    assert np.array_equal(matching.iou_matrix(det_dense, gt_dense), ref)
    assert (ref > 0).sum() >= 6  # the test exercises overlapping pairs, not only empty ones


def test_instance_masks_bad_input():
    with pytest.raises(ValueError, match="ids must be >= 1.*0"):
        instance_masks(np.zeros((4, 4), np.int32), [0, 1])
    with pytest.raises(ValueError, match="integer map"):
        instance_masks(np.zeros((4, 4), np.float32), [1])
