"""Metrics of the real bench that need little or no ground truth (pure functions, numpy in).

Boxes are (4,) x0 y0 x1 y1 px, quads (4, 2) px TL TR BR BL (fenestra.conventions); poses map
the window frame (z = outward normal, origin at a corner, height = the pose's scale parameter)
to the camera frame.
"""
from __future__ import annotations

import numpy as np

from fenestra.conventions import check_quad


def box_iou_matrix(det_boxes: list[np.ndarray], gt_boxes: list[np.ndarray]) -> np.ndarray:
    """Box IoU of every detection box with every ground-truth box: (D, G) float64 in [0, 1]."""
    if not det_boxes or not gt_boxes:
        return np.zeros((len(det_boxes), len(gt_boxes)))
    D = np.asarray(det_boxes, dtype=np.float64).reshape(-1, 4)
    G = np.asarray(gt_boxes, dtype=np.float64).reshape(-1, 4)
    iw = np.clip(np.minimum(D[:, None, 2], G[None, :, 2]) - np.maximum(D[:, None, 0], G[None, :, 0]), 0, None)
    ih = np.clip(np.minimum(D[:, None, 3], G[None, :, 3]) - np.maximum(D[:, None, 1], G[None, :, 1]), 0, None)
    inter = iw * ih
    area = lambda B: (B[:, 2] - B[:, 0]) * (B[:, 3] - B[:, 1])  # noqa: E731
    union = area(D)[:, None] + area(G)[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


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
