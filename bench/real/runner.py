"""The real-photo benchmark end to end: adapters -> evaluate every view -> tables, summary, report.

    from bench.real.profile import load_real_profile
    from bench.real.runner import run_real
    info = run_real(load_real_profile("real"), sim_dir="out/bench/smoke")

Writes the same run folder as the synthetic runner (results.parquet/.csv, summary.json with
metadata, per-method results and per-detector detection AP, and the report when a report writer
is passed, as in bench.runner), plus
``simreal.json`` when a synthetic run folder is given (bench.real.simreal). Optional datasets
whose folder is absent are skipped and listed in the metadata.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from bench import manifest
from bench import results as res
from bench.evaluate import ViewOutcome
from bench.real.adapters import ADAPTERS
from bench.real.evaluate import RealEvalSpec, evaluate_real_view
from bench.real.profile import RealProfile
from bench.runner import OUT_ROOT, ReportWriter, RunInfo, _sum_stages, plan_methods
from fenestra import data
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


@dataclass(frozen=True)
class LabelledOutcome:
    """A view's ViewOutcome with its dataset, COCO image key ("dataset/name") and size (H, W)."""

    dataset: str
    key: str
    size: tuple[int, int]
    outcome: ViewOutcome
    window_ids: tuple[str, ...] = ()  # the labelled windows (the run manifest's expected rows)


def coco_ap_of(done: list[LabelledOutcome], det: str) -> dict:
    """COCO bbox and segm scores (fenestra.data.coco_scores: fractions, NaN = absent, e.g. segm
    where a window has no mask) of one detector over the views it ran on, plus counts."""
    ran = [d for d in done if det in d.outcome.coco_dt]
    gt = [g for d in ran for g in d.outcome.coco_gt]
    dt = [x for d in ran for x in d.outcome.coco_dt[det]]
    stats = data.coco_scores(data.coco_ground_truth([(d.key, *d.size) for d in ran], gt), dt)
    return {**stats, "n_detections": len(dt), "n_gt": sum(not g["iscrowd"] for g in gt),
            "false_positives": sum(d.outcome.n_false_positives.get(det, 0) for d in ran)}


def detection_ap(done: list[LabelledOutcome]) -> dict[str, dict]:
    """{detector: COCO stats over every dataset} plus {"detector @ dataset": ...} per dataset
    when there are several (the report's detection table; see coco_ap_of)."""
    dets = list(dict.fromkeys(k for d in done for k in d.outcome.coco_dt))
    out = {det: coco_ap_of(done, det) for det in dets}
    names = list(dict.fromkeys(d.dataset for d in done))
    if len(names) > 1:
        for det in dets:
            for n in names:
                sub = [d for d in done if d.dataset == n]
                if any(det in d.outcome.coco_dt for d in sub):
                    out[f"{det} @ {n}"] = coco_ap_of(sub, det)
    return out


def evaluate_datasets(profile: RealProfile, datasets: list, methods, progress: bool = True) -> list[LabelledOutcome]:
    """evaluate_real_view over every view of every dataset, in order (one process: the real
    datasets are a few photos; the learned detector uses one thread)."""
    spec = RealEvalSpec(min_window_px=profile.min_window_px, height_m=profile.methods.height_m,
                        detector_long_side=profile.detector_long_side,
                        detector_options=profile.detector_options)
    outcomes = []
    for ds in datasets:
        for view in ADAPTERS[ds.format](ds.folder(), **{"dataset": ds.name, **dict(ds.options)}):
            outcomes.append(LabelledOutcome(ds.name, f"{ds.name}/{view.name}", view.image.shape[:2],
                                            evaluate_real_view(view, methods, spec),
                                            tuple(str(w.id) for w in view.windows)))
            if progress:
                print(f"  {ds.name}/{view.name}: {len(view.windows)} windows", flush=True)
    return outcomes


def run_real(profile: RealProfile, out_dir: str | Path | None = None, sim_dir: str | Path | None = None,
             progress: bool = True, report: ReportWriter | None = None, force: bool = False) -> RunInfo:
    """Run a real profile; see the module docstring. Returns the synthetic runner's RunInfo.

    report: called with the run folder after simreal.json is written (None or False: no report);
    force: replace a run folder holding another profile's run or foreign files
    (bench.manifest.claim_run_dir); the run's manifest lists every labelled window x method."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    t_start = time.perf_counter()
    run_dir = manifest.claim_run_dir(Path(out_dir) if out_dir else default_real_run_dir(profile),
                                     profile.name, profile.config_hash(), force)
    methods, skipped = plan_methods(profile)
    datasets, skipped_ds = available_datasets(profile)
    done = evaluate_datasets(profile, datasets, methods, progress)
    outcomes = [d.outcome for d in done]
    rows = [r for o in outcomes for r in o.rows]
    if not rows:
        raise FenestraError(f"profile {profile.name!r}: no labelled window in {[d.name for d in datasets]}")
    df = pd.DataFrame(rows)
    df.insert(0, "profile", profile.name)
    res.write_results(df, run_dir)
    expected = [(d.dataset, d.key[len(d.dataset) + 1:], w, m.name) for d in done for w in d.window_ids for m in methods]
    manifest.write_manifest(run_dir, expected, profile.name, profile.config_hash())
    stage_s = {f"cpu.{k}": v for k, v in _sum_stages(outcomes).items()}
    det = detection_ap(done)
    meta = res.make_metadata(profile.to_dict(), profile.config_hash(), profile.seed,
                             time.perf_counter() - t_start, stage_s, kind="real", n_views=len(outcomes),
                             n_rows=len(df), methods=[m.name for m in methods], skipped_detectors=skipped,
                             skipped_datasets=skipped_ds,
                             datasets={d.name: str(d.folder()) for d in datasets},
                             n_windows={d.name: sum(len(x.outcome.coco_gt) for x in done if x.dataset == d.name)
                                        for d in datasets})
    summary = res.summarize(df)
    res.write_summary(run_dir, meta, summary, det)
    if sim_dir is not None:
        from bench.real.simreal import write_simreal  # noqa: PLC0415

        write_simreal(Path(sim_dir), run_dir)
    if report:
        report(run_dir)
    meta["wall_time_s"] = time.perf_counter() - t_start
    res.write_summary(run_dir, meta, summary, det)
    return RunInfo(run_dir, meta["wall_time_s"], stage_s, skipped, len(outcomes), len(df))


def run_real_profile(profile: str | Path, out_dir: Path | None = None, data: Path | None = None,
                     fmt: str = "coco", sim_dir: Path | None = None, report: ReportWriter | None = None,
                     force: bool = False) -> RunInfo:
    """``fenestra bench --profile real [--data DIR --format F] [--sim RUN_DIR]``: load the profile,
    swap in the user's dataset if given, run. FileNotFoundError naming a missing --sim folder."""
    from bench.real.profile import load_real_profile, with_user_data  # noqa: PLC0415

    p = load_real_profile(profile)
    if data is not None:
        p = with_user_data(p, data, fmt)
    if sim_dir is not None and not (Path(sim_dir) / res.SUMMARY_JSON).is_file():
        raise FileNotFoundError(f"--sim {sim_dir}: not a benchmark run folder (no {res.SUMMARY_JSON})")
    return run_real(p, out_dir, sim_dir, report=report, force=force)
