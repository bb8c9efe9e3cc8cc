"""Detection AP (COCO bbox and segm, pycocotools) from the masks collected while benchmarking.

Ground truth: every window with visible pixels in a view's instance map (all of them, evaluable or
not: a detector should find partly hidden windows too). Detections: every detection, with score.
"""
from __future__ import annotations

import contextlib
import io

import numpy as np

STAT_NAMES = ("AP", "AP50", "AP75", "AP_small", "AP_medium", "AP_large",
              "AR1", "AR10", "AR100", "AR_small", "AR_medium", "AR_large")


def coco_ap(gt: list[dict], dt: list[dict]) -> dict[str, float]:
    """COCO metrics {"bbox_AP", "bbox_AP50", ..., "segm_AP", ...} in [0, 1] (NaN if undefined).

    gt: {"view", "rle", "bbox" (x, y, w, h px), "area"} per GT instance; dt: {"view", "rle",
    "bbox", "score"} per detection. Views are matched by their "view" key.
    """
    from pycocotools.coco import COCO  # noqa: PLC0415
    from pycocotools.cocoeval import COCOeval  # noqa: PLC0415

    if not gt:
        return {f"{t}_{k}": float("nan") for t in ("bbox", "segm") for k in STAT_NAMES}
    views = sorted({g["view"] for g in gt} | {d["view"] for d in dt})
    vid = {v: i + 1 for i, v in enumerate(views)}
    size = {}
    for g in gt + dt:
        size.setdefault(g["view"], g["rle"]["size"])
    images = [{"id": vid[v], "height": size[v][0], "width": size[v][1]} for v in views]
    anns = [{"id": i + 1, "image_id": vid[g["view"]], "category_id": 1, "iscrowd": 0,
             "segmentation": g["rle"], "bbox": g["bbox"], "area": float(g["area"])}
            for i, g in enumerate(gt)]
    out = {}
    for iou_type in ("bbox", "segm"):
        coco_gt = COCO()
        coco_gt.dataset = {"images": images, "annotations": anns,
                           "categories": [{"id": 1, "name": "window"}]}
        with contextlib.redirect_stdout(io.StringIO()):
            coco_gt.createIndex()
        res = [{"image_id": vid[d["view"]], "category_id": 1, "score": d["score"],
                "segmentation": d["rle"], "bbox": d["bbox"]} for d in dt]
        if not res:
            out.update({f"{iou_type}_{k}": 0.0 for k in STAT_NAMES})
            continue
        with contextlib.redirect_stdout(io.StringIO()):
            coco_dt = coco_gt.loadRes(res)
            ev = COCOeval(coco_gt, coco_dt, iou_type)
            ev.evaluate()
            ev.accumulate()
            ev.summarize()
        out.update({f"{iou_type}_{k}": (float(v) if v >= 0 else float("nan"))
                    for k, v in zip(STAT_NAMES, np.asarray(ev.stats))})
    return out
