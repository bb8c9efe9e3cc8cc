"""One-to-one matching of detections to ground-truth windows by mask IoU (Hungarian).

A detection and a ground-truth window match when the assignment that maximises the total IoU
pairs them and their IoU is at least ``TOL.match_iou``. Ground-truth windows left unmatched are
"missed"; detections left unmatched are false positives. Masks: full (H, W) bool arrays or
fenestra.masks.SparseMask (a crop: cost grows with the box, not the image).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from fenestra.tolerances import TOL
from fenestra.masks import SparseMask


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


def _sparse(masks: list) -> list[SparseMask]:
    return [m if isinstance(m, SparseMask) else SparseMask.from_dense(m) for m in masks]


def iou_matrix(det_masks: list, gt_masks: list) -> np.ndarray:
    """Mask IoU of every detection with every ground-truth window.

    det_masks: D masks, gt_masks: G masks, each an (H, W) bool array or a :class:`SparseMask`, all
    of one image shape. Returns (D, G) float64 in [0, 1] (the ratio rounded to float32 first).
    Only pairs whose boxes overlap are compared, on the overlap of their crops: the cost grows with
    the windows in view, not with image area x window count.
    """
    if not det_masks or not gt_masks:
        return np.zeros((len(det_masks), len(gt_masks)))
    dets, gts, inter = _intersections(det_masks, gt_masks)
    union = (np.array([d.area for d in dets])[:, None] + np.array([g.area for g in gts])[None, :]
             - inter)
    # float32 ratio: the figures of the dense float32 implementation this replaced, bit for bit
    ratio = inter.astype(np.float32) / np.maximum(union, 1).astype(np.float32)
    return np.where(union > 0, ratio, np.float32(0.0)).astype(np.float64)


def cover_matrix(det_masks: list, region_masks: list) -> np.ndarray:
    """(D, R) share of each detection's pixels inside each region (intersection / detection area,
    COCO's test against an ``iscrowd`` region), in [0, 1]; 0 for an empty detection. Masks as for
    :func:`iou_matrix`."""
    if not det_masks or not region_masks:
        return np.zeros((len(det_masks), len(region_masks)))
    dets, _, inter = _intersections(det_masks, region_masks)
    area = np.array([d.area for d in dets], dtype=np.float64)[:, None]
    return np.where(area > 0, inter / np.maximum(area, 1.0), 0.0)


def _intersections(det_masks: list, gt_masks: list) -> tuple[list[SparseMask], list[SparseMask], np.ndarray]:
    """(detections, windows, (D, G) int64 pixel counts of their intersections), as SparseMasks;
    only pairs whose boxes overlap are compared, on the overlap of their crops."""
    dets, gts = _sparse(det_masks), _sparse(gt_masks)
    shape = gts[0].shape
    for name, masks in (("det_masks", dets), ("gt_masks", gts)):
        for i, m in enumerate(masks):
            if m.shape != shape:
                raise ValueError(f"{name}[{i}] has shape {m.shape}, expected {shape}")
    db = np.array([(d.r0, d.r1, d.c0, d.c1) for d in dets]).reshape(-1, 4)
    gb = np.array([(g.r0, g.r1, g.c0, g.c1) for g in gts]).reshape(-1, 4)
    overlap = ((np.maximum(db[:, None, 0], gb[None, :, 0]) < np.minimum(db[:, None, 1], gb[None, :, 1]))
               & (np.maximum(db[:, None, 2], gb[None, :, 2]) < np.minimum(db[:, None, 3], gb[None, :, 3])))
    inter = np.zeros((len(dets), len(gts)), dtype=np.int64)
    for i, j in zip(*np.nonzero(overlap)):
        d, g = dets[i], gts[j]
        r0, r1 = max(d.r0, g.r0), min(d.r1, g.r1)
        c0, c1 = max(d.c0, g.c0), min(d.c1, g.c1)
        inter[i, j] = np.count_nonzero(d.crop[r0 - d.r0:r1 - d.r0, c0 - d.c0:c1 - d.c0]
                                       & g.crop[r0 - g.r0:r1 - g.r0, c0 - g.c0:c1 - g.c0])
    return dets, gts, inter


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


def match_masks(det_masks: list, gt_masks: list,
                min_iou: float = TOL.match_iou) -> Matching:
    """:func:`match` on :func:`iou_matrix` of the given masks."""
    return match(iou_matrix(det_masks, gt_masks), min_iou)
