"""The benchmark end to end: render (cached) -> detect -> match -> reconstruct -> measure -> tables.

    from bench.runner import run_benchmark
    run_dir = run_benchmark(load_profile("smoke"), workers=2)

Views are rendered and evaluated by an executor (bench.executors: a local process pool of
``workers`` processes, or a Ray cluster), with a rich progress bar. Every ground-truth
window gets one row per method combination (see bench.evaluate). The run folder (default
``out/bench/<profile>-<config hash>``) receives results.parquet/.csv, summary.json and, when a
report writer is passed, the report; renders go to ``out/renders`` (renders.dataset names and
reuses them by config hash). bench/ never imports reports/ (reports read bench's tables): the CLI
(app/cli.py) passes the report writer in.
"""
from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from bench import manifest
from bench import results as res
from bench.evaluate import Method, ViewOutcome
from bench.executors import HousePlan, Plan, get_executor
from bench.profiles import ALL, Profile, pose_strategies
from fenestra.errors import FenestraError

OUT_ROOT = Path("out")
LEARNED_DETECTOR_OPTIONS = {"threads": 1}  # one torch thread per worker process
ReportWriter = Callable[[Path], object]  # run folder -> writes its report (reports.build, via the CLI)


@dataclass(frozen=True)
class RunInfo:
    """What run_benchmark did: the folder, wall time, per-stage seconds, skipped detectors."""

    run_dir: Path
    wall_time_s: float
    stage_time_s: dict
    skipped_detectors: dict
    n_views: int
    n_rows: int


def default_run_dir(profile: Profile) -> Path:
    """out/bench/<profile name>-<config hash>."""
    return OUT_ROOT / "bench" / f"{profile.name}-{profile.config_hash()}"


# ---------------------------------------------------------------- methods

def _expand(names: tuple[str, ...], registry: dict, what: str) -> list[str]:
    """["all"] -> every registered name (but entries with ``in_all`` False); otherwise check each
    name exists."""
    if names == (ALL,):
        return [n for n, e in registry.items() if getattr(e, "in_all", True)]
    bad = [n for n in names if n not in registry]
    if bad:
        raise FenestraError(f"unknown {what} {bad}; registered: {sorted(registry)}")
    return list(names)


def available_detectors(names: list[str]) -> tuple[list[str], dict[str, str]]:
    """Detectors that can be built here (learned ones need weights); {skipped: reason}."""
    from pipeline.detectors import DETECTORS, get_detector  # noqa: PLC0415

    ok, skipped = [], {}
    for n in names:
        try:
            if not DETECTORS[n].needs_instances:  # the oracles load no weights
                get_detector(n, **LEARNED_DETECTOR_OPTIONS)
            ok.append(n)
        except Exception as e:  # noqa: BLE001 - missing weights etc.: skip, recorded in metadata
            skipped[n] = f"{type(e).__name__}: {e}"
    return ok, skipped


def plan_methods(profile: Profile) -> tuple[tuple[Method, ...], dict[str, str]]:
    """Every available detector x snapper x pose solver of the profile, and skipped detectors."""
    from pipeline.detectors import DETECTORS  # noqa: PLC0415
    from pipeline.snappers import SNAPPERS  # noqa: PLC0415

    requested = _expand(profile.methods.detectors, DETECTORS, "detector(s)")
    dets, skipped = available_detectors(requested)
    if not dets:
        raise FenestraError(f"no detector of {requested} is available: {skipped}")
    snaps = _expand(profile.methods.snappers, SNAPPERS, "snapper(s)")
    poses = _expand(profile.methods.pose_solvers, pose_strategies(), "pose solver(s)")
    return tuple(Method(d, s, p) for d, s, p in itertools.product(dets, snaps, poses)), skipped


# ---------------------------------------------------------------- renders

def house_list(profile: Profile) -> list[str]:
    """Bundled house names of the profile (["all"] expanded), then procedural ones."""
    from scenes.registry import BUNDLED  # noqa: PLC0415

    houses = list(BUNDLED) if profile.scenes.houses == (ALL,) else list(profile.scenes.houses)
    bad = [h for h in houses if h not in BUNDLED and not Path(h).is_file()]
    if bad:
        raise FenestraError(f"unknown house(s) {bad}; bundled: {sorted(BUNDLED)}")
    seed = profile.scenes.procedural_seed
    return houses + [f"procedural:{seed + i}" for i in range(profile.scenes.procedural)]


# ---------------------------------------------------------------- evaluation

def make_plan(profile: Profile, methods: tuple[Method, ...], renders_dir: str | Path | None,
              run_dir: Path) -> Plan:
    """The executor's plan: each house's dataset config (procedural IFCs generated here), methods."""
    from bench.render_adapter import dataset_config  # noqa: PLC0415
    from pipeline.detectors import DETECTORS  # noqa: PLC0415

    root = Path(renders_dir) if renders_dir is not None else OUT_ROOT / "renders"
    opts = tuple((d, tuple(LEARNED_DETECTOR_OPTIONS.items()))
                 for d in dict.fromkeys(m.detector for m in methods)
                 if not DETECTORS[d].needs_instances)
    houses = tuple(HousePlan(h, dataset_config(profile, h, root)) for h in house_list(profile))
    return Plan(houses=houses, profile=profile, methods=methods, detector_options=opts, run_dir=str(run_dir))


def _sum_stages(outcomes: list[ViewOutcome]) -> dict[str, float]:
    total: dict[str, float] = {}
    for o in outcomes:
        for k, v in o.stage_s.items():
            total[k] = total.get(k, 0.0) + v
    return dict(sorted(total.items()))


def per_unit_timings(stage_s: dict[str, float], n_views: int, n_windows: int) -> dict[str, dict]:
    """Per-view and per-window milliseconds of every CPU stage (``cpu.*``): regressions show there.

    n_windows: ground-truth windows (one row each per method). Returns {"stage_ms_per_view": {...},
    "stage_ms_per_window": {...}}.
    """
    cpu = {k[4:]: v for k, v in stage_s.items() if k.startswith("cpu.")}
    return {"stage_ms_per_view": {k: 1000.0 * v / max(1, n_views) for k, v in cpu.items()},
            "stage_ms_per_window": {k: 1000.0 * v / max(1, n_windows) for k, v in cpu.items()}}


def detection_ap(outcomes: list[ViewOutcome], fp_counts: bool = True) -> dict[str, dict]:
    """COCO AP per detector over all views (bench.detection_ap), plus false positives."""
    from bench.detection_ap import coco_ap  # noqa: PLC0415

    gt = [g for o in outcomes for g in o.coco_gt]
    out = {}
    for det in dict.fromkeys(d for o in outcomes for d in o.coco_dt):
        dt = [d for o in outcomes for d in o.coco_dt.get(det, [])]
        out[det] = coco_ap(gt, dt)
        if fp_counts:
            out[det]["false_positives"] = sum(o.n_false_positives.get(det, 0) for o in outcomes)
            out[det]["n_detections"] = len(dt)
            out[det]["n_gt"] = sum(not g["iscrowd"] for g in gt)  # windows, not ignore regions
    return out


def run_benchmark(profile: Profile, out_dir: str | Path | None = None, workers: int | None = None,
                  progress: bool = True, report: ReportWriter | None = None,
                  methods: tuple[Method, ...] | None = None,
                  renders_dir: str | Path | None = None, executor: str = "local",
                  executor_options: dict | None = None, force: bool = False) -> RunInfo:
    """Run a profile end to end; see the module docstring. Returns a RunInfo.

    methods: override the profile's method combinations (e.g. a test's extra snapper);
    renders_dir: where cached renders live (default out/renders);
    executor: a key of bench.executors.EXECUTORS ("local" process pool, "ray" cluster), with
    executor_options (ray: address, shard_views); force: replace a run folder that holds another
    profile's run or foreign files (bench.manifest.claim_run_dir); report: called with the run
    folder once the tables are written, its time recorded as stage "report" (None or False: no report).
    """
    t_start = time.perf_counter()
    run_dir = manifest.claim_run_dir(Path(out_dir) if out_dir else default_run_dir(profile),
                                     profile.name, profile.config_hash(), force)
    workers = workers or max(1, min(os.cpu_count() or 1, 8))
    skipped: dict[str, str] = {}
    if methods is None:
        methods, skipped = plan_methods(profile)
    plan = make_plan(profile, methods, renders_dir, run_dir)
    outcomes, stage_s, datasets = get_executor(executor)(plan, workers, progress, **(executor_options or {}))
    stage_s.update({f"cpu.{k}": v for k, v in _sum_stages(outcomes).items()})

    t0 = time.perf_counter()
    df = pd.DataFrame([r for o in outcomes for r in o.rows])
    df.insert(0, "profile", profile.name)
    res.write_results(df, run_dir)
    views = [(house, v) for house, ds in datasets for v in sorted((Path(ds) / "views").iterdir())
             if (v / "view.json").is_file()]  # from the renders, not from the outcomes
    manifest.write_manifest(run_dir, manifest.expected_rows(views, [m.name for m in methods]),
                            profile.name, profile.config_hash())
    det = detection_ap(outcomes)
    stage_s["summarize"] = time.perf_counter() - t0
    wall = time.perf_counter() - t_start
    meta = res.make_metadata(profile.to_dict(), profile.config_hash(), profile.seed, wall, stage_s,
                             workers=workers, executor=executor, n_views=len(outcomes), n_rows=len(df),
                             **per_unit_timings(stage_s, len(outcomes), len(df) // max(1, len(methods))),
                             methods=[m.name for m in methods], skipped_detectors=skipped,
                             datasets={h: str(p) for h, p in datasets})
    res.write_summary(run_dir, meta, res.summarize(df), det)
    if report:
        t0 = time.perf_counter()
        report(run_dir)
        stage_s["report"] = time.perf_counter() - t0
        meta["stage_time_s"] = stage_s
        meta["wall_time_s"] = time.perf_counter() - t_start
        res.write_summary(run_dir, meta, res.summarize(df), det)
    return RunInfo(run_dir, meta["wall_time_s"], stage_s, skipped, len(outcomes), len(df))
