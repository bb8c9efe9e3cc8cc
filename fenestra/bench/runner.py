"""The benchmark end to end, renders and photos alike: views -> detect -> match -> reconstruct ->
measure -> tables, summary, report.

    from fenestra.bench.runner import run_benchmark
    info = run_benchmark(load_profile("smoke"), workers=2)                       # renders
    info = run_benchmark(load_profile("real"), sim_dir="out/bench/smoke")       # photos

One bench.profiles.Profile type, routed on its source: a synthetic profile (source
bench.profiles.Renders) renders its houses (cached) and evaluates their views with an executor
(bench.executors: a local process pool of ``workers`` processes, or a Ray cluster); a real
profile (source bench.real.profile.Datasets) reads its labelled datasets with
bench.real.adapters (optional datasets whose folder is absent are skipped and listed in the
metadata) and evaluates them in this process. Either way every view is a bench.views.LabelledView
evaluated by the one bench.evaluate.evaluate_view, and every labelled window gets one row per
method combination. The run folder (default ``out/bench/<profile>-<config hash>``) receives
results.parquet (results.csv with ``csv``), manifest.json, summary.json (metadata, per-method results, per-detector
detection AP), ``simreal.json`` for a real profile given a synthetic run folder
(bench.real.simreal) and, when a report writer is passed, the report; renders go to
``out/renders`` (renders.dataset names and reuses them by config hash). bench/ never imports
reports/ (reports read bench's tables): the CLI (fenestra/app/cli.py) passes the report writer in.
"""
from __future__ import annotations

import gc
import multiprocessing as mp
import os
import resource
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd

from fenestra.bench import manifest
from fenestra.bench import results as res
from fenestra.bench.detection_ap import detection_ap
from fenestra.bench.evaluate import EvalOptions, LoadedView, ViewOutcome, ViewTask
from fenestra.bench.executors import HousePlan, Keep, Plan, evaluate_local, get_executor
from fenestra.bench.profiles import ALL, Profile, planned_methods, selected
from fenestra.bench.views import LabelledView
from fenestra.errors import FenestraError, one_line
from fenestra.methods import Method
from fenestra.registry import plugin_metadata
from fenestra.userfiles import utf8_name
from fenestra.pipeline.detectors import DETECTORS
from fenestra.scenes.registry import BUNDLED, WILD_PREFIX, is_known, resolve
from fenestra.bench.render_adapter import dataset_config
from fenestra import outputs

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

def available_detectors(names: list[str]) -> tuple[list[str], dict[str, str]]:
    """Detectors that can be built here (learned ones need weights); {skipped: reason}. Each
    learned one is built once and dropped (not kept in the detectors' cache): the workers build
    their own, and the parent process stays small while it gathers the results table."""

    ok, skipped = [], {}
    for n in names:
        try:
            if not DETECTORS[n].needs_instances:  # the oracles load no weights
                DETECTORS[n].build(**LEARNED_DETECTOR_OPTIONS)
            ok.append(n)
        except Exception as e:  # noqa: BLE001 - missing weights etc.: skip, recorded in metadata
            skipped[n] = f"{type(e).__name__}: {e}"
    return ok, skipped


def plan_methods(profile: Profile) -> tuple[tuple[Method, ...], dict[str, str]]:
    """The methods the profile plans (bench.profiles.planned_methods: its cross product, or the
    union of its designed grids; K withheld only where the strategy fits the focal length) for
    the available detectors, and the skipped detectors."""
    spec = profile.methods
    requested = selected(spec, "detectors")
    dets, skipped = available_detectors(requested)
    if not dets:
        raise FenestraError(f"no detector of {requested} is available: {skipped}")
    return planned_methods(spec, dets), skipped


# ---------------------------------------------------------------- renders

def house_list(profile: Profile) -> list[str]:
    """Bundled house names of the profile (["all"] expanded), then procedural ones."""

    scenes = profile.source.scenes
    houses = list(BUNDLED) if scenes.houses == (ALL,) else list(scenes.houses)
    bad = [h for h in houses if not is_known(h)]
    if bad:
        raise FenestraError(f"unknown house(s) {bad}; bundled: {sorted(BUNDLED)}")
    for h in houses:  # a wild house whose folder is absent: say so plainly (SceneError, one line)
        if h.startswith(WILD_PREFIX):
            resolve(h)
    seed = scenes.procedural_seed
    return houses + [f"procedural:{seed + i}" for i in range(scenes.procedural)]


# ---------------------------------------------------------------- evaluation

def make_plan(profile: Profile, methods: tuple[Method, ...], renders_dir: str | Path | None,
              run_dir: Path) -> Plan:
    """The executor's plan: each house's dataset config (procedural IFCs generated here), methods,
    evaluation options (learned detectors: one torch thread, full-size images)."""

    root = Path(renders_dir) if renders_dir is not None else OUT_ROOT / "renders"
    opts = tuple((d, tuple(LEARNED_DETECTOR_OPTIONS.items()))
                 for d in dict.fromkeys(m.detector for m in methods)
                 if not DETECTORS[d].needs_instances)
    options = EvalOptions(evaluation=profile.source.evaluation, height_m=profile.methods.height_m, detector_options=opts)
    houses = tuple(HousePlan(h, dataset_config(profile, h, root)) for h in house_list(profile))
    return Plan(houses=houses, profile=profile, methods=methods, options=options, run_dir=str(run_dir))


@dataclass(frozen=True)
class Evaluated:
    """What a profile's views gave: outcomes (canonical order; their rows spooled, see
    :func:`spooling`), wall seconds per stage, the run manifest's expected rows (house, view,
    window_id, method; bench.manifest.expected_rows's compact form) and the source's metadata."""

    outcomes: list[ViewOutcome]
    stage_s: dict[str, float]
    expected: dict
    meta: dict


def spooling(spool: res.RowSpool) -> Keep:
    """The executors' ``keep``: each view's rows go to the spool, the outcome is kept without them."""
    def keep(o: ViewOutcome) -> ViewOutcome:
        spool.add(o.table())
        return replace(o, rows=[], frame=None)
    return keep


def evaluate_renders(profile: Profile, methods: tuple[Method, ...], run_dir: Path, workers: int,
                     progress: bool, renders_dir: str | Path | None, executor: str,
                     executor_options: dict | None, keep: Keep | None = None) -> Evaluated:
    """Render (cached) and evaluate a synthetic profile's views with an executor; the expected rows
    come from the rendered view.json files, not from the outcomes (a dropped view shows)."""
    plan = make_plan(profile, methods, renders_dir, run_dir)
    outcomes, stage_s, datasets = get_executor(executor)(plan, workers, progress, keep=keep,
                                                         **(executor_options or {}))
    views = [(house, v) for house, ds in datasets for v in sorted((Path(ds) / "views").iterdir())
             if (v / "view.json").is_file()]
    return Evaluated(outcomes, stage_s, manifest.expected_rows(views, [m.name for m in methods]),
                     {"workers": workers, "executor": executor, "datasets": {h: str(p) for h, p in datasets}})


def _utf8_view(view: LabelledView, folder: Path) -> LabelledView:
    """``view`` when its name is valid UTF-8; DatasetError naming its photo in ``folder`` before it is
    evaluated otherwise (the results table holds UTF-8 text only)."""
    utf8_name(view.name, f"dataset {folder}: photo")
    return view


def evaluate_photos(profile: Profile, methods: tuple[Method, ...], progress: bool,
                    keep: Keep | None = None) -> Evaluated:
    """Evaluate every view of a real profile's datasets, in order, in this process (the real
    datasets are a few photos, read one at a time; the learned detectors use one thread); the
    expected rows are every labelled window x method."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    datasets, skipped = profile.source.available()
    options = profile.source.eval_options(profile.methods.height_m)
    tasks = (ViewTask(LoadedView(_utf8_view(v, ds.folder())), methods, options) for ds in datasets for v in ds.views())
    t0 = time.perf_counter()
    outcomes = evaluate_local(tasks, workers=1, progress=progress, keep=keep)
    stage_s = {"evaluate_wall": time.perf_counter() - t0}
    expected = {"methods": [m.name for m in methods], "views": [[o.dataset, o.view, list(o.window_ids)] for o in outcomes]}
    n_windows = {d.name: sum(len(o.coco_gt) for o in outcomes if o.dataset == d.name) for d in datasets}
    return Evaluated(outcomes, stage_s, expected,
                     {"kind": "real", "workers": 1, "executor": "local", "skipped_datasets": skipped,
                      "datasets": {d.name: str(d.folder()) for d in datasets}, "n_windows": n_windows})


def _sum_stages(outcomes: list[ViewOutcome]) -> dict[str, float]:
    total: dict[str, float] = {}
    for o in outcomes:
        for k, v in o.stage_s.items():
            total[k] = total.get(k, 0.0) + v
    return dict(sorted(total.items()))


def peak_rss_mb() -> dict[str, float]:
    """Peak resident memory (MB) so far of this process and of its largest finished child (a
    worker of the evaluation's process pool, or the report's process): what bounds a run's memory."""

    return {who: resource.getrusage(r).ru_maxrss / 1024.0
            for who, r in (("main", resource.RUSAGE_SELF), ("largest_worker", resource.RUSAGE_CHILDREN))}


def _report_child(report: ReportWriter, run_dir: Path, conn) -> None:
    """Child side of :func:`report_apart`: run the report (each file listed in the run folder's
    manifest as it is written, fenestra.outputs.listing), send back None or its error's one line."""

    try:
        with outputs.listing(run_dir):
            report(run_dir)
        conn.send(None)
    except BaseException as e:  # noqa: BLE001 - sent to the parent, which raises it as one line
        conn.send(f"{type(e).__name__}: {one_line(e)}")
    finally:
        conn.close()


def report_apart(report: ReportWriter, run_dir: Path) -> None:
    """report(run_dir) in a spawned process (report must pickle: a module-level function or a
    functools.partial of one). The evaluation's memory, which this process's allocator keeps, and
    the report's reading of the results table then never add up in one process (peak RSS bounded
    by the larger of the two). Its failure is raised here as a FenestraError of one line."""

    ctx = mp.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_report_child, args=(report, Path(run_dir), send), name="fenestra-report")
    child.start()
    send.close()
    try:
        error = recv.recv()
    except EOFError:
        error = "the report process ended without a result"
    child.join()
    if error is None and child.exitcode != 0:
        error = f"the report process exited with code {child.exitcode}"
    if error is not None:
        raise FenestraError(f"report of {run_dir}: {error}")


class Laps:
    """Wall seconds between calls, recorded into ``stage_s`` as ``prefix + name``: ``lap("x")``
    stores the time since the previous call (or since construction)."""

    def __init__(self, stage_s: dict[str, float], prefix: str) -> None:
        self.stage_s, self.prefix, self.t = stage_s, prefix, time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.stage_s[self.prefix + name] = now - self.t
        self.t = now


def per_unit_timings(stage_s: dict[str, float], n_views: int, n_windows: int) -> dict[str, dict]:
    """Per-view and per-window milliseconds of every CPU stage (``cpu.*``): regressions show there.

    n_windows: ground-truth windows (one row each per method). Returns {"stage_ms_per_view": {...},
    "stage_ms_per_window": {...}}.
    """
    cpu = {k[4:]: v for k, v in stage_s.items() if k.startswith("cpu.")}
    return {"stage_ms_per_view": {k: 1000.0 * v / max(1, n_views) for k, v in cpu.items()},
            "stage_ms_per_window": {k: 1000.0 * v / max(1, n_windows) for k, v in cpu.items()}}


def run_inputs(profile: Profile, renders_dir: str | Path | None) -> list[Path]:
    """What a run reads and its folder must neither hold nor lie inside (fenestra.outputs): a
    real profile's dataset folders; a synthetic profile's IFC files given as paths and the
    render cache."""
    if profile.photos:
        return [Path(d.folder()) for d in profile.source.available(kfree=True)[0]]
    ifcs = [Path(h) for h in profile.source.scenes.houses if Path(h).is_file()]
    return [*ifcs, Path(renders_dir) if renders_dir is not None else OUT_ROOT / "renders"]


def run_benchmark(profile: Profile, out_dir: str | Path | None = None, workers: int | None = None,
                  progress: bool = True, report: ReportWriter | None = None,
                  methods: tuple[Method, ...] | None = None,
                  renders_dir: str | Path | None = None, executor: str = "local",
                  executor_options: dict | None = None, force: bool = False,
                  sim_dir: str | Path | None = None, csv: bool = False, inputs: tuple = ()) -> RunInfo:
    """Run a profile, synthetic or real, end to end; see the module docstring. Returns a RunInfo.

    methods: override the profile's method combinations (e.g. a test's extra snapper);
    renders_dir: where cached renders live (default out/renders);
    executor: a key of bench.executors.EXECUTORS ("local" process pool, "ray" cluster), with
    executor_options (ray: address, shard_views); force: replace a run folder that holds another
    profile's run or foreign files (bench.manifest.claim_run_dir); sim_dir: a real profile's
    synthetic run folder for simreal.json (FileNotFoundError if it is not a run folder); report:
    called with the run folder once the tables (and simreal.json) are written, its time recorded
    as stage "report" (None or False: no report); csv: also write results.csv (the Parquet
    table is the results table); inputs: further paths the run reads (a profile file, a --real
    run), which the run folder may neither hold nor lie inside (:func:`run_inputs` adds the
    datasets and the render cache).
    """
    t_start = time.perf_counter()
    load_before = os.getloadavg()
    provenance = {"commit": res._commit(), "models": res.model_digests()}  # what the run starts with, not ends with
    photos = profile.photos
    if sim_dir is not None and not photos:
        raise ValueError(f"sim_dir needs a real profile, got profile {profile.name!r}")
    if sim_dir is not None and not (Path(sim_dir) / res.SUMMARY_JSON).is_file():
        raise FileNotFoundError(f"--sim {sim_dir}: not a benchmark run folder (no {res.SUMMARY_JSON})")
    run_dir = Path(out_dir) if out_dir else default_run_dir(profile)
    with manifest.claimed(run_dir, profile.name, profile.config_hash(), force,
                          inputs=(*inputs, sim_dir, *run_inputs(profile, renders_dir))):
        workers = workers or max(1, min(os.cpu_count() or 1, 8))
        skipped: dict[str, str] = {}
        if methods is None:
            methods, skipped = plan_methods(profile)
        spool = res.RowSpool(run_dir / res.SPOOL_DIR, owner=run_dir)
        ev = (evaluate_photos(profile, methods, progress, spooling(spool)) if photos else
              evaluate_renders(profile, methods, run_dir, workers, progress, renders_dir, executor, executor_options,
                               spooling(spool)))
        outcomes, stage_s = ev.outcomes, dict(ev.stage_s)
        stage_s.update({f"cpu.{k}": v for k, v in _sum_stages(outcomes).items()})
        blocks = {}
        if photos and profile.source.kfree is not None:  # the K-free single-photo path (bench.photo_eval)
            from fenestra.bench.photo_eval import run_kfree  # noqa: PLC0415 (fenestra.bench.photo_eval loads pandas, shapely: imported when first used)

            blocks["kfree"] = run_kfree(profile.source.kfree, profile.source.kfree_views(), run_dir, progress, workers)
            stage_s["kfree"] = blocks["kfree"]["wall_time_s"]

        t0 = time.perf_counter()
        if spool.n_rows == 0:
            raise FenestraError(f"profile {profile.name!r}: no labelled window in its views")
        n_rows = spool.n_rows
        lap = Laps(stage_s, "summarize.")  # the summarize stage's parts (summarize + report: a target of 10 s)
        spool.finish(run_dir, profile.name, csv=csv)
        lap("table")
        manifest.write_manifest(run_dir, ev.expected, profile.name, profile.config_hash())
        lap("manifest")
        det = detection_ap(outcomes, per_dataset=photos)
        lap("detection_ap")
        pq_path = run_dir / res.RESULTS_PARQUET
        summary = res.summarize(pd.read_parquet(pq_path, columns=res.summary_columns(res.parquet_columns(pq_path))))
        res.add_export_precision(summary, outcomes)  # per detection, from the outcomes: not in the table
        lap("statistics")
        stage_s["summarize"] = time.perf_counter() - t0
        wall = time.perf_counter() - t_start
        meta = res.make_metadata(profile.to_dict(), profile.config_hash(), profile.seed, wall, stage_s, **provenance,
                                 n_views=len(outcomes), n_rows=n_rows,
                                 **per_unit_timings(stage_s, len(outcomes), n_rows // max(1, len(methods))),
                                 methods=[m.name for m in methods], skipped_detectors=skipped,
                                 load_average={"before": load_before, "after": os.getloadavg()},
                                 peak_rss_mb=peak_rss_mb(), plugins=plugin_metadata(), **ev.meta)
        res.write_summary(run_dir, meta, summary, det, **blocks)
        n_views = len(outcomes)
        del ev, outcomes  # the views' COCO material: freed before the report reads the table (peak RSS)
        gc.collect()
        if sim_dir is not None:
            from fenestra.bench.real.simreal import write_simreal  # noqa: PLC0415 (fenestra.bench.real.simreal loads SciPy, pandas, shapely: imported when first used)

            write_simreal(Path(sim_dir), run_dir)
        if report:
            t0 = time.perf_counter()
            report(run_dir)
            stage_s["report"] = time.perf_counter() - t0
            meta["stage_time_s"] = stage_s
            meta["wall_time_s"] = time.perf_counter() - t_start
            meta["peak_rss_mb"] = peak_rss_mb()  # the report runs in this process: its peak counts too
            res.write_summary(run_dir, meta, summary, det, **blocks)
        return RunInfo(run_dir, meta["wall_time_s"], stage_s, skipped, n_views, n_rows)
