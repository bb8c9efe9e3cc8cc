"""The real-photo benchmark end to end: adapters -> evaluate every view -> tables, summary, report.

    from bench.real.profile import load_real_profile
    from bench.real.runner import run_real
    info = run_real(load_real_profile("real"), sim_dir="out/bench/smoke")

Writes the same run folder as the synthetic runner (results.parquet/.csv, summary.json with
metadata, per-method results and per-detector detection AP, report.html/.md), plus
``simreal.json`` when a synthetic run folder is given (bench.real.simreal). Optional datasets
whose folder is absent are skipped and listed in the metadata.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from bench import results as res
from bench.evaluate import ViewOutcome
from bench.real.adapters import ADAPTERS
from bench.real.evaluate import RealEvalSpec, evaluate_real_view
from bench.real.profile import RealProfile
from bench.runner import OUT_ROOT, RunInfo, _sum_stages, plan_methods
from fenestra.errors import FenestraError


def default_real_run_dir(profile: RealProfile) -> Path:
    """out/bench/<profile name>-<config hash>."""
    return OUT_ROOT / "bench" / f"{profile.name}-{profile.config_hash()}"


def available_datasets(profile: RealProfile) -> tuple[list, dict[str, str]]:
    """(datasets whose folder exists, {skipped optional dataset: reason}); FileNotFoundError
    naming a required dataset's missing folder."""
    ok, skipped = [], {}
    for ds in profile.datasets:
        if ds.folder().is_dir():
            ok.append(ds)
        elif ds.optional:
            skipped[ds.name] = f"folder {ds.folder()} not present"
        else:
            raise FileNotFoundError(f"dataset {ds.name!r}: folder {ds.folder()} not found")
    return ok, skipped


def detection_ap(outcomes: list[ViewOutcome]) -> dict[str, dict]:
    """Per detector, COCO bbox (and segm where every window has a mask) AP/AP50/AP75 and recall
    at IoU 0.5 (R50) as fractions, over the views it ran on (pipeline.detectors.evaluate)."""
    from pipeline.detectors.evaluate import coco_stats  # noqa: PLC0415

    out = {}
    for det in dict.fromkeys(d for o in outcomes for d in o.coco_dt):
        ran = [o for o in outcomes if det in o.coco_dt]
        gt = coco_dict([g for o in ran for g in o.coco_gt])
        vid = {im["file_name"]: im["id"] for im in gt["images"]}
        dt = [{"image_id": vid[d["view"]], "category_id": 1, "score": d["score"], "bbox": d["bbox"],
               "segmentation": d["rle"]} for o in ran for d in o.coco_dt[det]]
        types = ("bbox", "segm") if all(g["rle"] is not None for o in ran for g in o.coco_gt) else ("bbox",)
        stats = {f"{t}_{k}": v / 100.0 for t in types for k, v in coco_stats(gt, dt, t).items()}
        stats.update({f"segm_{k}": float("nan") for k in ("AP", "AP50", "AP75", "R50") if "segm" not in types})
        out[det] = {**stats, "n_detections": len(dt), "n_gt": len(gt["annotations"]),
                    "false_positives": sum(o.n_false_positives.get(det, 0) for o in ran)}
    return out


def coco_dict(gt: list[dict]) -> dict:
    """A COCO ground-truth dict from bench.real.evaluate.gt_coco entries (images named by view)."""
    views = sorted({g["view"] for g in gt})
    vid = {v: i + 1 for i, v in enumerate(views)}
    size = {g["view"]: g["size"] for g in gt}
    anns = [{"id": i + 1, "image_id": vid[g["view"]], "category_id": 1, "iscrowd": 0, "bbox": g["bbox"],
             "area": g["area"], **({"segmentation": g["rle"]} if g["rle"] is not None else {})}
            for i, g in enumerate(gt)]
    return {"images": [{"id": vid[v], "file_name": v, "height": size[v][0], "width": size[v][1]} for v in views],
            "annotations": anns, "categories": [{"id": 1, "name": "window"}]}


def summarize_real(df: pd.DataFrame) -> dict:
    """bench.results.summarize plus, per method, the real bench's own error columns."""
    from bench.real.evaluate import REAL_COLUMNS  # noqa: PLC0415
    from bench.metrics import error_stats  # noqa: PLC0415

    out = res.summarize(df)
    for m, g in df.groupby("method"):
        ev = g[g["evaluable"].astype(bool)]
        for col in REAL_COLUMNS:
            out[m][col] = error_stats(ev[col].to_numpy(float))
    return out


def evaluate_datasets(profile: RealProfile, datasets: list, methods, progress: bool = True) -> list[ViewOutcome]:
    """evaluate_real_view over every view of every dataset, in order (one process: the real
    datasets are a few photos; the learned detector uses one thread)."""
    spec = RealEvalSpec(min_window_px=profile.min_window_px, height_m=profile.methods.height_m,
                        detector_long_side=profile.detector_long_side)
    outcomes = []
    for ds in datasets:
        for view in ADAPTERS[ds.format](ds.folder(), **{"dataset": ds.name, **dict(ds.options)}):
            outcomes.append(evaluate_real_view(view, methods, spec))
            if progress:
                print(f"  {ds.name}/{view.name}: {len(view.windows)} windows", flush=True)
    return outcomes


def run_real(profile: RealProfile, out_dir: str | Path | None = None, sim_dir: str | Path | None = None,
             progress: bool = True, report: bool = True) -> RunInfo:
    """Run a real profile; see the module docstring. Returns the synthetic runner's RunInfo."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    t_start = time.perf_counter()
    run_dir = Path(out_dir) if out_dir else default_real_run_dir(profile)
    run_dir.mkdir(parents=True, exist_ok=True)
    methods, skipped = plan_methods(profile)
    datasets, skipped_ds = available_datasets(profile)
    outcomes = evaluate_datasets(profile, datasets, methods, progress)
    rows = [r for o in outcomes for r in o.rows]
    if not rows:
        raise FenestraError(f"profile {profile.name!r}: no labelled window in {[d.name for d in datasets]}")
    df = pd.DataFrame(rows)
    df.insert(0, "profile", profile.name)
    res.write_results(df, run_dir)
    stage_s = {f"cpu.{k}": v for k, v in _sum_stages(outcomes).items()}
    det = detection_ap(outcomes)
    meta = res.make_metadata(profile.to_dict(), profile.config_hash(), profile.seed,
                             time.perf_counter() - t_start, stage_s, kind="real", n_views=len(outcomes),
                             n_rows=len(df), methods=[m.name for m in methods], skipped_detectors=skipped,
                             skipped_datasets=skipped_ds,
                             datasets={d.name: str(d.folder()) for d in datasets},
                             n_windows={d.name: int(np.sum([len(o.coco_gt) for o in outcomes
                                                            if o.coco_gt and o.coco_gt[0]["view"].startswith(d.name + "/")]))
                                        for d in datasets})
    summary = summarize_real(df)
    res.write_summary(run_dir, meta, summary, det)
    if sim_dir is not None:
        from bench.real.simreal import write_simreal  # noqa: PLC0415

        write_simreal(Path(sim_dir), run_dir)
    if report:
        from reports.build import build_report  # noqa: PLC0415

        build_report(run_dir)
    meta["wall_time_s"] = time.perf_counter() - t_start
    res.write_summary(run_dir, meta, summary, det)
    return RunInfo(run_dir, meta["wall_time_s"], stage_s, skipped, len(outcomes), len(df))
