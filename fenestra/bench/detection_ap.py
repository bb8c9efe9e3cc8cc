"""Detection AP of a run (COCO bbox and segm), from the per-view COCO material of bench.evaluate.

Ground truth: every labelled window with pixels (or a box) of every view, evaluable or not (a
detector should find partly hidden and cut windows too), and the views' ignore regions (COCO
``iscrowd``: detections there count neither way). Detections: every detection down to
pipeline.session.CANDIDATE_SCORE_MIN, with its score. A detector is scored over the views it ran on (an
oracle cannot run on a photo labelled with boxes only). Scoring: fenestra.coco.coco_scores
(fractions in [0, 1]; NaN where undefined, e.g. mask AP of box-only labels).
"""
from __future__ import annotations

from fenestra.coco import coco_ground_truth, coco_scores


def coco_ap(gt: list[dict], dt: list[dict]) -> dict[str, float]:
    """fenestra.coco.coco_scores {"bbox_AP", ..., "segm_R50"} (fractions; NaN if undefined).

    gt: fenestra.coco.gt_annotation per window or ignore region; dt: fenestra.coco.coco_result per
    detection; both keyed by their view ("image", e.g. "house/000012"), every one with a mask
    (its RLE gives the view's size). Images are numbered in sorted key order.
    """
    size: dict[str, list[int]] = {}
    for a in gt + dt:
        size.setdefault(a["image"], a["segmentation"]["size"])
    images = [(k, *size[k]) for k in sorted(size)]
    return coco_scores(coco_ground_truth(images, gt), dt)


def coco_ap_of(outcomes: list, detector: str) -> dict:
    """COCO scores of one detector over the views it ran on, plus ``false_positives`` (at the
    matching threshold), ``n_detections`` and ``n_gt`` (windows, not ignore regions).

    outcomes: bench.evaluate.ViewOutcome (its key, size (H, W), coco_gt, coco_dt,
    n_false_positives); images are numbered in sorted key order, so the scores do not depend on
    the order views were evaluated in.
    """
    ran = [o for o in outcomes if detector in o.coco_dt]
    gt = [g for o in ran for g in o.coco_gt]
    dt = [d for o in ran for d in o.coco_dt[detector]]
    images = sorted((o.key, *o.size) for o in ran)
    stats = coco_scores(coco_ground_truth(images, gt), dt)
    return {**stats, "false_positives": sum(o.n_false_positives.get(detector, 0) for o in ran),
            "n_detections": len(dt), "n_gt": sum(not g["iscrowd"] for g in gt)}


def detection_ap(outcomes: list, per_dataset: bool = False) -> dict[str, dict]:
    """{detector: coco_ap_of over every view}; with ``per_dataset`` and views of several datasets,
    also {"detector @ dataset": ...} per dataset where the detector ran (the report's detection
    table of a photo run: datasets differ in what they label)."""
    dets = list(dict.fromkeys(d for o in outcomes for d in o.coco_dt))
    out = {det: coco_ap_of(outcomes, det) for det in dets}
    names = list(dict.fromkeys(o.dataset for o in outcomes))
    if per_dataset and len(names) > 1:
        for det in dets:
            for n in names:
                sub = [o for o in outcomes if o.dataset == n]
                if any(det in o.coco_dt for o in sub):
                    out[f"{det} @ {n}"] = coco_ap_of(sub, det)
    return out
