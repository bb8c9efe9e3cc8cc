"""The benchmark end to end: render (cached) -> detect -> match -> reconstruct -> measure -> tables.

    from bench.runner import run_benchmark
    run_dir = run_benchmark(load_profile("smoke"), workers=2)

Views are evaluated in a process pool (``workers``), with a rich progress bar. Every ground-truth
window gets one row per method combination (see bench.evaluate). The run folder (default
``out/bench/<profile>-<config hash>``) receives results.parquet/.csv, summary.json and the report;
renders go to ``out/renders`` (renders.dataset names and reuses them by config hash).
"""
from __future__ import annotations

import itertools
import multiprocessing as mp
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from bench import results as res
from bench.evaluate import Method, ViewOutcome, ViewTask, evaluate_view
from bench.profiles import ALL, Profile
from fenestra.errors import FenestraError

OUT_ROOT = Path("out")
LEARNED_DETECTOR_OPTIONS = {"threads": 1}  # one torch thread per worker process


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
    """["all"] -> every registered name; otherwise check each name exists."""
    if names == (ALL,):
        return list(registry)
    bad = [n for n in names if n not in registry]
    if bad:
        raise FenestraError(f"unknown {what} {bad}; registered: {sorted(registry)}")
    return list(names)


def available_detectors(names: list[str]) -> tuple[list[str], dict[str, str]]:
    """Detectors that can be built here (learned ones need weights); {skipped: reason}."""
    from pipeline.detectors import get_detector  # noqa: PLC0415

    ok, skipped = [], {}
    for n in names:
        try:
            if n not in ("oracle", "oracle-degraded"):
                get_detector(n, **LEARNED_DETECTOR_OPTIONS)
            ok.append(n)
        except Exception as e:  # noqa: BLE001 - missing weights etc.: skip, recorded in metadata
            skipped[n] = f"{type(e).__name__}: {e}"
    return ok, skipped


def pose_strategies() -> dict[str, str]:
    """Bench pose names: every per-window solver, every per-wall strategy, and each per-wall one
    with K withheld (``wall+noK``: the focal length estimated from the photo, bench.uncertainty)."""
    from pipeline.pose import POSE_SOLVERS  # noqa: PLC0415
    from pipeline.walls import WALL_STRATEGIES  # noqa: PLC0415

    from bench.uncertainty import NO_K_SUFFIX  # noqa: PLC0415

    return {**{p: "per-window" for p in POSE_SOLVERS}, **{p: "per-wall" for p in WALL_STRATEGIES},
            **{p + NO_K_SUFFIX: "per-wall, K withheld" for p in WALL_STRATEGIES}}


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


def render_house(profile: Profile, house: str, renders_dir: Path | None = None,
                 progress: bool = True) -> Path:
    """Render one house's views with renders.dataset (which reuses views already rendered).

    Returns the dataset folder (under ``renders_dir``, default out/renders).
    """
    from renders.dataset import render_dataset  # noqa: PLC0415

    from bench.render_adapter import dataset_config  # noqa: PLC0415

    root = Path(renders_dir) if renders_dir is not None else OUT_ROOT / "renders"
    return Path(render_dataset(dataset_config(profile, house, root), progress=progress))


# ---------------------------------------------------------------- evaluation

def _tasks(datasets: list[tuple[str, Path]], profile: Profile,
           methods: tuple[Method, ...]) -> list[ViewTask]:
    opts = tuple((d, tuple(LEARNED_DETECTOR_OPTIONS.items()))
                 for d in dict.fromkeys(m.detector for m in methods)
                 if d not in ("oracle", "oracle-degraded"))
    tasks = []
    for house, ds in datasets:
        for v in sorted(p for p in (ds / "views").iterdir() if (p / "view.json").is_file()):
            tasks.append(ViewTask(view_dir=str(v), house=house, renderer=profile.render.renderer,
                                  methods=methods, evaluation=profile.evaluation,
                                  height_m=profile.methods.height_m, detector_options=opts))
    return tasks


def _init_worker() -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import cv2  # noqa: PLC0415

    cv2.setNumThreads(1)


def evaluate_all(tasks: list[ViewTask], workers: int, progress: bool = True) -> list[ViewOutcome]:
    """evaluate_view over all tasks, in order; a process pool when workers > 1."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn, TimeRemainingColumn  # noqa: PLC0415

    cols = ("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), TimeRemainingColumn())
    outcomes: list[ViewOutcome] = []
    with Progress(*cols, disable=not progress, transient=False) as bar:
        job = bar.add_task("evaluating views", total=len(tasks))
        if workers <= 1:
            _init_worker()
            for t in tasks:
                outcomes.append(evaluate_view(t))
                bar.advance(job)
            return outcomes
        ctx = mp.get_context("spawn")  # no fork after EGL/torch state in the parent
        with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker) as pool:
            for o in pool.map(evaluate_view, tasks, chunksize=1):
                outcomes.append(o)
                bar.advance(job)
    return outcomes


def _sum_stages(outcomes: list[ViewOutcome]) -> dict[str, float]:
    total: dict[str, float] = {}
    for o in outcomes:
        for k, v in o.stage_s.items():
            total[k] = total.get(k, 0.0) + v
    return dict(sorted(total.items()))


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
            out[det]["n_gt"] = len(gt)
    return out


def run_benchmark(profile: Profile, out_dir: str | Path | None = None, workers: int | None = None,
                  progress: bool = True, report: bool = True, methods: tuple[Method, ...] | None = None,
                  renders_dir: str | Path | None = None) -> RunInfo:
    """Run a profile end to end; see the module docstring. Returns a RunInfo.

    methods: override the profile's method combinations (e.g. a test's extra snapper);
    renders_dir: where cached renders live (default out/renders).
    """
    t_start = time.perf_counter()
    run_dir = Path(out_dir) if out_dir else default_run_dir(profile)
    run_dir.mkdir(parents=True, exist_ok=True)
    workers = workers or max(1, min(os.cpu_count() or 1, 8))
    skipped: dict[str, str] = {}
    if methods is None:
        methods, skipped = plan_methods(profile)
    stage_s: dict[str, float] = {}

    t0 = time.perf_counter()
    datasets = [(h, render_house(profile, h, renders_dir, progress)) for h in house_list(profile)]
    stage_s["render"] = time.perf_counter() - t0

    tasks = _tasks(datasets, profile, methods)
    if not tasks:
        raise FenestraError(f"profile {profile.name!r} rendered no views")
    t0 = time.perf_counter()
    outcomes = evaluate_all(tasks, workers, progress)
    stage_s["evaluate_wall"] = time.perf_counter() - t0
    stage_s.update({f"cpu.{k}": v for k, v in _sum_stages(outcomes).items()})

    t0 = time.perf_counter()
    df = pd.DataFrame([r for o in outcomes for r in o.rows])
    df.insert(0, "profile", profile.name)
    res.write_results(df, run_dir)
    det = detection_ap(outcomes)
    stage_s["summarize"] = time.perf_counter() - t0
    wall = time.perf_counter() - t_start
    meta = res.make_metadata(profile.to_dict(), profile.config_hash(), profile.seed, wall, stage_s,
                             workers=workers, n_views=len(tasks), n_rows=len(df),
                             methods=[m.name for m in methods], skipped_detectors=skipped,
                             datasets={h: str(p) for h, p in datasets})
    res.write_summary(run_dir, meta, res.summarize(df), det)
    if report:
        from reports.build import build_report  # noqa: PLC0415

        t0 = time.perf_counter()
        build_report(run_dir)
        stage_s["report"] = time.perf_counter() - t0
        meta["stage_time_s"] = stage_s
        meta["wall_time_s"] = time.perf_counter() - t_start
        res.write_summary(run_dir, meta, res.summarize(df), det)
    return RunInfo(run_dir, meta["wall_time_s"], stage_s, skipped, len(tasks), len(df))
