"""Report sections of the K-free single-photo path (bench.photo_eval): summary.json's "kfree" block
and the per-photo table kfree.parquet, figures beside the issue's targets.

Sections use reports.build's tuple format (("h2", text), ("p", text), ("table", header, rows)).
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from fenestra.bench.results import AS_IS, KFREE_PARQUET, focal_spreads


def target_rows(block: dict) -> list[list]:
    """One row per dataset and target it measures: dataset, figure, value, target, met."""
    return [[name, t["words"], t["value"], t["target"], "yes" if t["met"] else "NO"]
            for name, d in block["datasets"].items() for t in d["targets"]]


def dataset_rows(block: dict) -> tuple[list[str], list[list]]:
    """Per dataset: the figures without a target as well."""
    header = ["dataset", "detections", "photos", "K sources", "exported", "labelled", "exported per labelled", "walls max",
              "focal spread per transform (median)", "focal err (all photos, median)", "s per run (median)"]
    rows = [[name, ", ".join(d.get("detections") or []), d["n_photos"], ", ".join(f"{k} {v}" for k, v in d["K_sources"].items()), d["n_exported"],
             d["n_labelled"], d["windows_per_label"], d["walls_max"],
             ", ".join(f"{k} {v:.3f}" for k, v in d["focal_spread_by_transform"].items()) or "-",
             d["focal_err_median_all"], d["seconds_per_run_median"]] for name, d in block["datasets"].items()]
    return header, rows


def photo_rows(df: pd.DataFrame) -> tuple[list[str], list[list]]:
    """Per photo (as is): K source, focal length and interval, walls, windows, largest focal spread."""
    spread = focal_spreads(df).groupby(["dataset", "photo"]).rel.max()
    a = df[df["transform"] == AS_IS]
    header = ["dataset", "photo", "K source", "f px", "f interval px", "f true px", "walls", "detected",
              "exported", "exported matching a label", "labelled", "focal spread", "error"]
    rows = [[r.dataset, r.photo, r.K_source, r.focal_px, f"{r.focal_lo_px:.0f}-{r.focal_hi_px:.0f}",
             r.focal_true_px, r.n_walls, r.n_detected, r.n_exported, r.n_exported_match, r.n_labelled,
             spread.get((r.dataset, r.photo)), r.error or ""] for r in a.itertuples()]
    return header, rows


def kfree_sections(run_dir: Path, block: dict | None) -> list[tuple]:
    """The K-free sections of a real run ([] when the run has no "kfree" block)."""
    if not block:
        return []
    spec = block["spec"]
    s: list[tuple] = [
        ("h2", "K-free path: `fenestra reconstruct PHOTO` without intrinsics"),
        ("p", f"Each photo of {', '.join(spec['datasets'])} through pipeline.photo.reconstruct_photo with no K "
              f"(detector {spec['detector']}; {block['n_runs']} runs in {block['wall_time_s']:.0f} s), as is and, "
              f"for {', '.join(spec['transform_datasets']) or 'no dataset'}, under {', '.join(spec['transforms'])}. "
              f"An exported window matches a label when its snapped quad's box has IoU >= {spec['match_iou']:g} with "
              "a labelled window box; focal spread per photo: the largest |f_t / f_as_is - 1| over the transforms; "
              "focal error: |f / f_calibrated - 1| where the focal length was observed (not the stated prior). The stated prior is a field of view of the frame, so a 10 % crop moves a prior focal length by 10 % by construction (without EXIF a crop cannot be told from a wider lens)."),
        ("table", ["dataset", "figure", "value", "target", "met"], target_rows(block)),
        ("table", *dataset_rows(block)),
    ]
    p = Path(run_dir) / KFREE_PARQUET
    if p.is_file():
        s += [("h3", "Per photo (as is)"), ("table", *photo_rows(pd.read_parquet(p)))]
    return s
