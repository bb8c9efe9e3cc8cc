"""Fitting EffWin's box verifier (fenestra/pipeline/detectors/verifier.py) on the real train photos and
some of the detector's training renders.

    fenestra train-verifier out/train/default.pt [--renders out/detector-data/train]   # adds "verifier" to it

The detector runs on the TRAIN part of the YOLO photos (training.dataset.real_box_photos; the
validation part and the test photos are never read) and on ``render_views`` rendered views of its
own training houses. Each detection at score >= MIN_SCORE is a sample: a window (label 1) when its
box matches a window box (photos: class 0; renders: the coco.json's windows) at IoU >= 0.5; a door
or signboard (label 0) when it lies on one (photos: training.evaluate's rule,
HARD_NEGATIVE_CLASSES, IoU or intersection over the detection > 0.5; renders: on an ignore region,
glazed-door or curtain-wall glazing) and matches no window; other detections are left out (partly
found windows, unlabelled ones). The renders keep the head from dropping rendered windows, which
look unlike the photos'. A logistic regression (L2, Newton's method in float64: deterministic) on
the standardised box features; the threshold keeps ``keep_windows`` of the windows detected at the
shipped score, measured out of fold (photos and views in FOLDS groups), so the head does not judge
its own training boxes.
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from fenestra.masks import box_from_coco, mask_box
from fenestra.yolo import yolo_boxes
from fenestra.errors import DatasetError, FenestraError
from fenestra.pipeline.detectors.verifier import (FeatureSpec, VerifierHead, box_features, detection_extras, head_to_dict,
                                         network_fingerprint)
from fenestra.training.evaluate import box_overlaps, HARD_NEGATIVE_CLASSES, HARD_NEGATIVE_OVERLAP, merged_coco
from fenestra.pipeline.detectors import DETECTORS, downscale, input_scale, load_model, read_weights
from fenestra.training.dataset import find_datasets, photo_labels, read_box_photo, real_box_photos
from fenestra.images import read_image
from fenestra.training import weights_file

MIN_SCORE = 0.05  # detections scored like training.evaluate.evaluate_boxes' (COCO AP) ones
SHIPPED_THRESHOLD = 0.5  # pipeline.detectors.detect's default score threshold
WINDOW_IOU = 0.5
FOLDS = 5
# The backbone at strides 32 and 64, inside the box and its context (the box grown by its size on
# every side): of the layer sets tried, the best on the validation photos.
SPEC = FeatureSpec(layers=("bb32", "bb64"), strides=(32, 64), context=1.0)


@dataclass(frozen=True)
class Samples:
    """Box features X (N, D), labels y (N,) 1 window / 0 door or signboard, detector scores (N,),
    photo (or view) index (N,) and the number of photos and views read."""

    X: np.ndarray
    y: np.ndarray
    score: np.ndarray
    photo: np.ndarray
    n_photos: int


def label_detections(boxes: np.ndarray, windows: list, negatives: list) -> np.ndarray:
    """(N,) per detection box: 1 on a window (IoU >= WINDOW_IOU), 0 on a door or signboard and no
    window (training.evaluate.HARD_NEGATIVE_OVERLAP rule), -1 otherwise (not a sample)."""

    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    win = box_overlaps(b, np.asarray(windows))[0].max(axis=1) >= WINDOW_IOU if len(windows) else np.zeros(len(b), bool)
    on = np.zeros(len(b), bool)
    if len(negatives):
        iou, iod = box_overlaps(b, np.asarray(negatives))
        on = ((iou > HARD_NEGATIVE_OVERLAP) | (iod > HARD_NEGATIVE_OVERLAP)).any(axis=1)
    return np.where(win, 1, np.where(on, 0, -1))


def image_samples(net, post, image: np.ndarray, windows: list, negatives: list, spec: FeatureSpec):
    """(X, y, score) of the labelled detections (:func:`label_detections`) of EffWin ``net`` on one
    RGB image, through the detector's input size (pipeline.detectors.input_scale) and
    post-processing; windows / negatives: boxes (4,) px of the full image. None without any."""
    from fenestra.pipeline.detectors import effwin  # noqa: PLC0415 (fenestra.pipeline.detectors.effwin loads SciPy, torch: imported when first used)

    scale = input_scale(image.shape[:2])
    small = image if scale == 1.0 else downscale(image, scale)
    maps, feats = effwin.predict_maps_features(net, small, post.mirror)
    dets = [d for d in effwin.detections_from_maps(maps, post) if d.score >= MIN_SCORE]
    if not dets:
        return None
    boxes = np.stack([d.box for d in dets])
    to_small = lambda bs: [(np.asarray(b, np.float64) + 0.5) * scale - 0.5 for b in bs]  # noqa: E731
    y = label_detections(boxes, to_small(windows), to_small(negatives))
    keep = y >= 0
    if not keep.any():
        return None
    X = box_features(feats, boxes[keep], small.shape[:2], detection_extras(dets, maps[0])[keep], spec)
    return X, y[keep], np.array([d.score for d in dets])[keep]


def photo_items(yolo_dir: str | Path, holdout_every: int, max_photos: int | None):
    """(image, window boxes, door and signboard boxes) of the TRAIN part of a YOLO photo folder."""

    for p in real_box_photos(yolo_dir, "train", holdout_every)[:max_photos]:
        image, inst, _ = read_box_photo(p)
        yield (image, [mask_box(inst == i) for i in np.unique(inst) if i],
               yolo_boxes(photo_labels(p)[0], image.shape[1], image.shape[0], HARD_NEGATIVE_CLASSES, p.name))


def render_items(roots: list, n_views: int):
    """(image, window boxes, ignore-region boxes: glazed doors and curtain walls) of ``n_views``
    rendered views spread evenly over the dataset folders under ``roots`` (their coco.json)."""

    coco, paths = merged_coco(find_datasets(roots))
    ids = [im["id"] for im in coco["images"]]
    pick = sorted({ids[int(i)] for i in np.linspace(0, len(ids) - 1, min(n_views, len(ids))).round()})
    anns: dict[int, list] = {}
    for a in coco["annotations"]:
        anns.setdefault(a["image_id"], []).append(a)
    for i in pick:
        boxes = [(box_from_coco(a["bbox"]), bool(a.get("iscrowd", 0))) for a in anns.get(i, [])]
        yield read_image(paths[i]), [b for b, crowd in boxes if not crowd], [b for b, crowd in boxes if crowd]


def collect(weights: str | Path, yolo_dir: str | Path, holdout_every: int = 5, spec: FeatureSpec = SPEC,
            max_photos: int | None = None, renders: tuple = (), render_views: int = 0,
            log: Callable[[str], None] = lambda s: None) -> Samples:
    """Samples of the detector in ``weights`` (EffWin) on the train part of a YOLO photo folder and
    on ``render_views`` views of the rendered datasets under ``renders`` (windows against glazed
    doors and curtain walls); each photo or view is one group (``Samples.photo``)."""
    from fenestra.pipeline.detectors import effwin  # noqa: PLC0415 (fenestra.pipeline.detectors.effwin loads SciPy, torch: imported when first used)

    _, net, ckpt = load_model(DETECTORS["default"].model, weights, any_arch=False)
    post = effwin.post_config(ckpt)
    items = [photo_items(yolo_dir, holdout_every, max_photos)] + ([render_items(list(renders), render_views)]
                                                                  if renders and render_views > 0 else [])
    parts, k = [], 0
    for source in items:
        for image, windows, negatives in source:
            got = image_samples(net, post, image, windows, negatives, spec)
            if got is not None:
                parts.append((*got, np.full(len(got[1]), k)))
            k += 1
            if k % 50 == 0:
                log(f"  {k} images, {sum(len(q[1]) for q in parts)} samples")
    if not parts:
        raise DatasetError(f"{yolo_dir}: no detection on a window, door or signboard in the train photos")
    X, y, s, ph = (np.concatenate(c) for c in zip(*parts))
    return Samples(X, y.astype(np.int64), s, ph, k)


def fit_logistic(X: np.ndarray, y: np.ndarray, l2: float = 1.0, iterations: int = 50) -> tuple[np.ndarray, float]:
    """(weight (D,), bias) of a class-balanced L2 logistic regression on X (N, D) (standardised)
    and y (N,) in {0, 1}, by Newton's method in float64 (deterministic; no step size to tune). The
    loss: mean over each class of the log loss, summed, + l2 / 2 |w|^2 / N."""
    X, y = np.asarray(X, np.float64), np.asarray(y, np.float64)
    if not (0 < y.sum() < len(y)):
        raise ValueError(f"fit_logistic needs both classes, got {int(y.sum())} positives of {len(y)}")
    n = len(y)
    sw = np.where(y > 0, 0.5 / y.sum(), 0.5 / (n - y.sum())) * n  # each class weighs half
    A = np.concatenate([X, np.ones((n, 1))], axis=1)
    reg = np.full(A.shape[1], l2)
    reg[-1] = 0.0
    theta = np.zeros(A.shape[1])
    for _ in range(iterations):
        p = 1.0 / (1.0 + np.exp(-np.clip(A @ theta, -50, 50)))
        grad = A.T @ (sw * (p - y)) + reg * theta
        hess = (A * (sw * p * (1 - p))[:, None]).T @ A + np.diag(reg) + 1e-9 * np.eye(A.shape[1])
        step = np.linalg.solve(hess, grad)
        theta -= step
        if np.abs(step).max() < 1e-8:
            break
    return theta[:-1], float(theta[-1])


def standardiser(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean, std) per column of X (std of a constant column: 1)."""
    mean, std = X.mean(axis=0), X.std(axis=0)
    return mean, np.where(std > 1e-8, std, 1.0)


def fit_head(X: np.ndarray, y: np.ndarray, spec: FeatureSpec, l2: float, threshold: float) -> VerifierHead:
    """The VerifierHead of a logistic regression on X, y (standardised with X's own statistics)."""
    mean, std = standardiser(X)
    w, b = fit_logistic((X - mean) / std, y, l2)
    return VerifierHead(spec, mean, std, w, b, threshold)


def out_of_fold(samples: Samples, spec: FeatureSpec, l2: float, folds: int = FOLDS) -> np.ndarray:
    """(N,) p(window) of each sample from a head fitted without its photo's fold (photo index mod
    ``folds``)."""
    p = np.zeros(len(samples.y))
    fold = samples.photo % folds
    for f in range(folds):
        tr = fold != f
        p[~tr] = fit_head(samples.X[tr], samples.y[tr], spec, l2, 0.5).window_probability(samples.X[~tr])
    return p


def choose_threshold(p: np.ndarray, y: np.ndarray, score: np.ndarray, keep_windows: float) -> float:
    """The highest p threshold that keeps ``keep_windows`` of the windows detected at the shipped
    score (out-of-fold p), so at most 1 - keep_windows of them are lost."""
    wins = np.sort(p[(y == 1) & (score >= SHIPPED_THRESHOLD)])
    if not len(wins):
        raise ValueError("no window detected at the shipped score to choose the threshold on")
    return float(wins[int(np.floor((1.0 - keep_windows) * len(wins)))])


@dataclass(frozen=True)
class Fitted:
    """The fitted head and what it does out of fold on the train photos at the shipped score."""

    head: VerifierHead
    n_photos: int
    n_windows: int
    n_negatives: int
    oof_windows_kept: float
    oof_negatives_dropped: float


def train_head(samples: Samples, spec: FeatureSpec = SPEC, l2: float = 100.0, keep_windows: float = 0.99) -> Fitted:
    """Threshold from out-of-fold probabilities (:func:`choose_threshold`), then the head on every sample."""
    p = out_of_fold(samples, spec, l2)
    t = choose_threshold(p, samples.y, samples.score, keep_windows)
    at = samples.score >= SHIPPED_THRESHOLD
    wins, negs = at & (samples.y == 1), at & (samples.y == 0)
    head = fit_head(samples.X, samples.y, spec, l2, t)
    return Fitted(head, samples.n_photos, int((samples.y == 1).sum()), int((samples.y == 0).sum()),
                  float((p[wins] >= t).mean()), float((p[negs] < t).mean()) if negs.any() else float("nan"))


def add_verifier(weights: str | Path, yolo_dir: str | Path, out: str | Path | None = None, holdout_every: int = 5,
                 renders: tuple = (), render_views: int = 0, l2: float = 100.0, keep_windows: float = 0.99,
                 log: Callable[[str], None] = print, force: bool = False) -> Fitted:
    """Fit the verifier of the EffWin weights file ``weights`` on ``yolo_dir``'s train photos (and
    ``render_views`` views of the rendered datasets under ``renders``) and write the file with its
    ``"verifier"`` key to ``out`` (default: in place, atomically), under training.weights_file's
    rule (``force``: also over a weights file no manifest lists)."""

    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)


    weights = Path(weights)
    if not weights.is_file():
        raise FenestraError(f"no weights file at {weights}")
    ckpt = read_weights(weights, ("effwin",))
    # in place: a weights file Fenestra wrote; --out: never over WEIGHTS, nor into the photos or renders
    inputs = () if out is None else (weights, yolo_dir, *renders)
    weights_file.check(weights if out is None else out, inputs, force)
    samples = collect(weights, yolo_dir, holdout_every, renders=tuple(renders), render_views=render_views, log=log)
    fitted = train_head(samples, SPEC, l2, keep_windows)
    ckpt["verifier"] = head_to_dict(fitted.head, network_fingerprint(ckpt["state_dict"]), {
        "photos": f"{yolo_dir} (train part, every {holdout_every}th photo held out)",
        "renders": [str(r) for r in renders], "render_views": render_views, "n_images": fitted.n_photos,
        "n_windows": fitted.n_windows, "n_doors_signboards": fitted.n_negatives, "l2": l2,
        "keep_windows": keep_windows, "oof_windows_kept": fitted.oof_windows_kept,
        "oof_doors_signboards_dropped": fitted.oof_negatives_dropped})
    buf = io.BytesIO()
    torch.save(ckpt, buf)
    weights_file.copy(Path(out) if out is not None else weights, buf.getvalue(), inputs, force, option="--out")
    return fitted
