"""Evaluate one rendered view: detect, match, reconstruct with every method, measure every error.

The unit of work of the runner's process pool. Input: a view folder of the data contract
(``image.png``, ``instances.png``, ``view.json``); output: one row per ground-truth window per
method combination (never dropped: missed, failed and non-evaluable windows keep a row with a
reason), the time spent per stage, and COCO-style masks for detection AP.

The pipeline is fed exactly what a user would give it: the RGB image and K (plus the instance map
for the oracle detectors, which stand in for a perfect or imperfect network).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench import matching, metrics, uncertainty
from bench.profiles import EvalSpec
from fenestra import data
from fenestra.conventions import TOL, camera_depths
from fenestra.methods import Method

AP_SCORE_MIN = 0.05  # detections kept for COCO AP
MATCH_SCORE_MIN = 0.5  # detections passed on to matching and reconstruction
NAN = float("nan")


@dataclass(frozen=True)
class ViewTask:
    """Everything a worker needs to evaluate one view (picklable)."""

    view_dir: str
    house: str
    renderer: str
    methods: tuple[Method, ...]
    evaluation: EvalSpec
    height_m: float = 1.0
    detector_options: tuple[tuple[str, tuple[tuple[str, object], ...]], ...] = ()


@dataclass
class ViewOutcome:
    """Rows (list of dicts), seconds per stage, and COCO material for detection AP."""

    rows: list[dict]
    stage_s: dict[str, float]
    coco_gt: list[dict] = field(default_factory=list)  # fenestra.data.gt_annotation per window / ignore region
    coco_dt: dict[str, list[dict]] = field(default_factory=dict)  # detector -> fenestra.data.coco_result
    n_false_positives: dict[str, int] = field(default_factory=dict)


def window_conditions(win: dict, meta: dict, mask_px: int, spec: EvalSpec) -> dict:
    """View conditions of one GT window and whether it is evaluable (and if not, why).

    mask_px: the window's visible pixels in instances.png.

    Keys: incidence_deg, distance_m, visible_fraction, n_corners_visible, corners_in_frame,
    window_px (shortest projected side, px), window_area_px (projected quad area, px^2),
    mask_px (visible pixels in instances.png), gt_width_m, gt_height_m, gt_aspect,
    evaluable (bool), eval_reason: "" when evaluable, else the first that applies of
    behind_camera (a corner at depth <= 0), back_facing (incidence >= 90 deg), hidden (no pixel
    in instances.png, corners in the image), outside_image (no pixel, corners outside),
    out_of_frame (a corner outside the image), occluded (visible_fraction below the profile's
    minimum), too_small (shortest side below min_window_px), grazing (incidence above maximum).
    """
    W, H = int(meta["width"]), int(meta["height"])
    q = np.asarray(win["corners_px"], dtype=np.float64)
    Cw = np.asarray(win["corners_world"], dtype=np.float64)
    sides = np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)
    x, y = q[:, 0], q[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    in_frame = bool(np.all((x >= -0.5) & (x <= W - 0.5) & (y >= -0.5) & (y <= H - 0.5)))
    depth_ok = bool(np.all(camera_depths(meta["R"], meta["t"], Cw) > 0))
    width = float(np.linalg.norm(Cw[1] - Cw[0]))
    height = float(np.linalg.norm(Cw[0] - Cw[3]))
    mask_px = int(mask_px)
    c = {
        "incidence_deg": float(win.get("incidence_deg", NAN)),
        "distance_m": float(win.get("distance_m", NAN)),
        "visible_fraction": float(win.get("visible_fraction", NAN)),
        "n_corners_visible": int(sum(bool(v) for v in win.get("corner_visible", [True] * 4))),
        "corners_in_frame": in_frame,
        "window_px": float(sides.min()),
        "window_area_px": area,
        "mask_px": mask_px,
        "gt_width_m": width,
        "gt_height_m": height,
        "gt_aspect": width / height,
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


_ERROR_COLUMNS = (
    "corner_err_px_mask", "corner_err_px_mask_max", "corner_err_px_snap", "corner_err_px_snap_max",
    "corner_err_px_reproj", "corner_err_px_reproj_max", "snap_gain_px", "aspect_est",
    "aspect_err_rel", "rot_err_deg", "normal_err_deg", "trans_err_m", "iou_2d", "iou_2d_mask",
    "iou_2d_reproj", "match_iou", "det_score", "corner_err_px_head",
)


def _head_error(det, win: dict) -> float:
    """Mean corner error (px) of a detection's predicted corners (a corner head's; pipeline.quad.
    corners_to_quad), NaN where it has none or they are not a quad."""
    from pipeline.quad import corners_to_quad  # noqa: PLC0415

    q = corners_to_quad(det.corners).quad
    return NAN if q is None else float(metrics.corner_errors_px(q, np.asarray(win["corners_px"], np.float64)).mean())


def _errors(res, win: dict, gt_pose: tuple[np.ndarray, np.ndarray]) -> dict:
    """Every error of one WindowResult against its GT window (NaN where a stage produced nothing).

    gt_pose: the window's true (R, t), metrics.gt_window_pose (computed once per view and window).
    """
    out = {k: NAN for k in _ERROR_COLUMNS}
    gt_q = np.asarray(win["corners_px"], dtype=np.float64)
    for stage, quad in (("mask", res.quad_mask), ("snap", res.quad_snapped),
                        ("reproj", res.quad_reprojected)):
        if quad is not None and np.all(np.isfinite(quad)):
            e = metrics.corner_errors_px(quad, gt_q)
            out[f"corner_err_px_{stage}"] = float(e.mean())
            out[f"corner_err_px_{stage}_max"] = float(e.max())
    out["snap_gain_px"] = out["corner_err_px_mask"] - out["corner_err_px_snap"]
    if res.quad_snapped is not None and np.all(np.isfinite(res.quad_snapped)):
        out["iou_2d"] = metrics.quad_iou(res.quad_snapped, gt_q)
    if res.quad_mask is not None and np.all(np.isfinite(res.quad_mask)):
        out["iou_2d_mask"] = metrics.quad_iou(res.quad_mask, gt_q)
    if res.quad_reprojected is not None and np.all(np.isfinite(res.quad_reprojected)):
        out["iou_2d_reproj"] = metrics.quad_iou(res.quad_reprojected, gt_q)
    Cw = np.asarray(win["corners_world"], dtype=np.float64)
    w_gt = float(np.linalg.norm(Cw[1] - Cw[0]))
    h_gt = float(np.linalg.norm(Cw[0] - Cw[3]))
    if res.aspect_ratio is not None and math.isfinite(res.aspect_ratio):
        out["aspect_est"] = float(res.aspect_ratio)
        out["aspect_err_rel"] = metrics.aspect_error_rel(res.aspect_ratio, w_gt / h_gt)
    if res.R is not None and res.t is not None:
        R_gt, t_gt = gt_pose
        out["rot_err_deg"] = metrics.rotation_error_deg(res.R, R_gt)
        out["normal_err_deg"] = metrics.normal_error_deg(res.R, R_gt)
        out["trans_err_m"] = metrics.translation_error_m(res.t, res.height_m, t_gt, h_gt)
    return out


PER_WINDOW_STAGES = ("snap", "aspect", "pose")


def _reconstruct(gray: np.ndarray, K: np.ndarray | None, dets: list, quads: list, cfg, withhold_K: bool,
                 per_window: dict) -> tuple[list, tuple[str, ...]]:
    """reconstruct_from_quads of one method, and the timing keys it spent time on.

    A per-wall strategy starts from the per-window results of its base pose; those are computed
    once per snapper (or taken from that per-window method's own run) and kept in ``per_window``,
    so every method's results are exactly those of a run of its own.
    """
    from dataclasses import replace  # noqa: PLC0415

    from pipeline.reconstruct import POSES, reconstruct_from_quads  # noqa: PLC0415

    if not dets:
        return [], ()
    wall = POSES[cfg.pose].wall
    if wall is None:
        results = reconstruct_from_quads(gray, K, dets, quads, cfg)
        per_window[(cfg.snapper, cfg.pose, withhold_K)] = results
        return results, PER_WINDOW_STAGES
    key = (cfg.snapper, wall.base_pose, withhold_K)
    counted: tuple[str, ...] = ("wall",)
    if key not in per_window:
        per_window[key] = reconstruct_from_quads(gray, K, dets, quads, replace(cfg, pose=wall.base_pose))
        counted = (*PER_WINDOW_STAGES, "wall")
    return reconstruct_from_quads(gray, K, dets, quads, cfg, base=per_window[key]), counted


def _detector_options(task: ViewTask, name: str) -> dict:
    for det, opts in task.detector_options:
        if det == name:
            return dict(opts)
    return {}


def evaluate_view(task: ViewTask) -> ViewOutcome:
    """Rows for every (GT window x method) of one view; see the module docstring."""
    from pipeline.detectors import detect, detector_entry  # noqa: PLC0415
    from pipeline.quad import QuadParams  # noqa: PLC0415
    from pipeline.reconstruct import ReconstructConfig, fit_quads, to_gray  # noqa: PLC0415

    stage_s: dict[str, float] = {}

    def tick(stage: str, t0: float) -> float:  # CPU seconds of this process: robust to a busy machine
        t1 = time.process_time()
        stage_s[stage] = stage_s.get(stage, 0.0) + t1 - t0
        return t1

    t0 = time.process_time()
    view = data.read_view(task.view_dir)
    image, instances, meta = view.image, view.instances, view.meta
    K = np.asarray(meta["K"], dtype=np.float64)
    view_name = Path(task.view_dir).name
    key = f"{task.house}/{view_name}"  # the COCO image of this view
    wins = meta["windows"]
    gt_masks = data.instance_masks(instances, [int(w["instance_id"]) for w in wins])
    conds = [window_conditions(w, meta, m.area, task.evaluation) for w, m in zip(wins, gt_masks)]
    base = [{"house": task.house, "renderer": task.renderer, "view": view_name, "window_id": w["id"],
             "instance_id": int(w["instance_id"]), **c} for w, c in zip(wins, conds)]
    out = ViewOutcome(rows=[], stage_s=stage_s, coco_gt=data.view_annotations(view, key, gt_masks))
    gt_poses: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    t0 = tick("load", t0)
    gray = to_gray(image)  # RGB, as detect() and reconstruct() take it; once per view, shared by every method
    t0 = tick("reconstruct", t0)

    for det_name in dict.fromkeys(m.detector for m in task.methods):
        inst = instances if detector_entry(det_name).needs_instances else None
        # every candidate down to AP_SCORE_MIN feeds detection AP; reconstruction gets the
        # detections a user would (score >= MATCH_SCORE_MIN, the detectors' default threshold)
        cands = detect(det_name, image, score_threshold=AP_SCORE_MIN, instances=inst,
                       **_detector_options(task, det_name))
        keep = [i for i, d in enumerate(cands) if d.score >= MATCH_SCORE_MIN]
        dets = [cands[i] for i in keep]
        t0 = tick("detect", t0)
        sparse = [data.SparseMask.from_crop(d.mask, d.origin, instances.shape) for d in cands]
        out.coco_dt[det_name] = [data.coco_result(key, d.score, d.box, m.rle()) for d, m in zip(cands, sparse)]
        iou = matching.iou_matrix([sparse[i] for i in keep], gt_masks)
        mt = matching.match(iou, TOL.match_iou)
        out.n_false_positives[det_name] = len(mt.false_positives)
        det_for_gt = mt.det_for_gt()
        matched = sorted(det_for_gt.items())  # [(gt_index, (det_index, iou))]
        t0 = tick("match", t0)
        rec_dets = [dets[d] for _, (d, _) in matched]
        quads: dict = {}  # QuadParams -> fit_quads(rec_dets): the quads are fitted once per detector
        per_window: dict = {}  # (snapper, pose, K withheld) -> per-window results, reused by per-wall strategies
        for method in (m for m in task.methods if m.detector == det_name):
            withhold_K = method.withhold_K
            cfg = ReconstructConfig(snapper=method.snapper, pose=method.pose, height_m=task.height_m,
                                    quad=QuadParams(source=method.quad_source))
            if cfg.quad not in quads:
                quads[cfg.quad] = fit_quads(rec_dets, cfg.quad, gray.shape)
                stage_s["reconstruct.quad"] = (stage_s.get("reconstruct.quad", 0.0)
                                               + sum(q.ms for q in quads[cfg.quad]) / 1000.0)
            K_in = None if withhold_K else K
            results, counted = _reconstruct(gray, K_in, rec_dets, quads[cfg.quad], cfg, withhold_K, per_window)
            t0 = tick("reconstruct", t0)
            by_gt = {matched[r.index][0]: r for r in results}
            for r in results:
                for k, ms in r.timings_ms.items():
                    if k in counted:  # the shared quad fit and reused per-window stages: counted once
                        stage_s[f"reconstruct.{k}"] = stage_s.get(f"reconstruct.{k}", 0.0) + ms / 1000.0
            for g, (w, b) in enumerate(zip(wins, base)):
                row = {**b, **method.row()}
                if g not in det_for_gt:
                    row.update({k: NAN for k in (*_ERROR_COLUMNS, *uncertainty.COLUMNS)}, status="missed",
                               reason="missed", aspect_case=None)
                else:
                    res = by_gt[g]
                    if g not in gt_poses:  # the same for every method
                        gt_poses[g] = metrics.gt_window_pose(meta["R"], meta["t"], w["corners_world"])
                    errs = _errors(res, w, gt_poses[g])
                    row.update(errs, **uncertainty.columns(res, w, gt_poses[g], K, errs), aspect_case=res.aspect_case,
                               status="ok" if res.failure is None else "failed",
                               reason="" if res.failure is None else f"failed: {res.failure}")
                    row["match_iou"] = det_for_gt[g][1]
                    row["det_score"] = float(dets[det_for_gt[g][0]].score)
                    row["corner_err_px_head"] = _head_error(dets[det_for_gt[g][0]], w)
                out.rows.append(row)
            t0 = tick("metrics", t0)
    return out
