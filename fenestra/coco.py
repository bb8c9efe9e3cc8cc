"""COCO ground truth and scoring (docs/DESIGN.md, "Data contracts").

- **Ground truth** (:func:`gt_annotation`, :func:`coco_ground_truth`): windows, and **ignore
  regions** (``iscrowd = 1``: curtain-wall glazing, glazed doors, or a dataset's own crowd
  regions): a detection lying there counts neither as a true nor as a false positive.
  :func:`complete_coco` makes a foreign coco.json safe to score.
- **Scoring** (:func:`coco_scores`): pycocotools' COCOeval, bbox and segm, its 12 summary
  statistics plus ``R50``, every value a **fraction in [0, 1]** (never percent), keys
  ``"<bbox|segm>_<stat>"`` with stat in :data:`SCORE_NAMES`.

Boxes and masks follow :mod:`fenestra.masks`. Ground floor: imports nothing above fenestra/.
"""
from __future__ import annotations

import contextlib
import io
from collections.abc import Iterable, Sequence

import numpy as np

from fenestra.masks import box_to_coco, rle_area, rle_box, segmentation_to_rle
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

CATEGORIES = [{"id": 1, "name": "window"}]
COCO_STATS = ("AP", "AP50", "AP75", "AP_small", "AP_medium", "AP_large",
              "AR1", "AR10", "AR100", "AR_small", "AR_medium", "AR_large")  # COCOeval.stats, in order
SCORE_NAMES = COCO_STATS + ("R50",)  # R50: recall at IoU 0.5, all areas, 100 detections per image
IOU_TYPES = ("bbox", "segm")


def gt_annotation(image: str | int, rle: dict | None = None, box=None, area: float | None = None,
                  ignore: bool = False, **extra) -> dict:
    """One ground-truth object of image ``image`` (its key in :func:`coco_ground_truth`).

    A window, or with ``ignore=True`` an ignore region (COCO ``iscrowd = 1``: a detection inside
    it counts neither way). rle: its mask (compressed RLE) or None (box-only labels: no mask AP);
    box: (4,) x0 y0 x1 y1 px, pixel-edge outline (default: the RLE's); area: px (default: the
    RLE's pixel count, else the box's area). extra: more keys, kept as they are (e.g. window_id).
    """
    if rle is None and box is None:
        raise ValueError(f"ground-truth object of image {image!r} has neither mask nor box")
    if box is None:
        box = rle_box(rle)
    bbox = box_to_coco(box)
    if area is None:
        area = rle_area(rle) if rle is not None else bbox[2] * bbox[3]
    out = {"image": image, "iscrowd": int(bool(ignore)), "bbox": bbox, "area": float(area)}
    if rle is not None:
        out["segmentation"] = rle
    return {**out, **extra}



def coco_ground_truth(images: Sequence[tuple[str, int, int]], annotations: Iterable[dict],
                      first_image_id: int = 1) -> dict:
    """A COCO ground-truth dict: ``{"images", "annotations", "categories"}``.

    images: (key, height, width) per image, in order: ids first_image_id, first_image_id + 1, ...,
    ``file_name`` = key. annotations: :func:`gt_annotation` dicts in order (ids 1, 2, ...; category
    1, "window"); their ``image`` key names the image. ValueError naming an unknown or duplicate key.
    """
    ids: dict[str, int] = {}
    imgs = []
    for key, h, w in images:
        if key in ids:
            raise ValueError(f"image key {key!r} given twice")
        ids[key] = first_image_id + len(imgs)
        imgs.append({"id": ids[key], "file_name": key, "height": int(h), "width": int(w)})
    anns = []
    for a in annotations:
        a = dict(a)
        key = a.pop("image")
        if key not in ids:
            raise ValueError(f"annotation of unknown image {key!r}")
        anns.append({"id": len(anns) + 1, "image_id": ids[key], "category_id": CATEGORIES[0]["id"], **a})
    return {"images": imgs, "annotations": anns, "categories": [dict(c) for c in CATEGORIES]}




def complete_coco(coco: dict) -> dict:
    """A COCO dict (e.g. a foreign coco.json) made safe for :func:`coco_scores`: annotation ids
    and ``iscrowd`` filled in, uncompressed RLE compressed, missing areas and bboxes computed."""
    sizes = {im["id"]: (im.get("height"), im.get("width")) for im in coco["images"]}
    anns = []
    for i, a in enumerate(coco.get("annotations", [])):
        a = {"id": i + 1, "iscrowd": 0, **a}
        seg = a.get("segmentation")
        if isinstance(seg, dict) and isinstance(seg.get("counts"), list):
            a["segmentation"] = segmentation_to_rle(seg, *sizes.get(a["image_id"], seg["size"]))
        if seg is not None and ("area" not in a or "bbox" not in a):
            rle = segmentation_to_rle(a["segmentation"], *sizes[a["image_id"]])
            a.setdefault("area", float(rle_area(rle)))
            a.setdefault("bbox", box_to_coco(rle_box(rle)))
        anns.append(a)
    return {"images": coco["images"], "annotations": anns,
            "categories": coco.get("categories") or [dict(c) for c in CATEGORIES]}


def coco_result(image: str | int, score: float, box, rle: dict | None = None) -> dict:
    """One detection for :func:`coco_scores`: image (key or id of the ground truth's image),
    score, box (4,) x0 y0 x1 y1 px on the pixel-edge outline, rle (its mask) or None."""
    out = {"image": image, "score": float(score), "bbox": box_to_coco(box)}
    if rle is not None:
        out["segmentation"] = rle
    return out


def _nan_scores(iou_type: str) -> dict[str, float]:
    return {f"{iou_type}_{k}": float("nan") for k in SCORE_NAMES}


def coco_scores(gt: dict, results: Sequence[dict], iou_types: Sequence[str] = IOU_TYPES) -> dict[str, float]:
    """COCO evaluation (pycocotools COCOeval) of detections against a ground-truth dict.

    gt: :func:`coco_ground_truth` (or :func:`complete_coco`) dict; results: :func:`coco_result`
    dicts (``image`` an image key = file_name, or an image id). Returns ``{"<iou>_<stat>": v}`` for
    each iou type and stat in :data:`SCORE_NAMES` (the 12 COCOeval statistics and R50), every v a
    fraction in [0, 1]. NaN where a value is undefined: where COCOeval reports -1 (no window in an
    area range), every key when ``gt`` holds no window, segm keys when a window has no mask
    (box-only labels). 0.0 for every key when there are windows but no detections. Ignore regions
    (``iscrowd = 1``) follow COCO: a detection matched to one counts neither way.
    """

    bad = [t for t in iou_types if t not in IOU_TYPES]
    if bad:
        raise ValueError(f"iou_types must be among {IOU_TYPES}, got {bad}")
    windows = [a for a in gt["annotations"] if not a.get("iscrowd", 0)]
    by_name = {im.get("file_name"): im["id"] for im in gt["images"]}
    cat = gt["categories"][0]["id"] if gt.get("categories") else CATEGORIES[0]["id"]
    res = []
    for r in results:
        key = r.get("image", r.get("image_id"))
        image_id = by_name.get(key) if isinstance(key, str) else key
        if image_id is None:
            raise ValueError(f"detection of unknown image {key!r}")
        res.append({"image_id": image_id, "category_id": cat, "score": r["score"], "bbox": list(r["bbox"]),
                    **({"segmentation": r["segmentation"]} if r.get("segmentation") is not None else {})})
    out: dict[str, float] = {}
    for iou_type in iou_types:
        if not windows or (iou_type == "segm" and any("segmentation" not in a for a in windows)):
            out.update(_nan_scores(iou_type))
            continue
        if not res:
            out.update({f"{iou_type}_{k}": 0.0 for k in SCORE_NAMES})
            continue
        anns = [a if "segmentation" in a else {**a, "segmentation": _box_polygon(a["bbox"])}
                for a in gt["annotations"]]  # a box-only ignore region: its box as the mask
        with contextlib.redirect_stdout(io.StringIO()):
            coco_gt = COCO()
            coco_gt.dataset = {"images": gt["images"], "annotations": anns, "categories": gt["categories"]}
            coco_gt.createIndex()
            coco_dt = coco_gt.loadRes([dict(r) for r in res])  # loadRes adds keys: give it copies
            ev = COCOeval(coco_gt, coco_dt, iou_type)
            ev.evaluate()
            ev.accumulate()
            ev.summarize()
        r50 = float(ev.eval["recall"][0, 0, 0, -1])  # [IoU 0.5, category, area all, maxDets 100]
        out.update({f"{iou_type}_{k}": (float(v) if v >= 0 else float("nan"))
                    for k, v in zip(SCORE_NAMES, [*np.asarray(ev.stats), r50])})
    return out


def _box_polygon(bbox) -> list[list[float]]:
    x, y, w, h = bbox
    return [[x, y, x, y + h, x + w, y + h, x + w, y]]
