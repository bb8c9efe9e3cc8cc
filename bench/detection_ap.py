"""Detection AP of the synthetic bench (COCO bbox and segm) from the per-view COCO material.

Ground truth: every window with visible pixels in a view's instance map (all of them, evaluable or
not: a detector should find partly hidden windows too), and the view's ignore regions (COCO
``iscrowd``: detections there count neither way). Detections: every detection, with its score.
Scoring: fenestra.data.coco_scores (fractions in [0, 1]).
"""
from __future__ import annotations

from fenestra import data


def coco_ap(gt: list[dict], dt: list[dict]) -> dict[str, float]:
    """fenestra.data.coco_scores {"bbox_AP", ..., "segm_R50"} (fractions; NaN if undefined).

    gt: fenestra.data.gt_annotation per window or ignore region; dt: fenestra.data.coco_result per
    detection; both keyed by their view ("image", e.g. "house/000012"), every one with a mask
    (its RLE gives the view's size). Images are numbered in sorted key order.
    """
    size: dict[str, list[int]] = {}
    for a in gt + dt:
        size.setdefault(a["image"], a["segmentation"]["size"])
    images = [(k, *size[k]) for k in sorted(size)]
    return data.coco_scores(data.coco_ground_truth(images, gt), dt)
