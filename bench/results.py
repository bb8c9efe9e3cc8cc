"""Results tables and summary.json of a benchmark run.

A run folder holds ``results.parquet`` (one row per view x GT window x method combination, errors
with their unit in the column name; ``results.csv``, the same table, only when asked for:
``fenestra bench --csv``) and ``summary.json``::

    {"metadata": {commit, versions, seed, profile, config, config_hash, wall_time_s, stage_time_s, ...},
     "results": {method: {n_gt, n_evaluable, detection_rate, failure_rate,
                          corner_err_px_{mask,snap,reproj}: {median, p90, max, mean, n, n_valid,
                                                             fail_rate, recall: {"1": .., "2": ..}},
                          aspect_err_rel / rot_err_deg / normal_err_deg / trans_err_m / iou_2d: {...}}},
     "detection": {detector: {bbox_AP, bbox_AP50, segm_AP, segm_AP50, ...}}}

Statistics are over *evaluable* rows (see bench.evaluate.window_base). Medians/p90 are
over windows with an estimate; recall counts a missed or failed window as not recalled.
"""
from __future__ import annotations

import importlib.metadata
import json
import math
import platform
from pathlib import Path

import numpy as np
import pandas as pd

from bench.metrics import error_stats, recall_at
from fenestra.tolerances import TOL

RESULTS_PARQUET = "results.parquet"
RESULTS_CSV = "results.csv"
SUMMARY_JSON = "summary.json"

CORNER_STAGES = ("mask", "snap", "reproj")
STAGE_LABELS = {"mask": "mask-fit", "snap": "snapped", "reproj": "reprojected"}
CALIBRATION_COLUMNS = ("aspect_in90", "rot_in90", "trans_in90")  # bench.uncertainty
OTHER_ERRORS = ("aspect_err_rel", "rot_err_deg", "normal_err_deg", "trans_err_m", "iou_2d")
# summarised when present: bench/real's; corner_err_px_head: the detector's corner head (its
# predicted corners, where it has one), beside the mask fit, for the same matched windows
OPTIONAL_ERRORS = ("reproj_consistency_px", "rel_size_err", "corner_err_px_head")
# Where a table says which windows have the truth an error needs (the real bench: bench/real),
# that error's statistics are over those windows only: absent truth is not a failure.
TRUTH_FLAGS = {**{f"corner_err_px_{s}": "has_quad" for s in CORNER_STAGES}, "iou_2d": "has_quad",
               "aspect_err_rel": "has_aspect", "rot_err_deg": "has_pose", "normal_err_deg": "has_pose",
               "trans_err_m": "has_pose", "rel_size_err": "has_size", "reproj_consistency_px": "known_K"}
REQUIRED_COLUMNS = ("method", "detector", "snapper", "pose", "evaluable", "status",
                    *(f"corner_err_px_{s}" for s in CORNER_STAGES), *OTHER_ERRORS)
VERSIONED_PACKAGES = ("numpy", "scipy", "opencv-python-headless", "ifcopenshell", "trimesh",
                      "torch", "torchvision", "mitsuba", "pyrender", "shapely", "pandas",
                      "pycocotools", "pyoidn")


def check_table(df: pd.DataFrame, where: str = "results") -> pd.DataFrame:
    """Raise ValueError naming the missing columns if ``df`` is not a results table."""
    missing = [c for c in REQUIRED_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"{where} lacks column(s) {missing}")
    return df


def write_results(df: pd.DataFrame, run_dir: str | Path, csv: bool = False) -> list[Path]:
    """Write results.parquet (the results table) into run_dir, and results.csv when ``csv``
    (a stale one is removed otherwise); return the paths written."""
    check_table(df)
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    pq, csv_path = run_dir / RESULTS_PARQUET, run_dir / RESULTS_CSV
    df.to_parquet(pq, index=False)
    if not csv:
        csv_path.unlink(missing_ok=True)
        return [pq]
    df.to_csv(csv_path, index=False)
    return [pq, csv_path]


def load_results(run_dir: str | Path) -> pd.DataFrame:
    """The results table of a run folder (Parquet, else CSV)."""
    run_dir = Path(run_dir)
    if (run_dir / RESULTS_PARQUET).is_file():
        df = pd.read_parquet(run_dir / RESULTS_PARQUET)
    elif (run_dir / RESULTS_CSV).is_file():
        df = pd.read_csv(run_dir / RESULTS_CSV)
    else:
        raise FileNotFoundError(f"{run_dir} has no {RESULTS_PARQUET} or {RESULTS_CSV}: not a run folder")
    return check_table(df, str(run_dir))


def load_summary(run_dir: str | Path) -> dict:
    """summary.json of a run folder."""
    p = Path(run_dir) / SUMMARY_JSON
    if not p.is_file():
        raise FileNotFoundError(f"{run_dir} has no {SUMMARY_JSON}")
    return json.loads(p.read_text())


def _stats_with_recall(errors: np.ndarray) -> dict:
    s = error_stats(errors)
    s["recall"] = {f"{k:g}": v for k, v in recall_at(errors, TOL.recall_thresholds_px).items()}
    return s


def summarize_method(df: pd.DataFrame) -> dict:
    """Summary of one method's rows (any rows; only evaluable ones are counted)."""
    ev = df[df["evaluable"].astype(bool)]
    n = len(ev)
    detected = int((ev["status"] != "missed").sum())
    failed = int((ev["status"] == "failed").sum())
    out: dict = {
        "n_gt": int(len(df)),
        "n_evaluable": n,
        "n_detected": detected,
        "detection_rate": detected / n if n else float("nan"),
        "failure_rate": failed / detected if detected else float("nan"),
    }
    for s in CORNER_STAGES:
        out[f"corner_err_px_{s}"] = _stats_with_recall(_with_truth(ev, f"corner_err_px_{s}"))
    for col in (*OTHER_ERRORS, *(c for c in OPTIONAL_ERRORS if c in df.columns)):
        out[col] = error_stats(_with_truth(ev, col))
    if "focal_err_rel" in ev:  # per-wall strategies with K withheld (bench.uncertainty)
        out["focal_err_rel"] = error_stats(ev["focal_err_rel"].to_numpy(float))
    out["calibration"] = calibration(ev)
    return out


def calibration(ev: pd.DataFrame) -> dict:
    """Fraction of windows whose true error lies in their 90 % interval, per quantity (aspect, rot,
    trans; NaN where no window has intervals), and ``n`` windows with intervals."""
    cols = [c for c in CALIBRATION_COLUMNS if c in ev]
    out: dict = {"n": int(ev[cols[0]].notna().sum()) if cols else 0}
    for c in CALIBRATION_COLUMNS:
        v = ev[c].to_numpy(float) if c in ev else np.array([])
        v = v[np.isfinite(v)]
        out[c.removesuffix("_in90")] = float(v.mean()) if v.size else float("nan")
    return out


def _with_truth(ev: pd.DataFrame, col: str) -> np.ndarray:
    """Column ``col`` of the rows whose TRUTH_FLAGS flag is set (all rows without the flag column)."""
    flag = TRUTH_FLAGS.get(col)
    rows = ev if flag is None or flag not in ev.columns else ev[ev[flag].astype(bool)]
    return rows[col].to_numpy(float)


def summarize(df: pd.DataFrame) -> dict[str, dict]:
    """{method: summarize_method(rows)} for every method of a results table, sorted by name."""
    check_table(df)
    return {m: summarize_method(g) for m, g in sorted(df.groupby("method"), key=lambda kv: kv[0])}


def _git_dirs(root: Path) -> tuple[Path, Path]:
    """(the checkout's git folder, its common folder): .git itself, or, in a worktree whose .git
    is a file ("gitdir: PATH"), that PATH and the folder its ``commondir`` names."""
    if root.is_file():
        root = Path(root.read_text().split(":", 1)[1].strip())
    common = root / "commondir"
    return root, ((root / common.read_text().strip()).resolve() if common.is_file() else root)


def _commit() -> str | None:
    """The current commit hash, read from .git files (no git process; worktrees too), or None."""
    try:
        git, common = _git_dirs(Path(__file__).resolve().parent.parent / ".git")
        head = (git / "HEAD").read_text().strip()
        if not head.startswith("ref:"):
            return head
        ref = head.split(" ", 1)[1]
        for d in (git, common):
            if (d / ref).is_file():
                return (d / ref).read_text().strip()
        packed = common / "packed-refs"
        for line in packed.read_text().splitlines() if packed.is_file() else []:
            if line.endswith(" " + ref):
                return line.split(" ", 1)[0]
    except (OSError, IndexError):
        return None
    return None


def versions() -> dict[str, str | None]:
    """Installed versions of the packages that affect results, plus Python's."""
    out: dict[str, str | None] = {"python": platform.python_version()}
    for pkg in VERSIONED_PACKAGES:
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def make_metadata(profile: dict, config_hash: str, seed: int, wall_time_s: float,
                  stage_time_s: dict[str, float], **extra) -> dict:
    """The metadata block of summary.json."""
    return {"commit": _commit(), "versions": versions(), "seed": seed,
            "profile": profile.get("name"), "config": profile, "config_hash": config_hash,
            "wall_time_s": wall_time_s, "stage_time_s": stage_time_s, **extra}


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_summary(run_dir: str | Path, metadata: dict, results: dict,
                  detection: dict | None = None, **blocks: dict) -> Path:
    """Write summary.json (NaN written as null); return its path. blocks: further top-level
    blocks (e.g. ``kfree``: bench.photo_eval)."""
    p = Path(run_dir) / SUMMARY_JSON
    doc = {"metadata": metadata, "results": results, "detection": detection or {}, **blocks}
    p.write_text(json.dumps(_jsonable(doc), indent=2))
    return p


def headline_table(results: dict) -> list[dict]:
    """One flat dict per method: the numbers the CLI prints and the report leads with."""
    rows = []
    for m, r in results.items():
        snap = r["corner_err_px_snap"]
        rows.append({
            "method": m, "n_evaluable": r["n_evaluable"], "detected": r["detection_rate"],
            "mask_med_px": r["corner_err_px_mask"]["median"],
            "head_med_px": r.get("corner_err_px_head", {}).get("median", float("nan")),
            "snap_med_px": snap["median"],
            "snap_p90_px": snap["p90"], "reproj_med_px": r["corner_err_px_reproj"]["median"],
            "recall_2px_snap": snap["recall"]["2"], "aspect_p90_rel": r["aspect_err_rel"]["p90"],
            "rot_med_deg": r["rot_err_deg"]["median"],
            "focal_med_rel": r.get("focal_err_rel", {}).get("median", float("nan")),
            "cover90_rot": r.get("calibration", {}).get("rot", float("nan")),
        })
    return rows


# ---------------------------------------------------------------- the K-free photo table (bench.photo_eval)

KFREE_PARQUET = "kfree.parquet"  # one row per photo per transform: dataset, photo, transform, focal_px, ...
AS_IS = "as_is"  # the transform name of the photo as given


def focal_spreads(df: pd.DataFrame) -> pd.DataFrame:
    """Per photo and transform: |f_t / f_as_is - 1| (rows of transforms with a focal length and an
    as-is focal length); columns dataset, photo, transform, rel."""
    base = df[df["transform"] == AS_IS].set_index(["dataset", "photo"]).focal_px
    t = df[df["transform"] != AS_IS].copy()
    t["rel"] = [abs(f / base.get((d, p), math.nan) - 1) for d, p, f in zip(t.dataset, t.photo, t.focal_px)]
    return t[["dataset", "photo", "transform", "rel"]].dropna(subset=["rel"])
