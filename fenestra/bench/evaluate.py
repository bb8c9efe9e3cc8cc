"""Evaluate one labelled view (a render or a photo): detect, match, reconstruct with every method,
measure every error its truth allows.

The unit of work of the runner's executors (bench.executors). Input: a bench.views.LabelledView
(read by the rendered-view adapter, bench.render_adapter, or a real-format adapter,
bench.real.adapters); output: one row per labelled window per method combination (never dropped:
missed, failed, non-evaluable windows and methods that cannot run on the view keep a row with
``status`` and ``reason``), the time spent per stage, and COCO material for detection AP.

Every method runs through the view's pipeline.session.PhotoSession, exactly as ``fenestra
reconstruct`` runs it on a photo (one session object, two callers): the detector at the CLI's
resolution, the quads, snapping, aspect ratio and pose, the focal chain where K is unknown or the
method withholds it (EXIF, vanishing points, prior: the rows' ``K_source``), the façade model (one
plane and one scale per wall: ``scale_source``; once with nothing known, the assumed window
height, and once with the house's true storey height, columns ``*_storey``) and the export
decision (``exported``, ``not_exported``; per view and method, ViewOutcome.export_counts: the
exported detections matched to a labelled window, on an ignore region such as a glazed door, or
on nothing, the export precision's counts). A window cut by the image border is exported as its
visible part (a partial window) but measured as the whole window it is not: its row keeps
the quad stage's ``touches_border`` failure (pipeline.session.Window.measured), its labelled
window is not evaluable (corners out of frame, or ``partial``), and its export counts like any
other (matched, on an ignore region, or on nothing). The session shares what methods have in common (each
detector runs once per view, the quads are fitted once per detector, snapping and per-window
poses are reused by the per-wall strategies), so that every method's rows are those of a run of
its own. The detections are matched to the labelled windows (mask IoU when every window has a
mask, else box IoU). The oracle detectors read the view's instance map (they stand in for a
perfect or imperfect network; they cannot run on a photo labelled with boxes only).

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

import time
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from fenestra.bench import matching, metrics, uncertainty
from fenestra.bench.evaluators import MODEL_COLUMNS, MethodResult, default_evaluators, house_elevations_m
from fenestra.bench.profiles import EvalSpec
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra import coco, masks
from fenestra.conventions import camera_depths
from fenestra.tolerances import TOL
from fenestra.methods import Method
from fenestra.pipeline.types import Status
from fenestra.pipeline.facade_model import Known, KNOWN_RANGE_M
from fenestra.scenes.storeys import storey_height_from_elevations
from fenestra.pipeline.detectors import detector_entry

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
    (an oracle needs masks). n_false_positives: {detector: its detections (score >= SCORE_MIN)
    matched to no labelled window}. export_counts: {method name: :func:`export_counts`, what the
    method exports into the BIM model with nothing known (:data:`EXPORT_COUNTS`)}.
    """

    rows: list[dict]
    stage_s: dict[str, float]
    coco_gt: list[dict] = field(default_factory=list)  # fenestra.data.gt_annotation per window / ignore region
    coco_dt: dict[str, list[dict]] = field(default_factory=dict)  # detector -> fenestra.data.coco_result
    n_false_positives: dict[str, int] = field(default_factory=dict)
    export_counts: dict[str, dict[str, int]] = field(default_factory=dict)
    dataset: str = ""
    view: str = ""
    size: tuple[int, int] = (0, 0)
    window_ids: tuple[str, ...] = ()
    frame: object = None  # pandas.DataFrame of the rows after to_frame(), else None

    def to_frame(self) -> "ViewOutcome":
        """This outcome with its rows moved into ``frame`` (a DataFrame, columns in row order)."""
        import pandas as pd  # noqa: PLC0415 (pandas: imported when first used, not at the package's import)

        if self.frame is not None:
            return self
        return replace(self, rows=[], frame=pd.DataFrame(self.rows))

    def table(self):
        """The view's rows as a DataFrame (``frame``, else built from ``rows``)."""
        import pandas as pd  # noqa: PLC0415 (pandas: imported when first used, not at the package's import)

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
# what a BIM user gets (bench.evaluators.BimEvaluator): every table, renders and photos; the written
# model against the true vertical and storeys (bench.evaluators.ModelEvaluator, MODEL_COLUMNS): renders
BIM_COLUMNS = ("K_source", "K_focal_px", "scale_source", "exported", "not_exported", "width_err_m", "height_err_m",
               "pos_err_m", "scale_source_storey", "width_err_m_storey", "height_err_m_storey", "pos_err_m_storey")
RENDER_TAIL = (*ERROR_COLUMNS, *uncertainty.COLUMNS, *BIM_COLUMNS, *MODEL_COLUMNS, "status", "reason", "aspect_case")
PHOTO_TAIL = (*ERROR_COLUMNS, *PHOTO_ERRORS, *BIM_COLUMNS, "aspect_case", "status", "reason")
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


# ---------------------------------------------------------------- the view's storey height (rec_storey)

def true_storey_m(view: LabelledView) -> float | None:
    """The storey height (m) of the house a render shows (its IFC storeys:
    fenestra.scenes.storeys), what a user who knows it gives as ``--known-storey``; None for a
    photo, a house with fewer than two storeys, or one whose storey height lies outside the range
    a user may give (pipeline.facade_model.KNOWN_RANGE_M: a split level is no storey to know)."""

    elevations = house_elevations_m(view)
    storey = None if elevations is None else storey_height_from_elevations(list(elevations))
    lo, hi = KNOWN_RANGE_M["storey_m"]
    return storey if storey is not None and lo <= storey <= hi else None


# ---------------------------------------------------------------- the session: detection and reconstruction

def view_session(view: LabelledView, options: EvalOptions, detectors: tuple[str, ...]):
    """The pipeline.session.PhotoSession a user's ``fenestra reconstruct`` would make for the
    view: the image, the view's K as the user's (if known), the instance map for the oracles, each
    of ``detectors`` with its profile options (torch threads: the worker's, bench.executors), at
    the profile's resolution (``detector_long_side``; 0: the CLI's)."""
    from fenestra.pipeline.session import PhotoSession, UserCamera  # noqa: PLC0415 (fenestra.pipeline.session loads SciPy: imported when first used)

    opts = {name: options.options_of(name) for name in detectors}
    return PhotoSession(view.image, camera=None if view.K is None else UserCamera(view.K, "the view's K"),
                        instances=view.instance_map(), detector_options=opts,
                        max_side=options.detector_long_side or None)


def _match_ious(view: LabelledView, det_masks: list[masks.SparseMask], dets: list) -> np.ndarray:
    """(D, G) mask IoU when every window has a mask, else box IoU."""
    if view.has_masks:
        return matching.iou_matrix(det_masks, [w.mask for w in view.windows])
    return metrics.box_iou_matrix([d.box for d in dets], [w.bbox() for w in view.windows])


def on_ignore(view: LabelledView, det_masks: list[masks.SparseMask], dets: list) -> dict[int, str | None]:
    """{detection index into ``dets``: the kind of the ignore region it lies on most} for the
    detections lying on one of the view's ignore regions (a glazed door, curtain-wall glazing:
    LabelledWindow.kind, None when the labels do not say): at least TOL.match_iou of the detection
    inside one region (COCO's test against an ``iscrowd`` region), by mask when every region has
    one, else by box."""
    if not view.ignore or not dets:
        return {}
    if all(r.mask is not None for r in view.ignore):
        cover = matching.cover_matrix(det_masks, [r.mask for r in view.ignore])
    else:
        cover = metrics.box_cover_matrix([d.box for d in dets], [r.bbox() for r in view.ignore])
    return {int(d): view.ignore[int(cover[d].argmax())].kind for d in np.nonzero(cover.max(axis=1) >= TOL.match_iou)[0]}


# what a method exports, counted per view (ViewOutcome.export_counts; summed by bench.results.export_precision)
EXPORT_COUNTS = ("n_exported", "n_matched", "n_on_ignore", "n_on_nothing", "n_on_door")
DOOR_KIND = "glazed_door"  # an ignore region that is an IfcDoor (fenestra.renders.gt.IGNORE_KINDS)


def export_counts(rec, matched: set[int], ignored: dict[int, str | None]) -> dict[str, int]:
    """What one method's Reconstruction exports (``rec.exported``), as EXPORT_COUNTS: the exported
    detections; of them, those matched to a labelled window (``matched``: detection indices), those
    matched to none but lying on an ignore region (``ignored``: {detection: the region's kind}, a
    door or glazing exported as a window) and those on neither. n_exported = n_matched +
    n_on_ignore + n_on_nothing. n_on_door: of n_on_ignore, those on a glazed door (DOOR_KIND): an
    IfcDoor of the truth that the model writes as an IfcWindow, the written model's class error."""
    out = dict.fromkeys(EXPORT_COUNTS, 0)
    for d, exported in rec.exported.items():
        if exported:
            out["n_exported"] += 1
            out["n_matched" if d in matched else "n_on_ignore" if d in ignored else "n_on_nothing"] += 1
            out["n_on_door"] += d not in matched and ignored.get(d) == DOOR_KIND
    return out


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


def _method_rows(view: LabelledView, base: list[dict], method: Method, tail: tuple[str, ...],
                 result: MethodResult, evaluators: list) -> list[dict]:
    """One method's rows, one per labelled window in order: missed, or the columns every evaluator
    (bench.evaluators) gives it, merged in their order, with its status, reason and aspect case.
    A detection cut by the image border is measured as the whole window it failed to be (status
    ``failed``, ``touches_border``: Window.measured); that its visible part is exported shows in the
    BIM columns (``exported``, ``scale_source``) and the export counts, its sizes stay NaN.

    result: the method's bench.evaluators.MethodResult on the view; evaluators: the view's
    (reset for it), each run once on the method."""
    columns: dict[int, dict] = {g: {} for g in result.det_for_gt}
    for e in evaluators:
        for g, c in e.process(view, result).items():
            columns[g].update(c)
    rows = []
    for g, b in enumerate(base):
        if g not in result.det_for_gt:
            rows.append(_method_row(b, method, tail, status=Status.MISSED.value, reason="missed", aspect_case=None))
            continue
        res = result.measured(g)  # a partial window: its whole-window failure (its export: the BIM columns)
        rows.append(_method_row(b, method, tail, **columns[g],
                                aspect_case=None if res.aspect_case is None else res.aspect_case.value,
                                status=res.status.value, reason="" if res.failure is None else f"failed: {res.failure}"))
    return rows


def evaluate_view(view: LabelledView, methods: tuple[Method, ...], options: EvalOptions) -> ViewOutcome:
    """Rows for every (labelled window x method) of one view; see the module docstring.

    The view gets one pipeline.session.PhotoSession (:func:`view_session`) and every method is
    its ``run``: what ``fenestra reconstruct`` gives on the same image and K. A method's windows are
    matched to the labels through its detector's detections (score >= SCORE_MIN, the CLI's);
    every candidate down to CANDIDATE_SCORE_MIN feeds detection AP.
    """
    from fenestra.pipeline.session import SCORE_MIN  # noqa: PLC0415 (fenestra.pipeline.session loads SciPy: imported when first used)

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
    evaluators = default_evaluators()  # one set per view: their memos are the view's
    for e in evaluators:
        e.reset(view)
    storey = true_storey_m(view)
    t0 = tick("load", t0)
    session = view_session(view, options, tuple(dict.fromkeys(m.detector for m in methods)))
    t0 = tick("reconstruct", t0)
    can_oracle = view.instance_map() is not None

    for det_name in dict.fromkeys(m.detector for m in methods):
        det_methods = [m for m in methods if m.detector == det_name]
        if detector_entry(det_name).needs_instances and not can_oracle:
            why = f"not run: {det_name} needs ground-truth masks, the labels are boxes"
            out.rows += [_method_row({**b, "evaluable": False, "eval_reason": "no_gt_masks"}, m, cols,
                                     status=Status.MISSED.value, reason=why, aspect_case=None)
                         for m in det_methods for b in base]
            continue
        cands = session.candidates(det_name)
        keep = [i for i, d in enumerate(cands) if d.score >= SCORE_MIN]  # = session.detections(det_name)
        dets = [cands[i] for i in keep]
        t0 = tick("detect", t0)
        sparse = [masks.SparseMask.from_crop(d.mask, d.origin, view.size) for d in cands]
        out.coco_dt[det_name] = [coco.coco_result(view.key, d.score, d.box, m.rle()) for d, m in zip(cands, sparse)]
        kept = [sparse[i] for i in keep]
        mt = matching.match(_match_ious(view, kept, dets), TOL.match_iou)
        out.n_false_positives[det_name] = len(mt.false_positives)
        det_for_gt = mt.det_for_gt()
        matched = {d for d, _ in det_for_gt.values()}
        ignored = on_ignore(view, kept, dets)
        t0 = tick("match", t0)
        for method in det_methods:
            rec = session.run(method, height_m=options.height_m)
            rec_storey = None if storey is None else session.run(method, Known(storey_m=storey),
                                                                 height_m=options.height_m)
            t0 = tick("reconstruct", t0)
            out.export_counts[method.name] = export_counts(rec, matched, ignored)
            out.rows += _method_rows(view, base, method, cols, MethodResult(rec, rec_storey, det_for_gt), evaluators)
            t0 = tick("metrics", t0)
    for k, s in session.stage_s.items():  # inside "detect" and "reconstruct": where the session's CPU went
        stage_s[f"session.{k}"] = s
    return out


def evaluate_task(task: ViewTask) -> ViewOutcome:
    """Load the task's view (its ``load`` CPU time counted as stage ``load``) and evaluate it."""
    t0 = time.process_time()
    view = task.source.load()
    load_s = time.process_time() - t0
    out = evaluate_view(view, task.methods, task.options)
    out.stage_s["load"] = out.stage_s.get("load", 0.0) + load_s
    return out
