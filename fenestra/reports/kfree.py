"""Report sections of the K-free single-photo path (bench.photo_eval): summary.json's "kfree" block
and the per-photo table kfree.parquet, figures beside the issue's targets.

Sections use reports.build's tuple format (("h2", text), ("p", text), ("table", header, rows)).
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from fenestra.bench.results import AS_IS, KFREE_PARQUET, KNOWN_STOREY, focal_spreads
from fenestra.pipeline.facade_model import MAX_WINDOW_M


def target_rows(block: dict) -> list[list]:
    """One row per dataset and target it measures: dataset, figure, value, target, met."""
    return [[name, t["words"], t["value"], t["target"], "yes" if t["met"] else "NO"]
            for name, d in block["datasets"].items() for t in d["targets"]]


def counts(d: dict) -> dict[str, str]:
    """The counts behind a dataset's figures, as text (also markdown's K-free table): exported
    (partial) / labelled windows and labelled ones matched, photos with transforms, walls measured
    for tilt (largest tilt), the known-storey runs; "-" for a figure the run lacks (an older summary)."""
    g = d.get

    def have(*keys):
        return all(g(k) is not None for k in keys)

    return {
        "exported (partial) / labelled, labelled matched":
            f"{g('n_exported')} ({g('n_exported_partial') if have('n_exported_partial') else '-'}) / "
            f"{g('n_labelled')}, {g('n_labels_matched') if have('n_labels_matched') else '-'}",
        "photos under transforms": str(g("walls_stable_n_photos")) if have("walls_stable_n_photos") else "-",
        "walls with a tilt (largest, deg)": (f"{g('wall_tilt_n_walls')} ("
                                             + ("-" if g("wall_tilt_max_deg") is None else f"{g('wall_tilt_max_deg'):.2f}")
                                             + ")") if have("wall_tilt_n_walls") else "-",
        "observed f: 90 % interval holds the calibration": (
            f"{g('focal_interval_n')} photos, {100 * g('focal_interval_coverage'):.0f} %"
            if have("focal_interval_n", "focal_interval_coverage") else "-"),
        "known storey: photos, exported, rows of >= 2": (
            f"{g('known_storey_m'):g} m: {g('known_storey_n_photos')}, {g('known_storey_n_exported')}, "
            f"{g('known_storey_n_rows')}" if g("known_storey_n_photos") else "-"),
    }


def dataset_rows(block: dict) -> tuple[list[str], list[list]]:
    """Per dataset: the figures without a target as well."""
    first = next(iter(block["datasets"].values()), {})
    header = ["dataset", "detections", "photos", "K sources", "exported", "labelled", "exported per labelled", "walls max",
              *counts(first), "focal spread per transform (median)", "focal err (all photos, median)", "s per run (median)"]
    rows = [[name, ", ".join(d.get("detections") or []), d["n_photos"], ", ".join(f"{k} {v}" for k, v in d["K_sources"].items()), d["n_exported"],
             d["n_labelled"], d["windows_per_label"], d["walls_max"], *counts(d).values(),
             ", ".join(f"{k} {v:.3f}" for k, v in d["focal_spread_by_transform"].items()) or "-",
             d["focal_err_median_all"], d["seconds_per_run_median"]] for name, d in block["datasets"].items()]
    return header, rows


def _walls_under_transforms(df: pd.DataFrame) -> dict[tuple, str]:
    """{(dataset, photo): "gray 1, jpeg 2, ..."}: the wall count of each transform run."""
    t = df[~df["transform"].isin((AS_IS, KNOWN_STOREY))]
    return {k: ", ".join(f"{r.transform} {'-' if r.n_walls != r.n_walls else int(r.n_walls)}" for r in g.itertuples())
            for k, g in t.groupby(["dataset", "photo"])}


def _largest(v) -> float | None:
    return None if v is None or (isinstance(v, float) and v != v) or len(v) == 0 else float(max(v))


def photo_rows(df: pd.DataFrame) -> tuple[list[str], list[list]]:
    """Per photo (as is): K source, focal length and interval, walls, windows, largest focal spread."""
    spread = focal_spreads(df).groupby(["dataset", "photo"]).rel.max()
    a = df[df["transform"] == AS_IS]
    walls_t = _walls_under_transforms(df)
    new = {c: c in df for c in ("n_labels_matched", "n_exported_oversized", "wall_tilts_deg")}  # older tables lack them
    header = ["dataset", "photo", "K source", "f px", "f interval px", "f true px", "walls", "walls under transforms",
              "detected", "exported", "exported matching a label", "labelled", "labelled matched",
              f"exported over {MAX_WINDOW_M:g} m", "wall tilt max deg", "focal spread", "error"]
    rows = [[r.dataset, r.photo, r.K_source, r.focal_px, f"{r.focal_lo_px:.0f}-{r.focal_hi_px:.0f}",
             r.focal_true_px, r.n_walls, walls_t.get((r.dataset, r.photo), "-"), r.n_detected, r.n_exported,
             r.n_exported_match, r.n_labelled, r.n_labels_matched if new["n_labels_matched"] else None,
             r.n_exported_oversized if new["n_exported_oversized"] else None,
             _largest(r.wall_tilts_deg) if new["wall_tilts_deg"] else None,
             spread.get((r.dataset, r.photo)), r.error or ""] for r in a.itertuples()]
    return header, rows


# what the K-free figures measure (also markdown's K-free paragraph)
KFREE_NOTES = ("Export recall: labelled windows whose box matches an exported window's (partial windows, cut by the "
               "photo's border, included). Over {m:g} m: exported windows wider or taller than {m:g} m "
               "(facade_model.MAX_WINDOW_M) on the runs without --known-*. Wall count under the transforms: a photo "
               "counts when every transform gives the as-is count. Wall tilt: per wall of the model, the angle "
               "between its plane and the exported model's vertical, which is the walls' own agreeing up axes "
               "(their vertical vanishing directions; it also sets the upright rotation): a consistency figure, "
               "not an independent truth (a wall whose windows share one rotation scores 0 by construction when it is "
               "alone in its photo). Known storey: exported "
               "windows taller than it, and per row of windows (export.json storeys) the height spread "
               "(max - min) / median of its whole exported windows, over rows of at least two.").format(m=MAX_WINDOW_M)


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
              "focal error: |f / f_calibrated - 1| where the focal length was observed (not the stated prior). The stated prior is a field of view of the frame, so a 10 % crop moves a prior focal length by 10 % by construction (without EXIF a crop cannot be told from a wider lens). "
              + KFREE_NOTES + (f" Run with the known storey: {', '.join(spec['known_storey_datasets'])} as is with --known-storey "
                               f"{spec['known_storey_m']:g} m." if spec.get("known_storey_datasets") else "")),
        ("table", ["dataset", "figure", "value", "target", "met"], target_rows(block)),
        ("table", *dataset_rows(block)),
    ]
    p = Path(run_dir) / KFREE_PARQUET
    if p.is_file():
        s += [("h3", "Per photo (as is)"), ("table", *photo_rows(pd.read_parquet(p)))]
    return s
