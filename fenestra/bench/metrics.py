"""Error metrics of the benchmark: pure functions, numpy in, floats out (bop_toolkit style).

Every function states shapes and units. Quads are (4, 2) px ordered TL, TR, BR, BL with pixel
centres at integer coordinates (see :mod:`fenestra.conventions`). Poses map the *window frame*
(x along TL->TR, y along BL->TL i.e. up, z outward towards the viewer, origin at the bottom-left
corner) to the OpenCV camera frame.

Missing values: functions that summarise many errors treat NaN as "no estimate" (a failure):
it never counts as recalled and is excluded from medians (reported separately as a rate).
"""
from __future__ import annotations

import numpy as np
from shapely.geometry import Polygon

from fenestra.checks import check_quad, check_rotation
from fenestra.conventions import rotation_error_deg
from fenestra.tolerances import TOL

__all__ = [
    "corner_errors_px", "mean_corner_error_px", "aspect_error_rel", "gt_window_pose",
    "rotation_error_deg", "normal_error_deg", "translation_error_m", "quad_iou", "mask_iou",
    "recall_at", "error_stats", "box_iou_matrix", "reprojection_consistency_px", "plane_distance",
    "relative_size_errors",
]


def corner_errors_px(quad_est: np.ndarray, quad_gt: np.ndarray) -> np.ndarray:
    """Euclidean distance (px) between corresponding corners. (4, 2), (4, 2) -> (4,) px."""
    e = check_quad(quad_est, "quad_est")
    g = check_quad(quad_gt, "quad_gt")
    return np.linalg.norm(e - g, axis=1)


def mean_corner_error_px(quad_est: np.ndarray, quad_gt: np.ndarray) -> float:
    """Mean over the four corners of :func:`corner_errors_px` (px)."""
    return float(corner_errors_px(quad_est, quad_gt).mean())


def aspect_error_rel(aspect_est: float, aspect_gt: float) -> float:
    """Relative aspect-ratio (width/height) error |est - gt| / gt, unitless."""
    if not np.isfinite(aspect_gt) or aspect_gt <= 0:
        raise ValueError(f"aspect_gt must be a positive finite number, got {aspect_gt}")
    if not np.isfinite(aspect_est):
        raise ValueError(f"aspect_est must be finite, got {aspect_est}")
    return float(abs(aspect_est - aspect_gt) / aspect_gt)


def gt_window_pose(R: np.ndarray, t: np.ndarray, corners_world: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Ground-truth window-frame-to-camera pose from the view pose and the GT corners.

    R (3, 3), t (3,) m: the view's world-to-camera pose. corners_world (4, 3) m: TL, TR, BR, BL.
    Window frame: x along TL->TR, y along BL->TL, z = x cross y (outward), origin at BL.
    Returns (R_wc (3, 3), t_wc (3,) m) with X_cam = R_wc @ X_window + t_wc.
    """
    R = check_rotation(R, "R")
    t = np.asarray(t, dtype=np.float64).reshape(3)
    C = np.asarray(corners_world, dtype=np.float64)
    if C.shape != (4, 3):
        raise ValueError(f"corners_world must have shape (4, 3), got {C.shape}")
    x = C[1] - C[0]
    y = C[0] - C[3]
    if np.linalg.norm(x) < 1e-9 or np.linalg.norm(y) < 1e-9:
        raise ValueError(f"corners_world is degenerate (zero width or height): {C.tolist()}")
    x /= np.linalg.norm(x)
    y -= x * (x @ y)  # Gram-Schmidt: exact GT is already orthogonal to well under 1e-6
    y /= np.linalg.norm(y)
    z = np.cross(x, y)
    R_window_to_world = np.stack([x, y, z], axis=1)
    return R @ R_window_to_world, R @ C[3] + t


def normal_error_deg(R_est: np.ndarray, R_gt: np.ndarray) -> float:
    """Angle (deg) between the window normals (third columns, window z in camera) of two poses."""
    n1 = check_rotation(R_est, "R_est")[:, 2]
    n2 = check_rotation(R_gt, "R_gt")[:, 2]
    return float(np.degrees(np.arccos(np.clip(n1 @ n2, -1.0, 1.0))))


def translation_error_m(t_est: np.ndarray, height_used_m: float, t_gt: np.ndarray,
                        height_gt_m: float) -> float:
    """Translation error (m) after fixing the unknown single-image scale with the true height.

    t_est (3,) is in units where the window is ``height_used_m`` tall (the pipeline's scale
    parameter); it is rescaled by height_gt_m / height_used_m before comparing with t_gt (3,) m.
    """
    if not (np.isfinite(height_used_m) and height_used_m > 0):
        raise ValueError(f"height_used_m must be positive, got {height_used_m}")
    if not (np.isfinite(height_gt_m) and height_gt_m > 0):
        raise ValueError(f"height_gt_m must be positive, got {height_gt_m}")
    t_est = np.asarray(t_est, dtype=np.float64).reshape(3)
    t_gt = np.asarray(t_gt, dtype=np.float64).reshape(3)
    return float(np.linalg.norm(t_est * (height_gt_m / height_used_m) - t_gt))


def _polygon(q: np.ndarray) -> Polygon:
    """Shapely polygon of a quad; a self-intersecting (bow-tie) quad is repaired by buffer(0)."""
    p = Polygon(q)
    return p if p.is_valid else p.buffer(0)


def quad_iou(quad_a: np.ndarray, quad_b: np.ndarray) -> float:
    """Intersection over union of two quads' areas (4, 2) px, in [0, 1] (0 if both are empty)."""
    a = _polygon(check_quad(quad_a, "quad_a"))
    b = _polygon(check_quad(quad_b, "quad_b"))
    union = a.union(b).area
    return float(a.intersection(b).area / union) if union > 0 else 0.0


def mask_iou(mask_a: np.ndarray, mask_b: np.ndarray) -> float:
    """Intersection over union of two boolean masks (H, W); 0 if both are empty."""
    a = np.asarray(mask_a, dtype=bool)
    b = np.asarray(mask_b, dtype=bool)
    if a.shape != b.shape or a.ndim != 2:
        raise ValueError(f"masks must be 2-D with equal shapes, got {a.shape} and {b.shape}")
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 0.0


def recall_at(errors: np.ndarray, thresholds: tuple[float, ...] = TOL.recall_thresholds_px
              ) -> dict[float, float]:
    """Fraction of errors (N,) at or below each threshold; NaN (no estimate) counts as a miss.

    Returns {threshold: fraction in [0, 1]}; every fraction is NaN when N == 0.
    """
    e = np.asarray(errors, dtype=np.float64).reshape(-1)
    if e.size == 0:
        return {float(th): float("nan") for th in thresholds}
    ok = np.where(np.isnan(e), np.inf, e)
    return {float(th): float(np.mean(ok <= th)) for th in thresholds}


def error_stats(errors: np.ndarray) -> dict[str, float]:
    """Median, p90, max, mean over the finite errors (N,), plus count n and failure rate.

    ``n`` counts all entries, ``n_valid`` the finite ones; ``fail_rate`` = 1 - n_valid / n.
    Statistics are NaN when no entry is finite.
    """
    e = np.asarray(errors, dtype=np.float64).reshape(-1)
    v = e[np.isfinite(e)]
    out = {"n": int(e.size), "n_valid": int(v.size),
           "fail_rate": float(1.0 - v.size / e.size) if e.size else float("nan")}
    if v.size:
        out.update(median=float(np.median(v)), p90=float(np.percentile(v, 90)),
                   max=float(v.max()), mean=float(v.mean()))
    else:
        out.update(median=float("nan"), p90=float("nan"), max=float("nan"), mean=float("nan"))
    return out


# ---------------------------------------------------------------- little or no ground truth (photos)

def box_iou_matrix(det_boxes: list[np.ndarray], gt_boxes: list[np.ndarray]) -> np.ndarray:
    """Box IoU of every detection box with every ground-truth box: (D, G) float64 in [0, 1]."""
    if not det_boxes or not gt_boxes:
        return np.zeros((len(det_boxes), len(gt_boxes)))
    D, G, inter = _box_intersections(det_boxes, gt_boxes)
    union = _box_area(D)[:, None] + _box_area(G)[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def box_cover_matrix(det_boxes: list[np.ndarray], region_boxes: list[np.ndarray]) -> np.ndarray:
    """Share of every detection box's area inside every region box (intersection / detection
    area, COCO's test against an ``iscrowd`` region): (D, R) float64 in [0, 1]; 0 for an empty box."""
    if not det_boxes or not region_boxes:
        return np.zeros((len(det_boxes), len(region_boxes)))
    D, _, inter = _box_intersections(det_boxes, region_boxes)
    a = _box_area(D)[:, None]
    return np.where(a > 0, inter / np.where(a > 0, a, 1.0), 0.0)


def _box_area(B: np.ndarray) -> np.ndarray:
    return (B[:, 2] - B[:, 0]) * (B[:, 3] - B[:, 1])


def _box_intersections(det_boxes, gt_boxes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(D (n, 4), G (m, 4) as float64 x0 y0 x1 y1, (n, m) areas of their intersections, px^2)."""
    D = np.asarray(det_boxes, dtype=np.float64).reshape(-1, 4)
    G = np.asarray(gt_boxes, dtype=np.float64).reshape(-1, 4)
    iw = np.clip(np.minimum(D[:, None, 2], G[None, :, 2]) - np.maximum(D[:, None, 0], G[None, :, 0]), 0, None)
    ih = np.clip(np.minimum(D[:, None, 3], G[None, :, 3]) - np.maximum(D[:, None, 1], G[None, :, 1]), 0, None)
    return D, G, iw * ih


def reprojection_consistency_px(quad_snapped: np.ndarray, quad_reprojected: np.ndarray) -> float:
    """Mean corner distance (px) between the snapped quad and the rectangle reprojected from the
    estimated pose: how well one rectangle explains the four image corners (no ground truth)."""
    a = check_quad(quad_snapped, "quad_snapped")
    b = check_quad(quad_reprojected, "quad_reprojected")
    return float(np.linalg.norm(a - b, axis=1).mean())


def plane_distance(R: np.ndarray, t: np.ndarray) -> float:
    """Camera-to-window-plane distance |n . t| in the pose's scale units (n = R[:, 2])."""
    return float(abs(np.asarray(R, dtype=np.float64)[:, 2] @ np.asarray(t, dtype=np.float64).reshape(3)))


def relative_size_errors(plane_dists: np.ndarray, true_heights_m: np.ndarray) -> np.ndarray:
    """Relative pane-size error of windows on one plane seen in one photo (no scale needed).

    Each pose is solved with the same height parameter h0, so window i's true height is
    H_i = D / d_i * h0 for the common camera-plane distance D: heights relative to their median
    follow from the plane distances d_i (N,) alone. Returns (N,) |est_i / true_i - 1| with
    est_i = (1/d_i) / median(1/d) and true_i = H_i / median(H); NaN for all when N < 2.
    """
    d = np.asarray(plane_dists, dtype=np.float64).reshape(-1)
    H = np.asarray(true_heights_m, dtype=np.float64).reshape(-1)
    if d.shape != H.shape:
        raise ValueError(f"plane_dists {d.shape} and true_heights_m {H.shape} differ in shape")
    if d.size < 2:
        return np.full(d.size, np.nan)
    if np.any(~np.isfinite(d) | (d <= 0)) or np.any(~np.isfinite(H) | (H <= 0)):
        raise ValueError(f"plane distances and heights must be positive, got {d.tolist()}, {H.tolist()}")
    est = (1.0 / d) / np.median(1.0 / d)
    true = H / np.median(H)
    return np.abs(est / true - 1.0)


def size_errors_m(aspect_est: float, height_est_m: float, size_gt_m: tuple[float, float]) -> tuple[float, float]:
    """(|width error|, |height error|) m of a window reconstructed at metric scale: estimated
    width = aspect_est * height_est_m, height = height_est_m; size_gt_m: the true (width, height) m."""
    w_gt, h_gt = (float(v) for v in size_gt_m)
    h = float(height_est_m)
    return abs(float(aspect_est) * h - w_gt), abs(h - h_gt)


def centre_error_m(R_est: np.ndarray, t_est: np.ndarray, width_est_m: float, height_est_m: float,
                   R_cam: np.ndarray, t_cam: np.ndarray, corners_world: np.ndarray) -> float:
    """Distance (m) between a reconstructed window's centre and the true one, both in the camera
    frame: estimated centre = t_est + R_est @ (w/2, h/2, 0) (window frame origin at its bottom-left
    corner, pipeline.types.WindowResult); true centre = R_cam @ mean(corners_world) + t_cam (the
    camera's world-to-camera pose, corners (4, 3) m)."""
    c_est = np.asarray(t_est, dtype=np.float64).reshape(3) + np.asarray(R_est, dtype=np.float64) @ np.array(
        [float(width_est_m) / 2.0, float(height_est_m) / 2.0, 0.0])
    c_gt = np.asarray(R_cam, dtype=np.float64) @ np.asarray(corners_world, dtype=np.float64).mean(axis=0) + np.asarray(
        t_cam, dtype=np.float64).reshape(3)
    return float(np.linalg.norm(c_est - c_gt))
