"""COCO evaluation (pycocotools COCOeval, bbox and segm) of a detector on a rendered dataset.

Ground truth is the dataset's own coco.json (written by the renderer), never recomputed here.
"""
from __future__ import annotations

import contextlib
import io
import time
from pathlib import Path

import numpy as np
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

from pipeline.detectors import DETECTORS, get_detector
from pipeline.types import Detection
from training.dataset import (DatasetError, coco_image_path, find_datasets, load_coco, read_image,
                              read_instances)

STAT_NAMES = ("AP", "AP50", "AP75", "APs", "APm", "APl")

# The paper's Table 2 (Mask R-CNN on its real-photo test set; not comparable one-to-one with
# synthetic renders, printed for orientation).
PAPER_TABLE2 = {"bbox": {"AP": 61.9, "AP50": 92.8, "AP75": 81.1},
                "segm": {"AP": 72.5, "AP50": 92.8, "AP75": 88.7}}


def detection_to_coco(det: Detection, image_id: int, category_id: int = 1) -> dict:
    """One COCO result entry (RLE segmentation, xywh bbox in pixel-edge coordinates)."""
    rle = mask_utils.encode(np.asfortranarray(det.mask.astype(np.uint8)))
    rle["counts"] = rle["counts"].decode("ascii")
    x0, y0, x1, y1 = (float(v) for v in det.box)
    return {"image_id": int(image_id), "category_id": int(category_id), "segmentation": rle,
            "bbox": [x0 + 0.5, y0 + 0.5, x1 - x0, y1 - y0], "score": float(det.score)}


def coco_stats(gt: dict, results: list[dict], iou_type: str) -> dict[str, float]:
    """AP, AP50, AP75, APs, APm, APl and R50 in percent (NaN where COCO reports -1: no GT in the
    range). R50: COCO recall at IoU 0.5, all areas, up to 100 detections per image."""
    if iou_type not in ("bbox", "segm"):
        raise ValueError(f"iou_type must be 'bbox' or 'segm', got {iou_type!r}")
    with contextlib.redirect_stdout(io.StringIO()):
        coco_gt = COCO()
        coco_gt.dataset = gt
        coco_gt.createIndex()
        coco_dt = coco_gt.loadRes(results) if results else None
        if coco_dt is None:
            return {k: 0.0 for k in STAT_NAMES + ("R50",)}
        ev = COCOeval(coco_gt, coco_dt, iou_type)
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    pct = lambda v: float(v) * 100.0 if v >= 0 else float("nan")  # noqa: E731
    r50 = ev.eval["recall"][0, 0, 0, -1]  # [IoU 0.5, category, area all, maxDets 100]
    return {**{k: pct(v) for k, v in zip(STAT_NAMES, ev.stats[:6])}, "R50": pct(r50)}


def best_overlaps(gt: dict, results: list[dict], iou_type: str) -> np.ndarray:
    """(len(results),) each result's best IoU with a window of its image (0 where it has none)."""
    key = "segmentation" if iou_type == "segm" else "bbox"
    gts: dict[int, list] = {}
    for a in gt["annotations"]:
        gts.setdefault(a["image_id"], []).append(_mask_api(a[key]))
    ious = np.zeros(len(results))
    for j, r in enumerate(results):
        g = gts.get(r["image_id"], [])
        if g:
            ious[j] = np.max(mask_utils.iou([_mask_api(r[key])], g, [0] * len(g)))
    return ious


def rescored_by_overlap(results: list[dict], overlaps: np.ndarray) -> list[dict]:
    """Copies of ``results`` scored by their best IoU with a window (``best_overlaps``; ties
    broken by the detector's score): COCO AP on them is the AP a perfect ranking of the same
    detections would reach, so AP(rescored) - AP(results) is what the detector's scores cost."""
    return [{**r, "score": float(o) + 1e-3 * r["score"]} for r, o in zip(results, overlaps)]


def _mask_api(x: dict | list) -> dict | list:
    """A COCO RLE with str counts as pycocotools' mask functions take it (bytes); else unchanged."""
    if isinstance(x, dict) and isinstance(x.get("counts"), str):
        return {**x, "counts": x["counts"].encode("ascii")}
    return x


def _gt_for_coco(coco: dict) -> dict:
    """coco.json made safe for COCOeval: areas and bboxes filled in from the RLE when missing."""
    gt = {"images": coco["images"], "categories": coco.get("categories") or [{"id": 1, "name": "window"}],
          "annotations": []}
    for i, a in enumerate(coco.get("annotations", [])):
        a = dict(a)
        a.setdefault("id", i + 1)
        a.setdefault("iscrowd", 0)
        seg = a["segmentation"]
        if isinstance(seg, dict) and isinstance(seg.get("counts"), list):
            seg = mask_utils.frPyObjects(seg, *seg["size"])
            a["segmentation"] = {"size": seg["size"], "counts": seg["counts"].decode("ascii")}
        if "area" not in a or "bbox" not in a:
            rle = _mask_api(a["segmentation"])
            a.setdefault("area", float(mask_utils.area(rle)))
            a.setdefault("bbox", [float(v) for v in mask_utils.toBbox(rle)])
        gt["annotations"].append(a)
    return gt


def merged_coco(dataset_dirs: list[Path]) -> tuple[dict, dict[int, Path]]:
    """One COCO dict over several dataset folders (image/annotation ids renumbered from 1) and
    image id -> image path."""
    images, anns, paths, cats = [], [], {}, None
    for d in dataset_dirs:
        coco = load_coco(d)
        cats = cats or coco.get("categories") or [{"id": 1, "name": "window"}]
        remap = {}
        for im in coco.get("images", []):
            remap[im["id"]] = len(images) + 1
            paths[len(images) + 1] = coco_image_path(d, im)
            images.append({**im, "id": len(images) + 1})
        for a in coco.get("annotations", []):
            anns.append({**a, "id": len(anns) + 1, "image_id": remap[a["image_id"]]})
    if not images:
        raise DatasetError(f"no images listed in the coco.json of {[str(d) for d in dataset_dirs]}")
    return {"images": images, "annotations": anns, "categories": cats}, paths


def evaluate(detector_name: str, dataset_dir: str | Path, max_images: int | None = None,
             min_score: float = 0.05, **options: object) -> dict:
    """COCO bbox/segm metrics of ``detector_name`` on a dataset folder (or a root holding several).

    Returns {"detector", "dataset", "n_images", "n_gt", "n_det", "ms_per_image_median",
    "bbox": {AP, AP50, ...}, "segm": {...}, "paper_table2": ...}; metrics in percent.
    options are passed to the detector's factory (e.g. weights=PATH).
    """
    if max_images is not None and max_images < 1:
        raise ValueError(f"--max-images must be >= 1, got {max_images}")
    dataset_dir = Path(dataset_dir)
    coco, paths = merged_coco(find_datasets([dataset_dir]))
    images = coco["images"]
    if max_images is not None:
        images = images[:max_images]
        ids = {im["id"] for im in images}
        coco = {**coco, "images": images, "annotations": [a for a in coco["annotations"] if a["image_id"] in ids]}
    cat = coco["categories"][0]["id"]
    detector = get_detector(detector_name, **options)
    needs_instances = DETECTORS[detector_name].needs_instances
    results, times = [], []
    for im in images:
        path = paths[im["id"]]
        image = read_image(path)
        per_image = {"instances": read_instances(path.parent / "instances.png")} if needs_instances else {}
        t0 = time.perf_counter()
        dets = detector(image, **per_image)
        times.append((time.perf_counter() - t0) * 1000.0)
        results += [detection_to_coco(d, im["id"], cat) for d in dets if d.score >= min_score]
    gt = _gt_for_coco(coco)
    overlaps = best_overlaps(gt, results, "segm")
    return {"detector": detector_name, "dataset": str(dataset_dir), "n_images": len(images),
            "n_gt": len(gt["annotations"]), "n_det": len(results),
            "ms_per_image_median": float(np.median(times)),
            "bbox": coco_stats(gt, results, "bbox"), "segm": coco_stats(gt, results, "segm"),
            "segm_perfect_ranking": coco_stats(gt, rescored_by_overlap(results, overlaps), "segm"),
            "n_det_matching_no_window": int((overlaps < 0.5).sum()),  # segm IoU < 0.5 with every window
            "paper_table2": PAPER_TABLE2}


def format_table(result: dict) -> str:
    """The metrics beside the paper's Table 2 (measured there on real photos), as text."""
    lines = [f"detector {result['detector']} on {result['dataset']}: {result['n_images']} images, "
             f"{result['n_gt']} windows, {result['n_det']} detections, "
             f"{result['ms_per_image_median']:.0f} ms/image (median)",
             f"{'':6}{'':>6}" + "".join(f"{k:>7}" for k in STAT_NAMES)]
    for iou in ("bbox", "segm"):
        lines.append(f"{iou:6}{'ours':>6}" + "".join(f"{result[iou][k]:7.1f}" for k in STAT_NAMES))
        paper = PAPER_TABLE2[iou]
        lines.append(f"{'':6}{'paper':>6}" + "".join(f"{paper[k]:7.1f}" if k in paper else f"{'-':>7}"
                                                   for k in STAT_NAMES))
    lines.append("paper = Table 2, Mask R-CNN measured on real photos (not synthetic renders)")
    if "segm_perfect_ranking" in result:
        s, o = result["segm"], result["segm_perfect_ranking"]
        lines.append(f"segm recall at IoU 0.5: {s['R50']:.1f} %; {result['n_det_matching_no_window']} of "
                     f"{result['n_det']} detections match no window (IoU < 0.5); with the same detections "
                     f"ranked by their overlap with the truth: AP {o['AP']:.1f}, AP50 {o['AP50']:.1f} "
                     f"(what the scores cost: {o['AP'] - s['AP']:.1f} AP)")
    return "\n".join(lines)
