"""One-to-one matching of detections to ground-truth windows by mask IoU (Hungarian).

A detection and a ground-truth window match when the assignment that maximises the total IoU
pairs them and their IoU is at least ``TOL.match_iou``. Ground-truth windows left unmatched are
"missed"; detections left unmatched are false positives.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from fenestra.conventions import TOL


@dataclass(frozen=True)
class Matching:
    """Result of :func:`match`.

    pairs: (det_index, gt_index, iou) for each accepted match, sorted by gt_index.
    missed_gt: indices of ground-truth windows without a detection.
    false_positives: indices of detections without a ground-truth window.
    """

    pairs: tuple[tuple[int, int, float], ...]
    missed_gt: tuple[int, ...]
    false_positives: tuple[int, ...]

    def det_for_gt(self) -> dict[int, tuple[int, float]]:
        """{gt_index: (det_index, iou)} of the accepted matches."""
        return {g: (d, iou) for d, g, iou in self.pairs}


def iou_matrix(det_masks: list[np.ndarray], gt_masks: list[np.ndarray]) -> np.ndarray:
    """Mask IoU of every detection with every ground-truth window.

    det_masks: D masks (H, W) bool; gt_masks: G masks (H, W) bool, all the same shape.
    Returns (D, G) float64 in [0, 1].
    """
    if not det_masks or not gt_masks:
        return np.zeros((len(det_masks), len(gt_masks)))
    shape = np.asarray(gt_masks[0]).shape
    for name, masks in (("det_masks", det_masks), ("gt_masks", gt_masks)):
        for i, m in enumerate(masks):
            if np.asarray(m).shape != shape:
                raise ValueError(f"{name}[{i}] has shape {np.asarray(m).shape}, expected {shape}")
    D = np.stack([np.asarray(m, dtype=bool).reshape(-1) for m in det_masks]).astype(np.float32)
    G = np.stack([np.asarray(m, dtype=bool).reshape(-1) for m in gt_masks]).astype(np.float32)
    inter = D @ G.T
    union = D.sum(1)[:, None] + G.sum(1)[None, :] - inter
    return np.where(union > 0, inter / np.maximum(union, 1), 0.0).astype(np.float64)


def match(iou: np.ndarray, min_iou: float = TOL.match_iou) -> Matching:
    """Hungarian one-to-one assignment on an IoU matrix (D, G); keep pairs with IoU >= min_iou."""
    iou = np.asarray(iou, dtype=np.float64)
    if iou.ndim != 2:
        raise ValueError(f"iou must be a 2-D (detections, gt) matrix, got shape {iou.shape}")
    if not 0.0 < min_iou <= 1.0:
        raise ValueError(f"min_iou must be in (0, 1], got {min_iou}")
    D, G = iou.shape
    pairs = []
    if D and G:
        rows, cols = linear_sum_assignment(-iou)
        pairs = [(int(r), int(c), float(iou[r, c])) for r, c in zip(rows, cols)
                 if iou[r, c] >= min_iou]
    pairs.sort(key=lambda p: p[1])
    used_d = {p[0] for p in pairs}
    used_g = {p[1] for p in pairs}
    return Matching(pairs=tuple(pairs),
                    missed_gt=tuple(g for g in range(G) if g not in used_g),
                    false_positives=tuple(d for d in range(D) if d not in used_d))


def match_masks(det_masks: list[np.ndarray], gt_masks: list[np.ndarray],
                min_iou: float = TOL.match_iou) -> Matching:
    """:func:`match` on :func:`iou_matrix` of the given masks."""
    return match(iou_matrix(det_masks, gt_masks), min_iou)
