"""Bench columns of the per-wall strategies: estimated focal length and uncertainty calibration.

Methods with K withheld (``fenestra.methods.Method.withhold_K``; pose column ``wall+noK``) run the pipeline with
K withheld (the principal point is then the image centre, as for a user's photo): their rows
carry the focal length the pipeline found (``focal_est_px``) and its relative error.

Calibration: a window with error bars (``WindowResult.uncertainty``, a pipeline.types.Uncertainty:
90 % intervals) gets ``aspect_in90`` / ``rot_in90`` / ``trans_in90`` (1.0 when its true error lies
inside the interval, 0.0 when not, NaN without intervals); the summary's calibration is their mean.
"""
from __future__ import annotations

import math

import numpy as np


NAN = float("nan")
COLUMNS = ("focal_est_px", "focal_err_rel", "aspect_in90", "rot_in90", "trans_in90",
           "aspect_ci90_rel", "rot_ci90_deg", "wall_id")
CALIBRATION = ("aspect_in90", "rot_in90", "trans_in90")


def columns(res, aspect_gt: float, gt_pose: tuple[np.ndarray, np.ndarray], K: np.ndarray, errors: dict,
            wall: int | None = None) -> dict:
    """The COLUMNS of one WindowResult against its GT window: ``aspect_gt`` its true width / height,
    ``gt_pose`` its true (R, t) (metrics.gt_window_pose), K the true intrinsics (3, 3) px;
    ``errors``: its bench.evaluate.window_errors row; wall: the façade model's wall it is on
    (pipeline.session.Window.wall; ``wall_id``), or None."""
    out = {k: NAN for k in COLUMNS}
    f_true = float(np.sqrt(K[0, 0] * K[1, 1]))
    if res.focal_estimate_px is not None and math.isfinite(res.focal_estimate_px):
        out["focal_est_px"] = float(res.focal_estimate_px)
        out["focal_err_rel"] = abs(res.focal_estimate_px - f_true) / f_true
    if wall is not None:
        out["wall_id"] = float(wall)
    u = res.uncertainty
    if u is None or res.R is None:
        return out
    out["aspect_in90"] = float(u.aspect_lo <= aspect_gt <= u.aspect_hi)
    out["aspect_ci90_rel"] = 0.5 * (u.aspect_hi - u.aspect_lo) / res.aspect_ratio
    out["rot_ci90_deg"] = u.rot_deg
    out["rot_in90"] = float(errors["rot_err_deg"] <= u.rot_deg)
    t_gt = gt_pose[1]
    out["trans_in90"] = float(errors["trans_err_m"] / np.linalg.norm(t_gt) <= u.trans_rel)
    return out
