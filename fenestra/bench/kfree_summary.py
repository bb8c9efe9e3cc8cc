"""The K-free block's summary: summary.json's "kfree" block from kfree.parquet's rows (bench.photo_eval),
per dataset its figures (see bench.photo_eval's docstring) beside the issue's targets
(bench.results.KFREE_TARGETS), and the block as text lines.

    block = summarize_kfree(df, spec, wall_s)      # -> summary.json "kfree"
    print("\n".join(format_kfree(block)))
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from fenestra.bench.results import AS_IS, KFREE_TARGETS, KNOWN_STOREY, focal_spreads

if TYPE_CHECKING:
    from fenestra.bench.photo_eval import KfreeSpec

UNOBSERVED_SOURCES = ("prior",)  # focal sources that observe nothing of the photo


def _med(x) -> float | None:
    x = pd.Series(x, dtype=float).dropna()
    return float(x.median()) if len(x) else None


def pooled(lists: Iterable) -> list[float]:
    """The values of per-row lists (kfree.parquet's list columns) in one list; None / NaN rows skip."""
    return [float(x) for v in lists if v is not None and not (isinstance(v, float) and math.isnan(v)) for x in v]


def walls_stable_share(df: pd.DataFrame) -> tuple[float | None, int]:
    """(share of photos whose wall count is the same under every transform as as is, photos with a
    transform run): per photo (dataset, photo) with at least one row of an image transform (not
    AS_IS, not KNOWN_STOREY), stable when every such row's ``n_walls`` equals the as-is row's; a
    run without a document (NaN walls) is not the same count. (None, 0) without such photos."""
    t = df[~df["transform"].isin((AS_IS, KNOWN_STOREY))]
    base = df[df["transform"] == AS_IS].set_index(["dataset", "photo"]).n_walls
    stable = [bool(len(g) and g.n_walls.eq(base.get(k, math.nan)).all()) for k, g in t.groupby(["dataset", "photo"])]
    return (float(np.mean(stable)) if stable else None), len(stable)


def _column(df: pd.DataFrame, name: str) -> pd.Series:
    """df[name], or an empty float column when kfree.parquet predates it."""
    return df[name] if name in df else pd.Series(math.nan, index=df.index, dtype=float)


def interval_coverage(rows: pd.DataFrame) -> dict:
    """{"focal_interval_coverage": share of ``rows`` with a calibrated focal length whose 90 %
    interval [focal_lo_px, focal_hi_px] holds it (None without such a row), "focal_interval_n":
    how many}: the issue's calibration check of the intervals on photos of known K."""
    r = rows[rows.focal_true_px.notna() & rows.focal_lo_px.notna()]
    inside = (r.focal_lo_px <= r.focal_true_px) & (r.focal_true_px <= r.focal_hi_px)
    return {"focal_interval_coverage": float(inside.mean()) if len(r) else None, "focal_interval_n": int(len(r))}


def dataset_summary(df: pd.DataFrame) -> dict:
    """The figures of one dataset's rows (see the module docstring); None where its labels or runs
    do not allow a figure."""
    a = df[df["transform"] == AS_IS]
    ks = df[df["transform"] == KNOWN_STOREY]
    n_exp, n_match = a.n_exported.sum(), a.n_exported_match.sum()
    n_lab, n_lab_match = a.n_labelled.sum(), _column(a, "n_labels_matched").sum()
    spread = focal_spreads(df)
    per_photo = spread.groupby("photo").rel.max()
    observed = a[~a.K_source.isin(UNOBSERVED_SOURCES)]
    stable, n_stable = walls_stable_share(df)
    tilts = pooled(_column(a, "wall_tilts_deg"))
    rows = pooled(_column(ks, "row_spreads"))
    exported_runs = a[a.n_exported.notna()]
    return {
        "n_photos": int(len(a)), "output_share": float(a.output.mean()) if len(a) else None,
        "errors": {p: e for p, e in zip(a.photo, a.error) if e},
        "export_precision": float(n_match / n_exp) if n_exp else None,
        "export_recall": float(n_lab_match / n_lab) if n_lab and len(exported_runs) else None,
        "n_labels_matched": int(n_lab_match),
        "n_exported": int(n_exp), "n_labelled": int(n_lab),
        "n_exported_partial": int(_column(a, "n_exported_partial").sum()),
        "n_exported_oversized": int(_column(a, "n_exported_oversized").sum()) if len(exported_runs) else None,
        "windows_per_label": float(n_exp / n_lab) if n_lab else None,
        "walls_median": _med(a.n_walls), "walls_max": None if a.n_walls.dropna().empty else int(a.n_walls.max()),
        "walls_stable_share": stable, "walls_stable_n_photos": n_stable,
        "wall_tilt_median_deg": _med(tilts), "wall_tilt_max_deg": max(tilts) if tilts else None,
        "wall_tilt_n_walls": len(tilts),
        "known_storey_m": float(ks.known_storey_m.iloc[0]) if len(ks) else None,
        "known_storey_n_photos": int(len(ks)),
        "known_storey_taller": int(ks.n_taller_than_storey.sum()) if ks.n_taller_than_storey.notna().any() else None,
        "known_storey_n_exported": int(ks.n_exported.sum()) if len(ks) else None,
        "known_storey_row_spread_median": _med(rows), "known_storey_n_rows": len(rows),
        "K_sources": {str(k): int(v) for k, v in a.K_source.value_counts().sort_index().items()},
        "focal_spread_median": _med(per_photo) if len(per_photo) else None,
        "focal_spread_observed_median": _med(per_photo[per_photo.index.isin(observed.photo)]) if len(per_photo) else None,
        "focal_spread_n_observed": int(per_photo.index.isin(observed.photo).sum()),
        "focal_spread_by_transform": {t: _med(g.rel) for t, g in spread.groupby("transform")},
        "focal_err_median": _med(observed.focal_err_rel) if a.focal_true_px.notna().any() else None,
        "focal_err_n_observed": int(observed.focal_err_rel.notna().sum()),
        "focal_err_median_all": _med(a.focal_err_rel),
        **interval_coverage(observed),
        "seconds_per_run_median": _med(df.seconds), "seconds_total": float(df.seconds.sum()),
        "detections": sorted(set(df["detections"])) if "detections" in df else [],
    }


def check_targets(figures: dict) -> list[dict]:
    """The targets this dataset's figures measure: key, words, target, value, met."""
    out = []
    for key, op, target, words in KFREE_TARGETS:
        v = figures.get(key)
        if v is not None:
            out.append({"key": key, "words": words, "target": f"{op} {target:g}", "value": v,
                        "met": bool(v >= target if op == ">=" else v <= target)})
    return out


def summarize_kfree(df: pd.DataFrame, spec: KfreeSpec, wall_s: float) -> dict:
    """summary.json's "kfree" block: the spec, and per dataset its figures and targets."""
    per = {}
    for name, g in (df.groupby("dataset", sort=False) if len(df) else ()):
        fig = dataset_summary(g)
        per[str(name)] = {**fig, "targets": check_targets(fig)}
    return {"spec": {"datasets": list(spec.datasets), "transforms": list(spec.transforms),
                     "transform_datasets": list(spec.transform_datasets),
                     "mask_datasets": list(spec.mask_datasets), "max_photos": spec.max_photos,
                     "match_iou": spec.match_iou, "detector": spec.detector or "default",
                     "known_storey_datasets": list(spec.known_storey_datasets), "known_storey_m": spec.known_storey_m},
            "wall_time_s": wall_s, "n_runs": int(len(df)), "datasets": per}


def format_kfree(block: dict) -> list[str]:
    """The block as text lines (figure beside target), for the CLI and the logs."""
    lines = [f"K-free path (no intrinsics; {block['n_runs']} runs in {block['wall_time_s']:.0f} s; "
             f"export match: box IoU >= {block['spec']['match_iou']:g})"]
    for name, d in block["datasets"].items():
        lines.append(f"  {name} ({', '.join(d.get('detections') or [])}): {d['n_photos']} photos, K sources {d['K_sources']}, "
                     f"windows per labelled window {_fmt(d['windows_per_label'])}, "
                     f"{d['n_exported']} exported ({d['n_exported_partial']} partial) / {d['n_labelled']} labelled, "
                     f"{d['n_labels_matched']} labelled matched; wall tilt over {d['wall_tilt_n_walls']} walls"
                     + (f", known storey {d['known_storey_m']:g} m on {d['known_storey_n_photos']} photos "
                        f"({d['known_storey_n_rows']} rows of >= 2 whole windows)" if d["known_storey_n_photos"] else ""))
        for t in d["targets"]:
            lines.append(f"    {t['words']}: {_fmt(t['value'])} (target {t['target']}) "
                         f"{'met' if t['met'] else 'NOT met'}")
        if d["focal_spread_by_transform"]:
            lines.append("    focal spread per transform (median): " + ", ".join(
                f"{k} {_fmt(v)}" for k, v in d["focal_spread_by_transform"].items()))
    return lines


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.3g}"
