"""COCO evaluation (fenestra.coco.coco_scores: COCOeval, bbox and segm) of a detector on a rendered dataset.

Ground truth is the dataset's own coco.json (written by the renderer with fenestra.coco's builder;
ignore regions as ``iscrowd``), never recomputed here. Scores are fractions in [0, 1];
:func:`format_table` prints them in percent, beside the paper's Table 2.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from fenestra.coco import coco_ground_truth, coco_result, coco_scores, complete_coco, gt_annotation
from fenestra.masks import mask_box, rle_from_crop, rle_iou, segmentation_to_rle
from fenestra.yolo import yolo_boxes
from fenestra import outputs
from fenestra.errors import DatasetError
from fenestra.images import read_image, read_instances
from fenestra.pipeline.detectors import detect, DETECTORS, get_detector
from fenestra.pipeline.types import Detection
from fenestra.training.dataset import coco_image_path, find_datasets, load_coco
from fenestra.training.dataset import photo_labels, read_box_photo, real_box_photos

TABLE_STATS = ("AP", "AP50", "AP75", "AP_small", "AP_medium", "AP_large")  # the columns of format_table

# The paper's Table 2 (Mask R-CNN on its real-photo test set; not comparable one-to-one with
# synthetic renders, printed for orientation; percent).
PAPER_TABLE2 = {"bbox": {"AP": 61.9, "AP50": 92.8, "AP75": 81.1},
                "segm": {"AP": 72.5, "AP50": 92.8, "AP75": 88.7}}
# what `evaluate-detector --json` writes, recognised where no manifest lists it (its --force)
METRICS_FILE = outputs.Recognised("a detector evaluation's metrics file",
                                  outputs.json_with(("detector", "dataset", "n_images")))


def detection_to_coco(det: Detection, image_id: int, shape: tuple[int, int] | None = None) -> dict:
    """fenestra.coco.coco_result of a Detection (full mask, or a crop at ``det.origin`` of an image
    of ``shape`` (H, W); default: the mask's own shape, a full mask)."""
    shape = np.asarray(det.mask).shape if shape is None else shape
    return coco_result(image_id, det.score, det.box, rle_from_crop(det.mask, det.origin, shape))


def best_overlaps(gt: dict, results: list[dict]) -> np.ndarray:
    """(len(results),) each result's best mask IoU with a window of its image (0 where it has
    none; ignore regions are not windows). gt: a COCO dict; results: coco_result dicts by image id."""
    sizes = {im["id"]: (im["height"], im["width"]) for im in gt["images"]}
    gts: dict[int, list] = {}
    for a in gt["annotations"]:
        if not a.get("iscrowd", 0):
            gts.setdefault(a["image_id"], []).append(segmentation_to_rle(a["segmentation"], *sizes[a["image_id"]]))
    ious = np.zeros(len(results))
    for j, r in enumerate(results):
        g = gts.get(r["image"], [])
        if g:
            ious[j] = rle_iou([r["segmentation"]], g).max()
    return ious


def rescored_by_overlap(results: list[dict], overlaps: np.ndarray) -> list[dict]:
    """Copies of ``results`` scored by their best IoU with a window (``best_overlaps``; ties
    broken by the detector's score): COCO AP on them is the AP a perfect ranking of the same
    detections would reach, so AP(rescored) - AP(results) is what the detector's scores cost."""
    return [{**r, "score": float(o) + 1e-3 * r["score"]} for r, o in zip(results, overlaps)]


def scores_by_type(scores: dict[str, float]) -> dict[str, dict[str, float]]:
    """fenestra.coco.coco_scores' flat {"bbox_AP": ...} as {"bbox": {"AP": ...}, "segm": {...}}."""
    out: dict[str, dict[str, float]] = {}
    for k, v in scores.items():
        t, stat = k.split("_", 1)
        out.setdefault(t, {})[stat] = v
    return out


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
             min_score: float = 0.05, ignore_regions: bool = True, **options: object) -> dict:
    """COCO bbox/segm scores of ``detector_name`` on a dataset folder (or a root holding several).

    Returns {"detector", "dataset", "n_images", "n_gt" (windows), "n_ignore" (ignore regions),
    "n_det", "ms_per_image_median", "bbox": {AP, AP50, ..., R50}, "segm": {...},
    "segm_perfect_ranking": {...}, "n_det_matching_no_window", "paper_table2"}; scores are
    fractions in [0, 1] (fenestra.coco.coco_scores). options are passed to the detector's
    factory (e.g. weights=PATH). ignore_regions=False drops the ignore regions (curtain-wall and
    glazed-door glazing), so detections there count as false positives: the figures before the
    project counted glazing that way.
    """
    if max_images is not None and max_images < 1:
        raise ValueError(f"--max-images must be >= 1, got {max_images}")
    dataset_dir = Path(dataset_dir)
    coco, paths = merged_coco(find_datasets([dataset_dir]))
    if not ignore_regions:
        coco = {**coco, "annotations": [a for a in coco["annotations"] if not a.get("iscrowd", 0)]}
    images = coco["images"]
    if max_images is not None:
        images = images[:max_images]
        ids = {im["id"] for im in images}
        coco = {**coco, "images": images, "annotations": [a for a in coco["annotations"] if a["image_id"] in ids]}
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
        results += [detection_to_coco(d, im["id"], image.shape[:2]) for d in dets if d.score >= min_score]
    gt = complete_coco(coco)
    overlaps = best_overlaps(gt, results)
    n_ignore = sum(bool(a["iscrowd"]) for a in gt["annotations"])
    scores = scores_by_type(coco_scores(gt, results))
    return {"detector": detector_name, "dataset": str(dataset_dir), "n_images": len(images),
            "n_gt": len(gt["annotations"]) - n_ignore, "n_ignore": n_ignore, "n_det": len(results),
            "ms_per_image_median": float(np.median(times)), **scores,
            "segm_perfect_ranking": scores_by_type(coco_scores(gt, rescored_by_overlap(results, overlaps),
                                                                    ("segm",)))["segm"],
            "n_det_matching_no_window": int((overlaps < 0.5).sum()),  # segm IoU < 0.5 with every window
            "paper_table2": PAPER_TABLE2}


def evaluate_boxes(detector_name: str, yolo_dir: str | Path, part: str = "val", holdout_every: int = 5,
                   max_images: int | None = None, min_score: float = 0.05, shipped_threshold: float = 0.5,
                   **options: object) -> dict:
    """COCO bbox scores of a learned detector on real photos with YOLO window boxes (class 0).

    part / holdout_every: which photos (training.dataset.real_box_photos: "val" is the part
    training never sees). The photos go through :func:`pipeline.detectors.detect`, as a user's
    would (resized to the network's input, boxes mapped back). Returns the keys of
    :func:`evaluate` but "segm" (boxes only) and the perfect-ranking figures, plus
    "hard_negatives" (:func:`hard_negative_share` of the detections at ``shipped_threshold``, the
    score pipeline.detectors.detect keeps by default, on the labels' doors and signboards).
    """

    if DETECTORS[detector_name].needs_instances:
        raise ValueError(f"detector {detector_name!r} needs instance maps; real photos have boxes only")
    photos = real_box_photos(yolo_dir, part, holdout_every)[:max_images]
    images, anns, results, times, hard = [], [], [], [], []
    for k, p in enumerate(photos, 1):
        image, inst, _ = read_box_photo(p)
        images.append((p.name, *image.shape[:2]))
        wins = [mask_box(inst == i) for i in np.unique(inst) if i]
        anns += [gt_annotation(p.name, box=b) for b in wins]
        t0 = time.perf_counter()
        dets = detect(detector_name, image, score_threshold=min_score, **options)
        times.append((time.perf_counter() - t0) * 1000.0)
        results += [coco_result(k, d.score, d.box) for d in dets]
        negs = yolo_boxes(photo_labels(p)[0], image.shape[1], image.shape[0], HARD_NEGATIVE_CLASSES, p.name)
        hard.append(([d.box for d in dets if d.score >= shipped_threshold], negs, wins))
    gt = coco_ground_truth(images, anns)
    scores = scores_by_type(coco_scores(gt, results, ("bbox",)))
    return {"detector": detector_name, "dataset": f"{yolo_dir} ({part}, every {holdout_every}th photo held out)",
            "n_images": len(images), "n_gt": len(anns), "n_ignore": 0, "n_det": len(results),
            "ms_per_image_median": float(np.median(times)), **scores, "paper_table2": PAPER_TABLE2,
            "hard_negatives": {**hard_negative_share(hard), "threshold": shipped_threshold}}


HARD_NEGATIVE_CLASSES = (3, 5)  # spb_facades labels: 3 signboard, 5 door (0 is the window)
HARD_NEGATIVE_OVERLAP = 0.5  # IoU, or intersection over the detection's box, above this: "on" the label


def box_overlaps(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(IoU, intersection over a's area), each (len(a), len(b)), of boxes (N, 4) x0 y0 x1 y1 px."""
    a, b = np.asarray(a, dtype=np.float64).reshape(-1, 4), np.asarray(b, dtype=np.float64).reshape(-1, 4)
    w = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)
    h = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0, None)
    inter = w * h
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return inter / np.maximum(union, 1e-9), inter / np.maximum(area_a[:, None], 1e-9)


def hard_negative_share(photos: list[tuple[list, list, list]]) -> dict:
    """How many detections lie on a labelled door or signboard: per photo (detection boxes at the
    shipped threshold, door/signboard boxes, window boxes). A detection is on one when its box IoU
    or its intersection over the detection's area exceeds HARD_NEGATIVE_OVERLAP. Returns
    {"n_det_at_threshold", "n_hard_negative", "hard_negative_share" (fraction, NaN without
    detections), "n_hard_negative_no_window" (of those, how many match no window box at IoU 0.5)}."""
    n_det = n_hard = n_alone = 0
    for dets, negs, wins in photos:
        n_det += len(dets)
        if not len(dets) or not len(negs):
            continue
        iou, iod = box_overlaps(np.asarray(dets), np.asarray(negs))
        on = ((iou > HARD_NEGATIVE_OVERLAP) | (iod > HARD_NEGATIVE_OVERLAP)).any(axis=1)
        win_iou = box_overlaps(np.asarray(dets), np.asarray(wins))[0].max(axis=1) if len(wins) else np.zeros(len(dets))
        n_hard += int(on.sum())
        n_alone += int((on & (win_iou < 0.5)).sum())
    return {"n_det_at_threshold": n_det, "n_hard_negative": n_hard,
            "hard_negative_share": n_hard / n_det if n_det else float("nan"), "n_hard_negative_no_window": n_alone}


def format_table(result: dict) -> str:
    """The scores in percent beside the paper's Table 2 (measured there on real photos), as text."""
    lines = [f"detector {result['detector']} on {result['dataset']}: {result['n_images']} images, "
             f"{result['n_gt']} windows ({result.get('n_ignore', 0)} ignore regions), {result['n_det']} "
             f"detections, {result['ms_per_image_median']:.0f} ms/image (median); scores in percent",
             f"{'':6}{'':>6}" + "".join(f"{k.replace('_small', 's').replace('_medium', 'm').replace('_large', 'l'):>7}"
                                        for k in TABLE_STATS)]
    for iou in (t for t in ("bbox", "segm") if t in result):
        lines.append(f"{iou:6}{'ours':>6}" + "".join(f"{100 * result[iou][k]:7.1f}" for k in TABLE_STATS))
        paper = PAPER_TABLE2[iou]
        lines.append(f"{'':6}{'paper':>6}" + "".join(f"{paper[k]:7.1f}" if k in paper else f"{'-':>7}"
                                                   for k in TABLE_STATS))
    lines.append("paper = Table 2, Mask R-CNN measured on real photos (not synthetic renders)")
    if "segm_perfect_ranking" in result:
        s, o = result["segm"], result["segm_perfect_ranking"]
        lines.append(f"segm recall at IoU 0.5: {100 * s['R50']:.1f} %; {result['n_det_matching_no_window']} of "
                     f"{result['n_det']} detections match no window (IoU < 0.5); with the same detections "
                     f"ranked by their overlap with the truth: AP {100 * o['AP']:.1f}, AP50 {100 * o['AP50']:.1f} "
                     f"(what the scores cost: {100 * (o['AP'] - s['AP']):.1f} AP)")
    if "hard_negatives" in result:
        h = result["hard_negatives"]
        lines.append(f"doors and signboards: {h['n_hard_negative']} of {h['n_det_at_threshold']} detections at score >= "
                     f"{h['threshold']} ({100 * h['hard_negative_share']:.1f} %) lie on a labelled door or signboard "
                     f"(box IoU or intersection over the detection > {HARD_NEGATIVE_OVERLAP}); "
                     f"{h['n_hard_negative_no_window']} of them match no window box")
    return "\n".join(lines)
