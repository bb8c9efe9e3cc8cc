"""A synthetic results table with known structure, for testing summaries, reports and gates.

Not benchmark output: errors are drawn from chosen distributions so that tests know the answer
(e.g. snapper "good" halves the mask-fit error, "bad" adds to it). Columns follow bench.evaluate.
"""
from __future__ import annotations

import numpy as np
import pandas as pd


def synthetic_results(n_windows: int = 200, seed: int = 0,
                      snap_factor: dict[str, tuple[float, float]] | None = None,
                      miss_rate: float = 0.05, not_evaluable_rate: float = 0.1) -> pd.DataFrame:
    """Rows for n_windows GT windows x one detector ("oracle") x snappers x one pose ("lm").

    snap_factor: snapper -> (scale, offset px): snapped error = scale * mask error + offset
    (default {"good": (0.5, 0.0), "bad": (1.5, 1.0)}). Mask-fit errors are lognormal with median
    2 px, so the snapped medians are known: good ~1 px, bad ~4 px. Missed windows (the same for
    every method, as the detector is shared) have NaN errors and status "missed".
    """
    snap_factor = snap_factor or {"good": (0.5, 0.0), "bad": (1.5, 1.0)}
    rng = np.random.default_rng(seed)
    mask_err = np.exp(rng.normal(np.log(2.0), 0.5, n_windows))
    incidence = rng.uniform(0, 75, n_windows)
    distance = rng.uniform(4, 25, n_windows)
    window_px = rng.uniform(15, 150, n_windows)
    missed = rng.random(n_windows) < miss_rate
    not_ev = rng.random(n_windows) < not_evaluable_rate
    aspect_err = np.abs(rng.normal(0, 0.02, n_windows))
    rows = []
    for s, (scale, off) in snap_factor.items():
        for i in range(n_windows):
            snap = scale * mask_err[i] + off
            row = {
                "profile": "synthetic", "house": "synthetic", "renderer": "none",
                "view": f"{i // 4:06d}", "window_id": f"w{i}", "instance_id": i % 4 + 1,
                "incidence_deg": incidence[i], "distance_m": distance[i],
                "visible_fraction": 0.5 if not_ev[i] else 1.0, "n_corners_visible": 4,
                "corners_in_frame": True, "window_px": window_px[i],
                "window_area_px": window_px[i] ** 2 * 1.5, "mask_px": int(window_px[i] ** 2),
                "gt_width_m": 1.2, "gt_height_m": 1.5, "gt_aspect": 0.8,
                "evaluable": not not_ev[i], "eval_reason": "occluded" if not_ev[i] else "",
                "detector": "oracle", "snapper": s, "pose": "lm", "method": f"oracle/{s}/lm",
                "corner_err_px_mask": mask_err[i], "corner_err_px_mask_max": 1.5 * mask_err[i],
                "corner_err_px_snap": snap, "corner_err_px_snap_max": 1.5 * snap,
                "corner_err_px_reproj": snap * 1.1, "corner_err_px_reproj_max": snap * 1.6,
                "snap_gain_px": mask_err[i] - snap, "aspect_est": 0.8 * (1 + aspect_err[i] * scale),
                "aspect_err_rel": aspect_err[i] * scale, "rot_err_deg": snap * 0.3,
                "normal_err_deg": snap * 0.25, "trans_err_m": snap * 0.01, "iou_2d": 0.95,
                "iou_2d_mask": 0.93, "iou_2d_reproj": 0.94, "match_iou": 0.97, "det_score": 1.0,
                "aspect_case": "general", "status": "ok", "reason": "",
            }
            if missed[i]:
                for k in list(row):
                    if k.startswith(("corner_err", "snap_gain", "aspect_e", "rot_", "normal_",
                                     "trans_", "iou_2d", "match_iou", "det_score")):
                        row[k] = np.nan
                row.update(status="missed", reason="missed", aspect_case=None)
            rows.append(row)
    return pd.DataFrame(rows)
