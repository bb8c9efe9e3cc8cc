"""The bench's measurements, one evaluator per kind of truth, over what a session gave.

    evaluators = default_evaluators()            # a fresh set per view (they keep per-view memos)
    for e in evaluators: e.reset(view)
    for method: result = MethodResult(view, rec, rec_storey, det_for_gt)
        columns = {g: {} for g in result.det_for_gt}
        for e in evaluators:                     # in order: a later evaluator's column wins
            for g, c in e.process(view, result).items(): columns[g].update(c)

In the manner of detectron2's ``DatasetEvaluator.process(inputs, outputs)``: an evaluator is told
the labelled view (bench.views.LabelledView: its truth) and one method's result on it
(:class:`MethodResult`: the pipeline.session.Reconstruction, with nothing known and with the true
storey height, and the matching of its detections to the labelled windows), and returns, per matched
labelled window, its own declared :attr:`Evaluator.columns` (a missing truth is NaN, never 0:
:meth:`Evaluator.process` leaves the column out or sets it NaN). bench.evaluate is the loop that
runs them and writes the rows; the table's column order is bench.evaluate's.

What each window is measured as (pipeline.session.Window): the corner, aspect-ratio, pose and
uncertainty errors on ``measured`` (the measurement's accuracy; a window cut by the photo's border:
its whole-window failure), the BIM errors on ``shipped`` (what a BIM user gets: its row's
regularized sill and head), the export decision on ``export``, the written model (its vertical, its
walls' tilt, its storey rows: :class:`ModelEvaluator`) on pipeline.photo.written_model. The pure
measures of the written model here (:func:`wall_tilts_deg`, :func:`row_spreads`) serve the K-free
block's evaluators too (bench.photo_eval), which read the same typed values.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from fenestra.bench import metrics, uncertainty
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra.pipeline.quad import corners_to_quad
from fenestra.bench.render_adapter import house_path
from fenestra.errors import SceneError
from fenestra.scenes.registry import resolve
from fenestra.scenes.storeys import storey_elevations_m, storey_index

NAN = float("nan")


@dataclass(frozen=True)
class MethodResult:
    """One method's result on one view, as the evaluators see it.

    rec: the method's pipeline.session.Reconstruction with nothing known (the assumed scale);
    rec_storey: the same with the house's true storey height known (renders of houses with two
    storeys or more), or None; det_for_gt: {labelled window index: (detection index, match IoU)}
    for the matched labelled windows (bench.matching; the others are missed).
    """

    rec: object
    rec_storey: object | None
    det_for_gt: dict

    def measured(self, g: int):
        """The WindowResult labelled window ``g`` is measured as (its detection's Window.measured)."""
        return self.rec.windows[self.det_for_gt[g][0]].measured


class Evaluator(Protocol):
    """One kind of truth's measurement. ``columns``: the columns it returns (its schema);
    :meth:`reset` starts a view (per-view memos); :meth:`process` measures one method's result:
    {labelled window index: {column: value}} for matched windows, columns among ``columns``."""

    columns: tuple[str, ...]

    def reset(self, view: LabelledView) -> None: ...

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]: ...


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


# ---------------------------------------------------------------- pure per-window errors

CORNER_COLUMNS = ("corner_err_px_mask", "corner_err_px_mask_max", "corner_err_px_snap", "corner_err_px_snap_max",
                  "corner_err_px_reproj", "corner_err_px_reproj_max", "snap_gain_px", "iou_2d", "iou_2d_mask",
                  "iou_2d_reproj")
ASPECT_COLUMNS = ("aspect_est", "aspect_err_rel")
POSE_COLUMNS = ("rot_err_deg", "normal_err_deg", "trans_err_m")


def corner_errors(res, w: LabelledWindow, quad_iou=metrics.quad_iou) -> dict:
    """CORNER_COLUMNS of one WindowResult against the window's labelled quad (px; IoU a fraction):
    the mean and largest corner error of the mask-fit, snapped and reprojected quads, the snapping's
    gain, and their 2D IoU; {} without a labelled quad, a stage's columns absent where it has none."""
    out: dict[str, float] = {}
    if w.quad is None:
        return out
    stages = {"mask": res.quad_mask, "snap": res.quad_snapped, "reproj": res.quad_reprojected}
    for s, q in stages.items():
        if _finite(q):
            e = metrics.corner_errors_px(q, w.quad)
            out[f"corner_err_px_{s}"], out[f"corner_err_px_{s}_max"] = float(e.mean()), float(e.max())
    out["snap_gain_px"] = out.get("corner_err_px_mask", NAN) - out.get("corner_err_px_snap", NAN)
    for col, s in (("iou_2d", "snap"), ("iou_2d_mask", "mask"), ("iou_2d_reproj", "reproj")):
        if _finite(stages[s]):
            out[col] = quad_iou(stages[s], w.quad)
    return out


def aspect_errors(res, w: LabelledWindow) -> dict:
    """ASPECT_COLUMNS: the estimated w/h (no truth needed) and, with a labelled aspect, its
    relative error; {} without a finite estimate."""
    if res.aspect_ratio is None or not math.isfinite(res.aspect_ratio):
        return {}
    out = {"aspect_est": float(res.aspect_ratio)}
    if w.aspect is not None:
        out["aspect_err_rel"] = metrics.aspect_error_rel(res.aspect_ratio, w.aspect)
    return out


def pose_errors(res, w: LabelledWindow, gt_pose: tuple[np.ndarray, np.ndarray] | None) -> dict:
    """POSE_COLUMNS against the window's true (R, t) (metrics.gt_window_pose; renders): rotation and
    normal error (deg), translation error at the true scale (m); {} without a pose or its truth."""
    if gt_pose is None or res.R is None or res.t is None:
        return {}
    R_gt, t_gt = gt_pose
    return {"rot_err_deg": metrics.rotation_error_deg(res.R, R_gt),
            "normal_err_deg": metrics.normal_error_deg(res.R, R_gt),
            "trans_err_m": metrics.translation_error_m(res.t, res.height_m, t_gt, w.size_m[1])}


def consistency_errors(res, K: np.ndarray | None) -> dict:
    """``reproj_consistency_px``: the snapped quad against the reprojected one (px), with a known
    K (with the focal length estimated from the same quad it is 0 by construction); {} else."""
    if _finite(res.quad_snapped) and _finite(res.quad_reprojected) and K is not None:
        return {"reproj_consistency_px": metrics.reprojection_consistency_px(res.quad_snapped, res.quad_reprojected)}
    return {}


def window_errors(res, w: LabelledWindow, gt_pose: tuple[np.ndarray, np.ndarray] | None,
                  K: np.ndarray | None, quad_iou=metrics.quad_iou, wall: int | None = None) -> dict:
    """Every error of one WindowResult against what the window's truth knows, NaN elsewhere: the
    corner, aspect, pose and consistency errors above and, with gt_pose and K, bench.uncertainty's
    columns (``wall``: the façade model's wall the window is on, for ``wall_id``). gt_pose: the
    window's true (R, t) or None; K: the view's true K or None."""
    out = dict.fromkeys((*CORNER_COLUMNS, *ASPECT_COLUMNS, *POSE_COLUMNS, "reproj_consistency_px"), NAN)
    out.update(corner_errors(res, w, quad_iou), **aspect_errors(res, w), **pose_errors(res, w, gt_pose),
               **consistency_errors(res, K))
    if gt_pose is not None and K is not None:
        out.update(uncertainty.columns(res, w.aspect, gt_pose, K, out, wall))
    return out


def head_error(det, w: LabelledWindow) -> float:
    """Mean corner error (px) of a detection's predicted corners (a corner head's; pipeline.quad.
    corners_to_quad) against the labelled quad; NaN without either, or when they are not a quad."""

    if w.quad is None:
        return NAN
    q = corners_to_quad(det.corners).quad
    return NAN if q is None else float(metrics.corner_errors_px(q, w.quad).mean())


def metric_errors(res, w: LabelledWindow, view: LabelledView, suffix: str) -> dict:
    """``width_err_m``, ``height_err_m`` (|error| m, the window at its wall's scale) and
    ``pos_err_m`` (its centre, camera frame; renders) of one window of a façade model, each
    name + ``suffix``; NaN where the window has no pose or the truth no size."""
    out = {f"{k}{suffix}": NAN for k in ("width_err_m", "height_err_m", "pos_err_m")}
    if res.failure is not None or res.R is None or res.aspect_ratio is None or w.size_m is None:
        return out
    out[f"width_err_m{suffix}"], out[f"height_err_m{suffix}"] = metrics.size_errors_m(res.aspect_ratio, res.height_m,
                                                                                    w.size_m)
    if view.pose is not None and w.corners_world is not None:
        out[f"pos_err_m{suffix}"] = metrics.centre_error_m(res.R, res.t, res.aspect_ratio * res.height_m, res.height_m,
                                                          *view.pose, w.corners_world)
    return out


# ---------------------------------------------------------------- the written model (pure, typed)

def house_elevations_m(view: LabelledView) -> tuple[float, ...] | None:
    """The IfcBuildingStorey elevations (m) of the house a render shows
    (fenestra.scenes.storeys.storey_elevations_m); None for a photo or a view folder made by hand
    (it names no house)."""
    if view.pose is None:
        return None

    try:
        path = resolve(house_path(view.dataset))
    except SceneError:  # a view folder made by hand names no house
        return None
    return storey_elevations_m(str(path))


def exported_windows(rec) -> list:
    """The pipeline.session.Windows of ``rec`` (a Reconstruction) that go into the BIM model
    (``Window.export``; partial windows among them), in detection order."""
    return [w for w in rec.windows if w.export.exported]


def _metres(v) -> float:
    return math.nan if v is None else float(v)


def window_size_m(res) -> tuple[float, float]:
    """(width, height) m of a WindowResult as windows.json gives them (a partial window's visible
    extent): width NaN without an aspect ratio or a pose, height NaN without one."""
    width = NAN if res.aspect_ratio is None or res.R is None else res.aspect_ratio * res.height_m
    return _metres(width), _metres(res.height_m)


def wall_tilts_deg(rec, up) -> dict[int, float]:
    """{wall id: the angle in degrees between its plane and ``up`` (3,) camera frame} for each
    wall of the façade model holding an exported window: asin |normal . up|; 0 for a plumb wall."""
    up = np.asarray(up, dtype=np.float64).reshape(3)
    up = up / np.linalg.norm(up)
    on = {w.wall for w in exported_windows(rec)}
    return {wall.id: float(np.degrees(np.arcsin(min(1.0, abs(wall.normal @ up) / np.linalg.norm(wall.normal)))))
            for wall in rec.model.walls if wall.id in on}


def row_spreads(rec, rows: list[list[int]]) -> list[float]:
    """Per row of windows of the written model (``rows``: each row's window indices,
    pipeline.export.WrittenModel.rows) with at least two whole (not partial) exported windows:
    (max - min) / median of their heights (m, Window.result); dimensionless, 0 when they agree."""
    height = {w.index: window_size_m(w.result)[1] for w in exported_windows(rec) if w.result.partial is None}
    out = []
    for row in rows:
        h = np.array([height[i] for i in row if i in height])
        h = h[np.isfinite(h)]
        if len(h) >= 2:
            out.append(float((h.max() - h.min()) / np.median(h)))
    return out


# ---------------------------------------------------------------- the evaluators

class MatchEvaluator:
    """Detection: the match of each labelled window (its IoU with the detection it matched, that
    detection's score)."""

    columns = ("match_iou", "det_score")

    def reset(self, view: LabelledView) -> None:
        pass

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]:
        dets = result.rec.detections
        return {g: {"match_iou": iou, "det_score": float(dets[d].score)} for g, (d, iou) in result.det_for_gt.items()}


class CornerEvaluator:
    """A labelled quad: corner errors and 2D IoU of the window as measured, and the error of its
    detection's predicted corners (``corner_err_px_head``, kept per view for every method of a
    detector); quad IoUs computed once per pair on a view (:class:`QuadIoUMemo`)."""

    columns = (*CORNER_COLUMNS, "corner_err_px_head")

    def reset(self, view: LabelledView) -> None:
        self.quad_iou, self.heads = QuadIoUMemo(), {}

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]:
        out = {}
        for g, (d, _) in result.det_for_gt.items():
            w, k = view.windows[g], (result.rec.method.detector, d, g)  # a detector's detections: every method's
            if k not in self.heads:
                self.heads[k] = head_error(result.rec.detections[d], w)
            out[g] = {**corner_errors(result.measured(g), w, self.quad_iou), "corner_err_px_head": self.heads[k]}
        return out


class AspectEvaluator:
    """A labelled aspect ratio: the estimate and its relative error."""

    columns = ASPECT_COLUMNS

    def reset(self, view: LabelledView) -> None:
        pass

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]:
        return {g: aspect_errors(result.measured(g), view.windows[g]) for g in result.det_for_gt}


class PoseEvaluator:
    """An exact pose (renders): rotation, normal and translation errors, and the per-wall
    strategies' focal estimate and uncertainty calibration (bench.uncertainty, with the view's K);
    each window's true pose computed once per view."""

    columns = (*POSE_COLUMNS, *uncertainty.COLUMNS)

    def reset(self, view: LabelledView) -> None:
        self.gt_poses: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]:
        if view.pose is None:
            return {}
        out = {}
        for g, (d, _) in result.det_for_gt.items():
            w, res = view.windows[g], result.measured(g)
            if g not in self.gt_poses:
                self.gt_poses[g] = metrics.gt_window_pose(*view.pose, w.corners_world)
            errs = pose_errors(res, w, self.gt_poses[g])
            if view.K is not None:
                win = result.rec.windows[d]  # its wall as measured: none for a partial one (placed only as its visible part)
                full = {**dict.fromkeys(POSE_COLUMNS, NAN), **errs}
                errs.update(uncertainty.columns(res, w.aspect, self.gt_poses[g], view.K, full,
                                                None if win.placed is not None else win.wall))
            out[g] = errs
        return out


class ConsistencyEvaluator:
    """No truth but a known K: the snapped quad against the pose's reprojection."""

    columns = ("reproj_consistency_px",)

    def reset(self, view: LabelledView) -> None:
        pass

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]:
        return {g: consistency_errors(result.measured(g), view.K) for g in result.det_for_gt}


class RelativeSizeEvaluator:
    """Known sizes on a coplanar photo: each window's relative size error against the others'
    (bench.metrics.relative_size_errors; windows with a pose and a known size, at least two)."""

    columns = ("rel_size_err",)

    def reset(self, view: LabelledView) -> None:
        pass

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]:
        if not view.coplanar:
            return {}
        res = {g: result.measured(g) for g in result.det_for_gt}
        idx = [g for g, r in res.items() if r.R is not None and view.windows[g].size_m is not None]
        if len(idx) < 2:
            return {}
        # distance per unit of the window's own scale: invariant to the façade model's move along the ray
        d = [metrics.plane_distance(res[g].R, res[g].t) / float(res[g].height_m) for g in idx]
        errs = metrics.relative_size_errors(np.array(d), np.array([view.windows[g].size_m[1] for g in idx]))
        return {g: {"rel_size_err": float(e)} for g, e in zip(idx, errs)}


class BimEvaluator:
    """What a BIM user gets, per matched window: where K came from (``K_source``) and its focal
    length (``K_focal_px``; where K was not given and the view's K is known, ``focal_est_px`` and
    ``focal_err_rel`` of the K used, replacing the per-wall fit's own), how its wall got its scale
    (``scale_source``), the export decision (``exported`` 1.0 / 0.0, ``not_exported``), and the
    metric errors (:func:`metric_errors`) of the window as shipped with nothing known and, suffix
    ``_storey``, with the true storey height known (NaN without one)."""

    columns = ("K_source", "K_focal_px", "scale_source", "exported", "not_exported", "width_err_m", "height_err_m",
               "pos_err_m", "scale_source_storey", "width_err_m_storey", "height_err_m_storey", "pos_err_m_storey",
               "focal_est_px", "focal_err_rel")

    def reset(self, view: LabelledView) -> None:
        pass

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]:
        rec, rec_storey = result.rec, result.rec_storey
        out = {}
        for g, (d, _) in result.det_for_gt.items():
            w, win = view.windows[g], rec.windows[d]
            c = {"K_source": rec.resolved.source, "K_focal_px": float(rec.K[0, 0]),
                 "scale_source": rec.scale_source(d), "exported": float(win.export.exported),
                 "not_exported": win.export.reason or "", **metric_errors(win.shipped, w, view, "")}
            if rec_storey is not None:
                c.update(metric_errors(rec_storey.windows[d].shipped, w, view, "_storey"),
                         scale_source_storey=rec_storey.scale_source(d))
            if rec.resolved.source != "K" and view.K is not None:  # the focal chain's answer against the truth
                f_true = float(np.sqrt(view.K[0, 0] * view.K[1, 1]))
                c.update(focal_est_px=float(rec.K[0, 0]), focal_err_rel=abs(float(rec.K[0, 0]) - f_true) / f_true)
            out[g] = c
        return out


MODEL_COLUMNS = ("model_up_err_deg", "model_wall_tilt_deg", "model_storey", "true_storey", "model_n_storeys",
                 "true_n_storeys")


def angle_deg(a, b) -> float:
    """The angle (deg) between two (3,) directions."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return float(np.degrees(np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))))


def true_storeys(view: LabelledView) -> dict[int, int]:
    """{labelled window index: the storey it stands on (0 = the ground floor)} of a render of a
    known house: its sill (its world corners' lowest z, m) on the house's IFC storeys
    (fenestra.scenes.storeys.storey_index); {} for a photo or a house of unknown storeys; a
    window below the ground floor has none."""

    elevations = house_elevations_m(view)
    if not elevations:
        return {}
    out = {}
    for g, w in enumerate(view.windows):
        s = None if w.corners_world is None else storey_index(float(np.min(w.corners_world[:, 2])), list(elevations))
        if s is not None:
            out[g] = s
    return out


class ModelEvaluator:
    """The written model (pipeline.photo.written_model: what model.ifc holds, nothing written)
    against a render's truth, the exact pose and the house's IFC storeys: the model's vertical
    against the true one (``model_up_err_deg``; the world's z in the camera frame), the tilt of
    the window's wall from the true vertical (``model_wall_tilt_deg``, deg; a wall holding an
    exported window), the storey (floor, pipeline.export.floors) the window is written in
    (``model_storey``, 0 = the model's ground floor) and the storey it stands on (``true_storey``,
    0 = the ground floor), and per method the model's storeys (``model_n_storeys``) against the distinct true storeys of
    the labelled windows it writes (``true_n_storeys``). NaN where the window is not written or the
    truth lacks the storeys; nothing for a photo (no true vertical)."""

    columns = MODEL_COLUMNS

    def reset(self, view: LabelledView) -> None:
        self.storey = true_storeys(view)

    def process(self, view: LabelledView, result: MethodResult) -> dict[int, dict]:
        if view.pose is None:
            return {}
        from fenestra.pipeline.photo import written_model  # noqa: PLC0415 (fenestra.pipeline.photo loads IfcOpenShell, SciPy: imported when first used)

        rec = result.rec
        model = written_model(rec)
        up = np.asarray(view.pose[0], dtype=np.float64) @ np.array([0.0, 0.0, 1.0])  # the world's z, camera frame
        tilts, rows = wall_tilts_deg(rec, up), model.floors.floor_of
        written = {g: d for g, (d, _) in result.det_for_gt.items() if d in rows}
        shown = {self.storey[g] for g in written if g in self.storey}
        per_view = {"model_up_err_deg": angle_deg(model.up, up), "model_n_storeys": float(len(model.floors.elevations_m)),
                    "true_n_storeys": float(len(shown)) if self.storey else NAN}
        return {g: {**per_view, "model_wall_tilt_deg": tilts.get(rec.windows[d].wall, NAN),
                    "model_storey": float(rows[d]) if d in rows else NAN,
                    "true_storey": float(self.storey[g]) if g in self.storey else NAN}
                for g, (d, _) in result.det_for_gt.items()}


def default_evaluators() -> list[Evaluator]:
    """A fresh set of the bench's evaluators, in the order their columns merge (a later one's
    column wins: BimEvaluator's focal_est_px over the per-wall fit's own where K was not given)."""
    return [CornerEvaluator(), AspectEvaluator(), PoseEvaluator(), ConsistencyEvaluator(), RelativeSizeEvaluator(),
            MatchEvaluator(), BimEvaluator(), ModelEvaluator()]


__all__ = ["AspectEvaluator", "BimEvaluator", "ConsistencyEvaluator", "CornerEvaluator", "Evaluator", "MatchEvaluator",
           "MethodResult", "ModelEvaluator", "PoseEvaluator", "QuadIoUMemo", "RelativeSizeEvaluator", "default_evaluators",
           "head_error", "metric_errors", "window_errors"]
