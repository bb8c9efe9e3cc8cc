"""Evaluate one RealView with every method: detect, match, reconstruct, measure what the labels allow.

One row per labelled window per method, never dropped: a window the detector missed, a failed
stage, or a method that cannot run on this view (an oracle without ground-truth masks) keeps its
row with ``status`` and ``reason``. Errors whose truth the view lacks are NaN (absent), never 0:
corner errors and 2D IoU need a labelled quad, aspect error a known aspect ratio, relative size a
coplanar photo with known sizes; rotation, normal and translation errors need a true pose, which
no real dataset here has. Reprojection consistency needs no truth but a known K (with the focal
length estimated from the same quad, the pose reprojects onto it exactly: 0 by construction).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from bench import matching, metrics
from bench.evaluate import _ERROR_COLUMNS, AP_SCORE_MIN, MATCH_SCORE_MIN, ViewOutcome
from fenestra.methods import Method
from bench.real import metrics as real_metrics
from bench.real.contract import RealView, RealWindow
from fenestra import data
from fenestra.conventions import TOL
from pipeline.detectors import detector_entry
from pipeline.types import Detection

NAN = float("nan")
REAL_COLUMNS = ("reproj_consistency_px", "rel_size_err")


@dataclass(frozen=True)
class RealEvalSpec:
    """min_window_px: shortest labelled side below which a window is not evaluable; height_m: the
    pose's scale parameter; detector_long_side: learned detectors see the photo resized to this
    long side (px; 0 = full size), masks are scaled back."""

    min_window_px: float = 12.0
    height_m: float = 1.0
    detector_long_side: int = 640
    detector_options: tuple[tuple[str, tuple[tuple[str, object], ...]], ...] = ()  # (name, build options)


def detect_resized(name: str, image: np.ndarray, long_side: int, score_threshold: float,
                   instances: np.ndarray | None = None, **options: object) -> list[Detection]:
    """Detections at full size. Oracles (``instances`` (H, W) int) run at full size; a learned
    detector on a copy resized to ``long_side`` px (INTER_AREA), masks scaled back (nearest)
    and boxes recomputed from them; empty masks dropped. options: the detector's build options
    (e.g. weights=PATH), one torch thread unless given."""
    from pipeline.detectors import detect  # noqa: PLC0415

    if detector_entry(name).needs_instances:
        return detect(name, image, score_threshold=score_threshold, instances=instances)
    options = {"threads": 1, **options}
    H, W = image.shape[:2]
    s = long_side / max(H, W) if long_side else 1.0
    if s >= 1.0:
        return detect(name, image, score_threshold=score_threshold, **options)
    small = cv2.resize(image, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA)
    out = []
    for d in detect(name, small, score_threshold=score_threshold, **options):
        m = cv2.resize(d.mask.astype(np.uint8), (W, H), interpolation=cv2.INTER_NEAREST).astype(bool)
        if m.any():
            out.append(Detection(mask=m, box=data.mask_box(m), score=d.score, label=d.label))
    return out


def window_px(w: RealWindow) -> float:
    """Shortest labelled side (px): of the quad if labelled, else of the (mask's) box."""
    if w.quad is not None:
        q = np.asarray(w.quad, dtype=np.float64)
        return float(np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1).min())
    b = w.bbox()
    return float(min(b[2] - b[0], b[3] - b[1]))


def window_base(view: RealView, w: RealWindow, spec: RealEvalSpec) -> dict:
    """The method-independent columns of one labelled window (conditions, truth available)."""
    px = window_px(w)
    reason = "partial" if w.partial else ("too_small" if px < spec.min_window_px else "")
    return {"house": view.dataset, "dataset": view.dataset, "renderer": "photo", "view": view.name,
            "window_id": w.id, "instance_id": -1, "incidence_deg": NAN, "distance_m": NAN,
            "visible_fraction": NAN, "window_px": px, "gt_aspect": NAN if w.aspect is None else w.aspect,
            "has_quad": w.quad is not None, "has_box": w.box is not None, "has_mask": w.mask is not None,
            "has_aspect": w.aspect is not None, "has_size": w.size_m is not None and view.coplanar,
            "has_pose": False, "known_K": view.K is not None, "evaluable": reason == "", "eval_reason": reason}


def window_errors(res, w: RealWindow, known_K: bool = True) -> dict:
    """Errors of one WindowResult against what the window's labels know (NaN elsewhere);
    reprojection consistency only with a known K (see the module docstring)."""
    out = {k: NAN for k in (*_ERROR_COLUMNS, *REAL_COLUMNS)}
    stages = (("mask", res.quad_mask), ("snap", res.quad_snapped), ("reproj", res.quad_reprojected))
    finite = {s: q is not None and bool(np.all(np.isfinite(q))) for s, q in stages}
    if w.quad is not None:
        for s, q in stages:
            if finite[s]:
                e = metrics.corner_errors_px(q, w.quad)
                out[f"corner_err_px_{s}"], out[f"corner_err_px_{s}_max"] = float(e.mean()), float(e.max())
        out["snap_gain_px"] = out["corner_err_px_mask"] - out["corner_err_px_snap"]
        for col, s in (("iou_2d", "snap"), ("iou_2d_mask", "mask"), ("iou_2d_reproj", "reproj")):
            if finite[s]:
                out[col] = metrics.quad_iou(dict(stages)[s], w.quad)
    if res.aspect_ratio is not None and np.isfinite(res.aspect_ratio):
        out["aspect_est"] = float(res.aspect_ratio)
        if w.aspect is not None:
            out["aspect_err_rel"] = metrics.aspect_error_rel(res.aspect_ratio, w.aspect)
    if finite["snap"] and finite["reproj"] and known_K:
        out["reproj_consistency_px"] = real_metrics.reprojection_consistency_px(res.quad_snapped,
                                                                                 res.quad_reprojected)
    return out


def add_relative_sizes(rows: list[dict], results: dict[int, object], view: RealView) -> None:
    """Fill ``rel_size_err`` of one method's rows of a coplanar view: windows with a pose and a
    known size (at least two), see bench.real.metrics.relative_size_errors."""
    if not view.coplanar:
        return
    idx = [g for g, r in results.items() if r.R is not None and view.windows[g].size_m is not None]
    if len(idx) < 2:
        return
    d = [real_metrics.plane_distance(results[g].R, results[g].t) for g in idx]
    errs = real_metrics.relative_size_errors(np.array(d), np.array([view.windows[g].size_m[1] for g in idx]))
    for g, e in zip(idx, errs):
        rows[g]["rel_size_err"] = float(e)


def image_key(view: RealView) -> str:
    """The view's COCO image key, "dataset/name"."""
    return f"{view.dataset}/{view.name}"


def gt_coco(view: RealView) -> list[dict]:
    """COCO ground truth of a view (fenestra.data.gt_annotation): every window, evaluable or not
    (a detector should find cut windows too), with its labelled box (else its mask's) and its
    mask's RLE (none for box-only labels); then the view's ignore regions (``iscrowd``)."""
    out = []
    for ignore, regions in ((False, view.windows), (True, view.ignore)):
        for w in regions:
            m = None if w.mask is None else data.SparseMask.from_dense(w.mask)
            out.append(data.gt_annotation(image_key(view), None if m is None else m.rle(), w.bbox(),
                                          None if m is None else m.area, ignore=ignore))
    return out


def _iou(dets: list[Detection], view: RealView) -> np.ndarray:
    """(D, G) mask IoU when every window has a mask, else box IoU."""
    if view.has_masks:
        shape = view.image.shape[:2]
        return matching.iou_matrix([data.SparseMask.from_crop(d.mask, d.origin, shape) for d in dets],
                                   [w.mask for w in view.windows])
    return real_metrics.box_iou_matrix([d.box for d in dets], [w.bbox() for w in view.windows])


def _not_run_rows(base: list[dict], method: Method, why: str) -> list[dict]:
    return [{**b, **method.row(), **{k: NAN for k in (*_ERROR_COLUMNS, *REAL_COLUMNS)},
             "evaluable": False, "eval_reason": "no_gt_masks", "status": "missed",
             "reason": f"not run: {why}", "aspect_case": None} for b in base]


def evaluate_real_view(view: RealView, methods: tuple[Method, ...], spec: RealEvalSpec) -> ViewOutcome:
    """Rows for every (labelled window x method) of one photo; see the module docstring.

    ViewOutcome.coco_dt holds only the detectors that ran on this view (an oracle needs masks).
    """
    from pipeline.reconstruct import ReconstructConfig, fit_quads, reconstruct_from_quads, to_gray  # noqa: PLC0415

    stage_s: dict[str, float] = {}
    t0 = time.perf_counter()
    base = [window_base(view, w, spec) for w in view.windows]
    out = ViewOutcome(rows=[], stage_s=stage_s, coco_gt=gt_coco(view))
    gray = to_gray(view.image)  # RGB, as detect() and reconstruct() take it
    inst = view.instance_map() if view.has_masks else None
    for det_name in dict.fromkeys(m.detector for m in methods):
        ms = [m for m in methods if m.detector == det_name]
        if detector_entry(det_name).needs_instances and inst is None:
            for m in ms:
                out.rows += _not_run_rows(base, m, f"{det_name} needs ground-truth masks, the labels are boxes")
            continue
        cands = detect_resized(det_name, view.image, spec.detector_long_side, AP_SCORE_MIN, inst,
                               **dict(dict(spec.detector_options).get(det_name, ())))
        dets = [d for d in cands if d.score >= MATCH_SCORE_MIN]
        out.coco_dt[det_name] = [data.coco_result(image_key(view), d.score, d.box,
                                                  data.rle_from_crop(d.mask, d.origin, view.image.shape[:2]))
                                 for d in cands]
        mt = matching.match(_iou(dets, view), TOL.match_iou)
        out.n_false_positives[det_name] = len(mt.false_positives)
        det_for_gt = mt.det_for_gt()
        matched = sorted(det_for_gt.items())
        rec_dets = [dets[d] for _, (d, _) in matched]
        t0 = _tick(stage_s, "detect", t0)
        quads = fit_quads(rec_dets, ReconstructConfig().quad, gray.shape)
        for m in ms:
            cfg = ReconstructConfig(snapper=m.snapper, pose=m.pose, height_m=spec.height_m)
            K_in = None if m.withhold_K else view.K
            res = reconstruct_from_quads(gray, K_in, rec_dets, quads, cfg) if matched else []
            by_gt = {matched[r.index][0]: r for r in res}
            rows = [_row(b, m, w, by_gt.get(g), det_for_gt.get(g), dets, view.K is not None)
                    for g, (w, b) in enumerate(zip(view.windows, base))]
            add_relative_sizes(rows, by_gt, view)
            out.rows += rows
        t0 = _tick(stage_s, "reconstruct", t0)
    return out


def _tick(stage_s: dict, stage: str, t0: float) -> float:
    t1 = time.perf_counter()
    stage_s[stage] = stage_s.get(stage, 0.0) + t1 - t0
    return t1


def _row(base: dict, m: Method, w: RealWindow, res, match, dets: list[Detection], known_K: bool) -> dict:
    """One results row: the window's columns, the method, its outcome and errors."""
    row = {**base, **m.row()}
    if res is None:
        row.update({k: NAN for k in (*_ERROR_COLUMNS, *REAL_COLUMNS)}, status="missed", reason="missed",
                   aspect_case=None)
        return row
    row.update(window_errors(res, w, known_K), aspect_case=res.aspect_case,
               status="ok" if res.failure is None else "failed",
               reason="" if res.failure is None else f"failed: {res.failure}")
    row["match_iou"], row["det_score"] = match[1], float(dets[match[0]].score)
    return row
