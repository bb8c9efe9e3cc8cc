"""Report sections of the per-wall strategies (pipeline.walls): per window vs per wall on the same
windows, the focal length found with K withheld, and the calibration of the 90 % intervals."""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from fenestra.bench.paired import PairedTable
from fenestra.conventions import PAPER
from fenestra.methods import Method, read_methods

PER_WINDOW = PAPER.pose  # the reference of the comparisons: the paper's per-window solver


def wall_poses(df: pd.DataFrame) -> list[str]:
    """The per-wall strategies (capability ``per_wall`` of pipeline.reconstruct.POSES) present, with
    K given, in a results table."""
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415 (fenestra.pipeline.reconstruct loads SciPy: imported when first used)

    return [p for p in POSES.where(per_wall=True) if (df["pose"] == p).any()]


def without_lines(pose: str, poses: list[str]) -> str | None:
    """The per-wall strategy of ``poses`` that is ``pose`` without the façade's line segments (its
    WallParams with ``lines`` and ``snap_sigma`` off), or None (``pose`` uses no lines, or that
    strategy is not there)."""
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415 (fenestra.pipeline.reconstruct loads SciPy: imported when first used)

    w = POSES[pose].wall
    if w is None or not w.lines:
        return None
    plain = dataclasses.replace(w, lines=False, snap_sigma=False)
    return next((p for p in poses if POSES[p].wall == plain), None)


def k_withheld(df: pd.DataFrame) -> pd.Series:
    """Per row: whether its method ran with K withheld (each method's label parsed once)."""
    methods = read_methods(df["method"].unique())
    return df["method"].isin([m for m, meth in methods.items() if meth.withhold_K])


def paired_rows(df: pd.DataFrame, pose: str, ref: str = PER_WINDOW, table: PairedTable | None = None) -> list[list]:
    """Per detector x snapper: rotation (median, p90) and aspect p90 of the pose ``ref`` (default
    per-window LM) and the per-wall strategy ``pose``, paired on the windows where both have an
    estimate, and the Wilcoxon p of the rotation. table: df's PairedTable, if already made."""
    table = table if table is not None else PairedTable(df)
    cols = ["rot_err_deg", "aspect_err_rel"]
    rows = []
    present = set(df["method"].unique())
    for det, snap in sorted(df[["detector", "snapper"]].drop_duplicates().itertuples(index=False)):
        a, b = Method(det, snap, ref).label, Method(det, snap, pose).label
        if not {a, b} <= present:
            continue
        rot = table.compare(b, a, "rot_err_deg")
        both = pd.concat({a: table.rows(a)[cols], b: table.rows(b)[cols]}, axis=1, join="inner").dropna()
        if both.empty:
            continue
        q = both.quantile(0.9)
        rows.append([f"{det}/{snap}", rot["n"], rot["median_b"], rot["median_a"], q[(a, "rot_err_deg")],
                     q[(b, "rot_err_deg")], q[(a, "aspect_err_rel")], q[(b, "aspect_err_rel")], rot["a_better"],
                     rot["p_value"]])
    return rows


def focal_rows(df: pd.DataFrame) -> list[list]:
    """Per K-withheld method: windows with a focal estimate, median and p90 relative error, failures."""
    ev = df[df["evaluable"].astype(bool) & k_withheld(df)]
    rows = []
    for m, g in ev.groupby("method"):
        e = g["focal_err_rel"].to_numpy(float)
        e = e[np.isfinite(e)]
        detected = g[g["status"] != "missed"]
        rows.append([m, len(e), float(np.median(e)) if e.size else float("nan"),
                     float(np.percentile(e, 90)) if e.size else float("nan"),
                     float((detected["status"] == "failed").mean()) if len(detected) else float("nan")])
    return rows


def calibration_rows(df: pd.DataFrame) -> list[list]:
    """Per method with intervals: windows, coverage of aspect / rotation / translation 90 % intervals,
    median interval half-widths (aspect relative, rotation deg)."""
    ev = df[df["evaluable"].astype(bool)]
    rows = []
    for m, g in ev.groupby("method"):
        g = g[g["aspect_in90"].notna()] if "aspect_in90" in g else g.iloc[:0]
        if g.empty:
            continue
        rows.append([m, len(g), g["aspect_in90"].mean(), g["rot_in90"].mean(), g["trans_in90"].mean(),
                     g["aspect_ci90_rel"].median(), g["rot_ci90_deg"].median()])
    return rows


def wall_sections(df: pd.DataFrame, table: PairedTable | None = None) -> list[tuple]:
    """Report sections (build.py's tuple format); empty for a run without per-wall methods.
    table: df's PairedTable, if already made."""
    if "pose" not in df or not wall_poses(df):
        return []
    s: list[tuple] = [("h2", "Per window or per wall (shared plane)")]
    s.append(("p", "Same evaluable windows, paired (both estimates present). 'wall' groups a view's windows into "
                   "walls by their vanishing directions and fits one rotation per wall over all their corners; "
                   "'building' also ties walls at right angles into one rotation (fenestra/pipeline/walls/strategies.py); '+lines' "
                   f"adds the photo's line segments along the walls' two directions; '{PER_WINDOW}' is the paper's "
                   "per-window solver."))
    poses = wall_poses(df)
    table = table if table is not None else PairedTable(df)
    pairs = [(p, PER_WINDOW) for p in poses] + [(p, without_lines(p, poses)) for p in poses
                                                 if without_lines(p, poses) is not None]
    for pose, ref in pairs:
        if ref != PER_WINDOW:
            s.append(("p", f"With and without the façade's line segments: '{pose}' against '{ref}'."))
        s.append(("table", ["detector/snapper", "n paired", f"rot median {ref}", f"rot median {pose}", f"rot p90 {ref}",
                            f"rot p90 {pose}", f"aspect p90 {ref}", f"aspect p90 {pose}", f"{pose} better on",
                            "Wilcoxon p"], paired_rows(df, pose, ref, table)))
    if k_withheld(df).any():
        s.append(("h3", "Focal length with K withheld ('+noK')"))
        s.append(("p", "The pipeline gets the image only (principal point assumed at the image centre); relative "
                       "error of the focal length it finds. A view whose walls leave f unobservable fails."))
        s.append(("table", ["method", "windows with f", "median rel. error", "p90 rel. error", "failure rate"],
                  focal_rows(df)))
    cal = calibration_rows(df)
    if cal:
        s.append(("h3", "Uncertainty: coverage of the 90 % intervals"))
        s.append(("p", "Fraction of windows whose true error lies inside their 90 % interval (first-order "
                       "covariance of the wall fit); well calibrated is 0.85-0.95."))
        s.append(("table", ["method", "windows", "aspect", "rotation", "translation", "median aspect ±",
                            "median rotation bound deg"], cal))
    return s
