"""Evaluate one labelled view (a render or a photo): detect, match, reconstruct with every method,
measure every error its truth allows.

The unit of work of the runner's executors (bench.executors). Input: a bench.views.LabelledView
(read by the rendered-view adapter, bench.render_adapter, or a real-format adapter,
bench.real.adapters); output: one row per labelled window per method combination (never dropped:
missed, failed, non-evaluable windows and methods that cannot run on the view keep a row with
``status`` and ``reason``), the time spent per stage, and COCO material for detection AP.

Each detector runs once per view; its detections are matched to the labelled windows (mask IoU
when every window has a mask, else box IoU), the quads are fitted once per detector, and every
snapper x pose method reconstructs from them. The pipeline is fed exactly what a user would give
it: the RGB image and K (none where K is unknown or withheld), plus the instance map for the
oracle detectors (which stand in for a perfect or imperfect network; they cannot run on a photo
labelled with boxes only).

Errors whose truth the view lacks are NaN (absent), never 0: corner errors and 2D IoU need a
labelled quad; aspect error a known aspect; rotation, normal and translation errors and the
uncertainty calibration an exact pose (renders); relative size a coplanar photo with known
sizes; reprojection consistency needs no truth but a known K (with the focal length estimated
from the same quad the pose reprojects onto it exactly: 0 by construction).

The two kinds of table keep their columns: a view with exact pose truth (a render) gets
:data:`RENDER_COLUMNS` (its view conditions, pose errors and bench.uncertainty's columns), a
photo :data:`PHOTO_COLUMNS` (which truth it has: ``has_quad``, ``has_aspect``, ...; reprojection
consistency and relative size).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Protocol

import cv2
import numpy as np

from fenestra.bench import matching, metrics, uncertainty
from fenestra.bench.profiles import EvalSpec
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra import coco, masks
from fenestra.conventions import camera_depths
from fenestra.tolerances import TOL
from fenestra.methods import Method

AP_SCORE_MIN = 0.05  # detections kept for COCO AP
MATCH_SCORE_MIN = 0.5  # detections passed on to matching and reconstruction
NAN = float("nan")


@dataclass(frozen=True)
class EvalOptions:
    """How views are evaluated (picklable; part of a run's configuration).

    evaluation: which windows are evaluable (a photo uses ``min_window_px`` only); height_m: the
    pose's scale parameter; detector_long_side: learned detectors see an image larger than this
    resized to this long side (px; 0 = full size), masks scaled back; detector_options: build
    options per learned detector, ((name, ((key, value), ...)), ...).
    """

    evaluation: EvalSpec = field(default_factory=EvalSpec)
    height_m: float = 1.0
    detector_long_side: int = 0
    detector_options: tuple[tuple[str, tuple[tuple[str, object], ...]], ...] = ()

    def options_of(self, detector: str) -> dict:
        """The build options of one detector ({} if none)."""
        return dict(dict(self.detector_options).get(detector, ()))


class ViewSource(Protocol):
    """Something that loads one LabelledView (in a worker): bench.render_adapter.RenderedViewRef,
    or :class:`LoadedView` for a view read by a real-format adapter."""

    def load(self) -> LabelledView: ...


@dataclass(frozen=True)
class LoadedView:
    """A view already read (a photo from bench.real.adapters) as a ViewTask source."""

    view: LabelledView

    def load(self) -> LabelledView:
        return self.view


@dataclass(frozen=True)
class ViewTask:
    """Everything a worker needs to evaluate one view (picklable)."""

    source: ViewSource
    methods: tuple[Method, ...]
    options: EvalOptions


@dataclass
class ViewOutcome:
    """Rows (list of dicts), seconds per stage, and COCO material for detection AP of one view.

    frame: the same rows as a pandas DataFrame once :meth:`to_frame` moved them there (``rows``
    is then empty): a run keeps each view's rows in columns, not 60 Python objects per row.

    dataset/view/size: the view's dataset (house), name and (H, W); window_ids: its labelled
    windows (a run manifest's expected rows); coco_dt holds the detectors that ran on the view
    (an oracle needs masks).
    """

    rows: list[dict]
    stage_s: dict[str, float]
    coco_gt: list[dict] = field(default_factory=list)  # fenestra.data.gt_annotation per window / ignore region
    coco_dt: dict[str, list[dict]] = field(default_factory=dict)  # detector -> fenestra.data.coco_result
    n_false_positives: dict[str, int] = field(default_factory=dict)
    dataset: str = ""
    view: str = ""
    size: tuple[int, int] = (0, 0)
    window_ids: tuple[str, ...] = ()
    frame: object = None  # pandas.DataFrame of the rows after to_frame(), else None

    def to_frame(self) -> "ViewOutcome":
        """This outcome with its rows moved into ``frame`` (a DataFrame, columns in row order)."""
        import pandas as pd  # noqa: PLC0415

        if self.frame is not None:
            return self
        return replace(self, rows=[], frame=pd.DataFrame(self.rows))

    def table(self):
        """The view's rows as a DataFrame (``frame``, else built from ``rows``)."""
        import pandas as pd  # noqa: PLC0415

        return self.frame if self.frame is not None else pd.DataFrame(self.rows)

    @property
    def key(self) -> str:
        """The view's COCO image key, "dataset/view" (bench.views.LabelledView.key)."""
        return f"{self.dataset}/{self.view}"


# ---------------------------------------------------------------- the tables' columns

RENDER_BASE = ("house", "renderer", "view", "window_id", "instance_id", "incidence_deg", "distance_m",
               "visible_fraction", "n_corners_visible", "corners_in_frame", "window_px", "window_area_px",
               "mask_px", "gt_width_m", "gt_height_m", "gt_aspect", "evaluable", "eval_reason")
PHOTO_BASE = ("house", "dataset", "renderer", "view", "window_id", "instance_id", "incidence_deg",
              "distance_m", "visible_fraction", "window_px", "gt_aspect", "has_quad", "has_box", "has_mask",
              "has_aspect", "has_size", "has_pose", "known_K", "evaluable", "eval_reason")
METHOD_COLUMNS = ("detector", "snapper", "pose", "method")
ERROR_COLUMNS = (
    "corner_err_px_mask", "corner_err_px_mask_max", "corner_err_px_snap", "corner_err_px_snap_max",
    "corner_err_px_reproj", "corner_err_px_reproj_max", "snap_gain_px", "aspect_est",
    "aspect_err_rel", "rot_err_deg", "normal_err_deg", "trans_err_m", "iou_2d", "iou_2d_mask",
    "iou_2d_reproj", "match_iou", "det_score", "corner_err_px_head",
)
PHOTO_ERRORS = ("reproj_consistency_px", "rel_size_err")
RENDER_TAIL = (*ERROR_COLUMNS, *uncertainty.COLUMNS, "status", "reason", "aspect_case")
PHOTO_TAIL = (*ERROR_COLUMNS, *PHOTO_ERRORS, "aspect_case", "status", "reason")  # the order photo tables always had
RENDER_COLUMNS = (*RENDER_BASE, *METHOD_COLUMNS, *RENDER_TAIL)
PHOTO_COLUMNS = (*PHOTO_BASE, *METHOD_COLUMNS, *PHOTO_TAIL)


def tail_columns(view: LabelledView) -> tuple[str, ...]:
    """The error and outcome columns of the view's table, in order: a render's (exact pose truth)
    or a photo's."""
    return RENDER_TAIL if view.pose is not None else PHOTO_TAIL


# ---------------------------------------------------------------- per window, method-independent

def _shortest_side(q: np.ndarray) -> float:
    return float(np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1).min())


def render_conditions(view: LabelledView, w: LabelledWindow, spec: EvalSpec) -> dict:
    """View conditions of one window of a render (exact truth) and whether it is evaluable.

    Keys: incidence_deg, distance_m, visible_fraction, n_corners_visible, corners_in_frame,
    window_px (shortest projected side, px), window_area_px (projected quad area, px^2),
    mask_px (visible pixels in instances.png), gt_width_m, gt_height_m, gt_aspect,
    evaluable (bool), eval_reason: "" when evaluable, else the first that applies of
    behind_camera (a corner at depth <= 0), back_facing (incidence >= 90 deg), hidden (no pixel
    in instances.png, corners in the image), outside_image (no pixel, corners outside),
    out_of_frame (a corner outside the image), occluded (visible_fraction below the profile's
    minimum), too_small (shortest side below min_window_px), grazing (incidence above maximum).
    """
    H, W = view.size
    q = np.asarray(w.quad, dtype=np.float64)
    x, y = q[:, 0], q[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    in_frame = bool(np.all((x >= -0.5) & (x <= W - 0.5) & (y >= -0.5) & (y <= H - 0.5)))
    depth_ok = bool(np.all(camera_depths(*view.pose, w.corners_world) > 0))
    mask_px = int(w.mask.area)
    c = {
        "incidence_deg": w.incidence_deg,
        "distance_m": w.distance_m,
        "visible_fraction": w.visible_fraction,
        "n_corners_visible": int(sum(w.corner_visible)),
        "corners_in_frame": in_frame,
        "window_px": _shortest_side(q),
        "window_area_px": area,
        "mask_px": mask_px,
        "gt_width_m": w.size_m[0],
        "gt_height_m": w.size_m[1],
        "gt_aspect": w.aspect,
    }
    any_in = bool(np.any((x >= -0.5) & (x <= W - 0.5) & (y >= -0.5) & (y <= H - 0.5)))
    reason = ""
    if not depth_ok:
        reason = "behind_camera"
    elif c["incidence_deg"] >= 90.0:
        reason = "back_facing"
    elif mask_px == 0:
        reason = "hidden" if any_in else "outside_image"
    elif spec.require_corners_in_frame and not in_frame:
        reason = "out_of_frame"
    elif not c["visible_fraction"] >= spec.min_visible_fraction:
        reason = "occluded"
    elif c["window_px"] < spec.min_window_px:
        reason = "too_small"
    elif c["incidence_deg"] > spec.max_incidence_deg:
        reason = "grazing"
    c["evaluable"] = reason == ""
    c["eval_reason"] = reason
    return c


def photo_conditions(view: LabelledView, w: LabelledWindow, spec: EvalSpec) -> dict:
    """The truth one labelled window of a photo has, and whether it is evaluable: not when
    ``partial`` (cut by the border), nor when its shortest labelled side (of the quad, else of
    the box) is below ``spec.min_window_px`` (``too_small``)."""
    b = w.bbox()
    px = _shortest_side(np.asarray(w.quad, dtype=np.float64)) if w.quad is not None \
        else float(min(b[2] - b[0], b[3] - b[1]))
    reason = "partial" if w.partial else ("too_small" if px < spec.min_window_px else "")
    return {"dataset": view.dataset, "incidence_deg": w.incidence_deg, "distance_m": w.distance_m,
            "visible_fraction": w.visible_fraction, "window_px": px,
            "gt_aspect": NAN if w.aspect is None else w.aspect, "has_quad": w.quad is not None,
            "has_box": w.box is not None, "has_mask": w.mask is not None, "has_aspect": w.aspect is not None,
            "has_size": w.size_m is not None and view.coplanar, "has_pose": view.pose is not None,
            "known_K": view.K is not None, "evaluable": reason == "", "eval_reason": reason}


def window_base(view: LabelledView, w: LabelledWindow, spec: EvalSpec) -> dict:
    """The method-independent columns of one window, in the table's order (RENDER_BASE for a
    view with exact pose truth, else PHOTO_BASE)."""
    ident = {"house": view.dataset, "renderer": view.renderer, "view": view.name, "window_id": w.id,
             "instance_id": w.instance_id}
    if view.pose is not None:
        row = {**ident, **render_conditions(view, w, spec)}
        order = RENDER_BASE
    else:
        row = {**ident, **photo_conditions(view, w, spec)}
        order = PHOTO_BASE
    return {k: row[k] for k in order}


def gt_coco(view: LabelledView) -> list[dict]:
    """COCO ground truth of a view (fenestra.data.gt_annotation, key ``view.key``): every window
    with pixels, evaluable or not (a detector should find cut and partly hidden windows too; a
    render's hidden window has none), with its labelled box (else its mask's) and its mask's RLE
    (none for box-only labels); then the view's ignore regions (``iscrowd``)."""
    out = []
    for ignore, regions in ((False, view.windows), (True, view.ignore)):
        for w in regions:
            if w.mask is not None and not w.mask.area:
                continue
            out.append(coco.gt_annotation(view.key, None if w.mask is None else w.mask.rle(), w.bbox(),
                                          None if w.mask is None else w.mask.area, ignore=ignore))
    return out


# ---------------------------------------------------------------- per window and method

def _finite(q) -> bool:
    return q is not None and bool(np.isfinite(q).all())


class QuadIoUMemo:
    """bench.metrics.quad_iou of quad pairs, each pair computed once: a view's mask-fit quads are
    the same for every snapper and pose, its snapped quads for every pose (a callable like
    metrics.quad_iou; make one per view)."""

    def __init__(self) -> None:
        self._seen: dict[tuple, float] = {}

    def __call__(self, q: np.ndarray, gt: np.ndarray) -> float:
        a, b = np.asarray(q), np.asarray(gt)
        key = (a.dtype.str, a.shape, a.tobytes(), b.dtype.str, b.shape, b.tobytes())
        if key not in self._seen:
            self._seen[key] = metrics.quad_iou(q, gt)
        return self._seen[key]


def window_errors(res, w: LabelledWindow, gt_pose: tuple[np.ndarray, np.ndarray] | None,
                  K: np.ndarray | None, quad_iou=metrics.quad_iou) -> dict:
    """Every error of one WindowResult against what the window's truth knows (NaN elsewhere).

    gt_pose: the window's true (R, t) (metrics.gt_window_pose; renders), or None; K: the view's
    true K, or None (unknown); quad_iou: metrics.quad_iou or a :class:`QuadIoUMemo` of the view.
    Keys: ERROR_COLUMNS (match_iou and det_score NaN: the caller's), PHOTO_ERRORS, and, with
    gt_pose and K, bench.uncertainty.COLUMNS.
    """
    out = {k: NAN for k in (*ERROR_COLUMNS, *PHOTO_ERRORS)}
    stages = {"mask": res.quad_mask, "snap": res.quad_snapped, "reproj": res.quad_reprojected}
    if w.quad is not None:
        for s, q in stages.items():
            if _finite(q):
                e = metrics.corner_errors_px(q, w.quad)
                out[f"corner_err_px_{s}"], out[f"corner_err_px_{s}_max"] = float(e.mean()), float(e.max())
        out["snap_gain_px"] = out["corner_err_px_mask"] - out["corner_err_px_snap"]
        for col, s in (("iou_2d", "snap"), ("iou_2d_mask", "mask"), ("iou_2d_reproj", "reproj")):
            if _finite(stages[s]):
                out[col] = quad_iou(stages[s], w.quad)
    if res.aspect_ratio is not None and math.isfinite(res.aspect_ratio):
        out["aspect_est"] = float(res.aspect_ratio)
        if w.aspect is not None:
            out["aspect_err_rel"] = metrics.aspect_error_rel(res.aspect_ratio, w.aspect)
    if gt_pose is not None and res.R is not None and res.t is not None:
        R_gt, t_gt = gt_pose
        out["rot_err_deg"] = metrics.rotation_error_deg(res.R, R_gt)
        out["normal_err_deg"] = metrics.normal_error_deg(res.R, R_gt)
        out["trans_err_m"] = metrics.translation_error_m(res.t, res.height_m, t_gt, w.size_m[1])
    if _finite(res.quad_snapped) and _finite(res.quad_reprojected) and K is not None:
        out["reproj_consistency_px"] = metrics.reprojection_consistency_px(res.quad_snapped, res.quad_reprojected)
    if gt_pose is not None and K is not None:
        out.update(uncertainty.columns(res, w.aspect, gt_pose, K, out))
    return out


def head_error(det, w: LabelledWindow) -> float:
    """Mean corner error (px) of a detection's predicted corners (a corner head's; pipeline.quad.
    corners_to_quad) against the labelled quad; NaN without either, or when they are not a quad."""
    from fenestra.pipeline.quad import corners_to_quad  # noqa: PLC0415

    if w.quad is None:
        return NAN
    q = corners_to_quad(det.corners).quad
    return NAN if q is None else float(metrics.corner_errors_px(q, w.quad).mean())


def add_relative_sizes(rows: list[dict], results: dict[int, object], view: LabelledView) -> None:
    """Fill ``rel_size_err`` of one method's rows of a coplanar view: windows with a pose and a
    known size (at least two), see bench.metrics.relative_size_errors."""
    if not view.coplanar:
        return
    idx = [g for g, r in results.items() if r.R is not None and view.windows[g].size_m is not None]
    if len(idx) < 2:
        return
    d = [metrics.plane_distance(results[g].R, results[g].t) for g in idx]
    errs = metrics.relative_size_errors(np.array(d), np.array([view.windows[g].size_m[1] for g in idx]))
    for g, e in zip(idx, errs):
        rows[g]["rel_size_err"] = float(e)


# ---------------------------------------------------------------- detection and reconstruction

def detect_view(name: str, view: LabelledView, long_side: int, score_threshold: float, **options: object) -> list:
    """Detections (pipeline.types.Detection) at full size, best first. Oracles read the view's
    instance map at full size; a learned detector sees a copy resized to ``long_side`` px
    (INTER_AREA; 0 or an image no larger: full size), its masks scaled back (nearest) and boxes
    recomputed from them (empty masks dropped; predicted corners are not scaled: none). options:
    the detector's build options (e.g. weights=PATH), one torch thread unless given."""
    from fenestra.pipeline.detectors import detect, detector_entry  # noqa: PLC0415
    from fenestra.pipeline.types import Detection  # noqa: PLC0415

    if detector_entry(name).needs_instances:
        return detect(name, view.image, score_threshold=score_threshold, instances=view.instance_map())
    options = {"threads": 1, **options}
    H, W = view.size
    s = long_side / max(H, W) if long_side else 1.0
    if s >= 1.0:
        return detect(name, view.image, score_threshold=score_threshold, **options)
    small = cv2.resize(view.image, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA)
    out = []
    for d in detect(name, small, score_threshold=score_threshold, **options):
        m = cv2.resize(d.mask.astype(np.uint8), (W, H), interpolation=cv2.INTER_NEAREST).astype(bool)
        if m.any():
            out.append(Detection(mask=m, box=masks.mask_box(m), score=d.score, label=d.label))
    return out


PER_WINDOW_STAGES = ("snap", "aspect", "pose")


def _reconstruct(gray: np.ndarray, K: np.ndarray | None, dets: list, quads: list, cfg, withhold_K: bool,
                 per_window: dict, segment_cache, memo) -> tuple[list, tuple[str, ...]]:
    """reconstruct_from_quads of one method, and the timing keys it spent time on.

    A per-wall strategy starts from the per-window results of its base pose; those are computed
    once per snapper (or taken from that per-window method's own run) and kept in ``per_window``,
    so every method's results are exactly those of a run of its own. segment_cache: the view's
    pipeline.segments.SegmentCache (its façade line segments, found once for every method);
    memo: the view's pipeline.memo.StepMemo (the steps with identical inputs computed once for
    every method: the snapping and aspect ratio of ``lm`` and ``ippe``; the per-wall grouping,
    vanishing points and fits of ``wall`` and ``building`` where no walls are tied).
    """
    from fenestra.pipeline.reconstruct import POSES, reconstruct_from_quads  # noqa: PLC0415

    if not dets:
        return [], ()
    wall = POSES[cfg.pose].wall
    if wall is None:
        results = reconstruct_from_quads(gray, K, dets, quads, cfg, memo=memo)
        per_window[(cfg.quad, cfg.snapper, cfg.pose, withhold_K)] = results
        return results, PER_WINDOW_STAGES
    key = (cfg.quad, cfg.snapper, wall.base_pose, withhold_K)
    counted: tuple[str, ...] = ("wall",)
    if key not in per_window:
        per_window[key] = reconstruct_from_quads(gray, K, dets, quads, replace(cfg, pose=wall.base_pose), memo=memo)
        counted = (*PER_WINDOW_STAGES, "wall")
    return reconstruct_from_quads(gray, K, dets, quads, cfg, base=per_window[key], segment_cache=segment_cache,
                                  memo=memo), counted


def _match_ious(view: LabelledView, det_masks: list[masks.SparseMask], dets: list) -> np.ndarray:
    """(D, G) mask IoU when every window has a mask, else box IoU."""
    if view.has_masks:
        return matching.iou_matrix(det_masks, [w.mask for w in view.windows])
    return metrics.box_iou_matrix([d.box for d in dets], [w.bbox() for w in view.windows])


def _method_row(base: dict, method: Method, tail: tuple[str, ...], **values) -> dict:
    """One results row in the table's column order: the window's columns, the method, then the
    ``tail`` columns (errors: NaN unless in ``values``; status, reason, aspect_case: required)."""
    missing = [k for k in ("status", "reason", "aspect_case") if k in tail and k not in values]
    if missing:
        raise KeyError(f"row values lack {missing}")
    row = {**base, **method.row()}
    get = values.get
    row.update({k: get(k, NAN) for k in tail})
    return row


def _method_rows(view: LabelledView, base: list[dict], method: Method, tail: tuple[str, ...], by_gt: dict,
                 det_for_gt: dict, dets: list, gt_poses: dict, quad_iou=metrics.quad_iou,
                 head_errors: dict | None = None) -> list[dict]:
    """One method's rows, one per labelled window in order: missed, or its result's errors.

    by_gt: {window index: WindowResult}; det_for_gt: {window index: (detection index, IoU)};
    dets: the detections matched against; gt_poses: {window index: true (R, t)}, filled here once
    per window of a render (the same for every method); quad_iou: as for window_errors; head_errors:
    {(detection index, window index): head_error}, kept across the methods of one detector (None:
    computed here)."""
    head_errors = {} if head_errors is None else head_errors
    rows = []
    for g, (w, b) in enumerate(zip(view.windows, base)):
        if g not in by_gt:
            rows.append(_method_row(b, method, tail, status="missed", reason="missed", aspect_case=None))
            continue
        res, (d, iou) = by_gt[g], det_for_gt[g]
        if view.pose is not None and g not in gt_poses:
            gt_poses[g] = metrics.gt_window_pose(*view.pose, w.corners_world)
        errs = window_errors(res, w, gt_poses.get(g), view.K, quad_iou)
        if (d, g) not in head_errors:
            head_errors[(d, g)] = head_error(dets[d], w)
        errs.update(match_iou=iou, det_score=float(dets[d].score), corner_err_px_head=head_errors[(d, g)])
        rows.append(_method_row(b, method, tail, **errs, aspect_case=res.aspect_case,
                                status="ok" if res.failure is None else "failed",
                                reason="" if res.failure is None else f"failed: {res.failure}"))
    add_relative_sizes(rows, by_gt, view)
    return rows


def evaluate_view(view: LabelledView, methods: tuple[Method, ...], options: EvalOptions) -> ViewOutcome:
    """Rows for every (labelled window x method) of one view; see the module docstring."""
    from fenestra.pipeline.detectors import detector_entry  # noqa: PLC0415
    from fenestra.pipeline.reconstruct import ReconstructConfig, fit_quads, to_gray  # noqa: PLC0415
    from fenestra.pipeline.quad import QuadParams  # noqa: PLC0415
    from fenestra.pipeline.segments import SegmentCache  # noqa: PLC0415
    from fenestra.pipeline.memo import StepMemo  # noqa: PLC0415

    stage_s: dict[str, float] = {}

    def tick(stage: str, t0: float) -> float:  # CPU seconds of this process: robust to a busy machine
        t1 = time.process_time()
        stage_s[stage] = stage_s.get(stage, 0.0) + t1 - t0
        return t1

    t0 = time.process_time()
    cols = tail_columns(view)
    base = [window_base(view, w, options.evaluation) for w in view.windows]
    out = ViewOutcome(rows=[], stage_s=stage_s, coco_gt=gt_coco(view), dataset=view.dataset, view=view.name,
                      size=view.size, window_ids=tuple(str(w.id) for w in view.windows))
    gt_poses: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    iou_memo = QuadIoUMemo()  # quad IoUs of this view, each pair computed once for every method
    t0 = tick("load", t0)
    gray = to_gray(view.image)  # RGB, as detect() and reconstruct() take it; once per view, shared by every method
    segment_cache = SegmentCache(gray)  # the view's line segments (+lines strategies): found once, shared too
    memo = StepMemo()  # the pipeline steps of this view, each distinct input computed once for every method
    t0 = tick("reconstruct", t0)
    can_oracle = view.instance_map() is not None

    for det_name in dict.fromkeys(m.detector for m in methods):
        det_methods = [m for m in methods if m.detector == det_name]
        if detector_entry(det_name).needs_instances and not can_oracle:
            why = f"not run: {det_name} needs ground-truth masks, the labels are boxes"
            out.rows += [_method_row({**b, "evaluable": False, "eval_reason": "no_gt_masks"}, m, cols,
                                     status="missed", reason=why, aspect_case=None)
                         for m in det_methods for b in base]
            continue
        # every candidate down to AP_SCORE_MIN feeds detection AP; reconstruction gets the
        # detections a user would (score >= MATCH_SCORE_MIN, the detectors' default threshold)
        cands = detect_view(det_name, view, options.detector_long_side, AP_SCORE_MIN,
                            **options.options_of(det_name))
        keep = [i for i, d in enumerate(cands) if d.score >= MATCH_SCORE_MIN]
        dets = [cands[i] for i in keep]
        t0 = tick("detect", t0)
        sparse = [masks.SparseMask.from_crop(d.mask, d.origin, view.size) for d in cands]
        out.coco_dt[det_name] = [coco.coco_result(view.key, d.score, d.box, m.rle()) for d, m in zip(cands, sparse)]
        mt = matching.match(_match_ious(view, [sparse[i] for i in keep], dets), TOL.match_iou)
        out.n_false_positives[det_name] = len(mt.false_positives)
        det_for_gt = mt.det_for_gt()
        matched = sorted(det_for_gt.items())  # [(gt_index, (det_index, iou))]
        t0 = tick("match", t0)
        rec_dets = [dets[d] for _, (d, _) in matched]
        quads: dict = {}  # QuadParams -> fit_quads(rec_dets): the quads are fitted once per detector
        per_window: dict = {}  # (quad params, snapper, pose, K withheld) -> per-window results, reused by per-wall strategies
        head_errors: dict = {}  # (detection, window) -> the detection's predicted corners' error, for every method
        for method in det_methods:
            withhold_K = method.withhold_K
            cfg = ReconstructConfig(snapper=method.snapper, pose=method.pose, height_m=options.height_m,
                                    quad=QuadParams(source=method.quad_source))
            if cfg.quad not in quads:
                quads[cfg.quad] = fit_quads(rec_dets, cfg.quad, gray.shape)
                stage_s["reconstruct.quad"] = (stage_s.get("reconstruct.quad", 0.0)
                                               + sum(q.ms for q in quads[cfg.quad]) / 1000.0)
            K_in = None if withhold_K else view.K
            results, counted = _reconstruct(gray, K_in, rec_dets, quads[cfg.quad], cfg, withhold_K, per_window,
                                             segment_cache, memo)
            t0 = tick("reconstruct", t0)
            by_gt = {matched[r.index][0]: r for r in results}
            for r in results:
                for k, ms in r.timings_ms.items():
                    if k in counted:  # the shared quad fit and reused per-window stages: counted once
                        stage_s[f"reconstruct.{k}"] = stage_s.get(f"reconstruct.{k}", 0.0) + ms / 1000.0
            out.rows += _method_rows(view, base, method, cols, by_gt, det_for_gt, dets, gt_poses, iou_memo,
                                     head_errors)
            t0 = tick("metrics", t0)
    return out


def evaluate_task(task: ViewTask) -> ViewOutcome:
    """Load the task's view (its ``load`` CPU time counted as stage ``load``) and evaluate it."""
    t0 = time.process_time()
    view = task.source.load()
    load_s = time.process_time() - t0
    out = evaluate_view(view, task.methods, task.options)
    out.stage_s["load"] = out.stage_s.get("load", 0.0) + load_s
    return out
