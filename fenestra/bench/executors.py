"""Executors: how the bench spreads its views over processes (``local``) or machines (``ray``).

    outcomes, stage_s, datasets = EXECUTORS["local"](plan, workers=2, progress=True)

Both executors take the same :class:`Plan` (each house's dataset config, the methods, the
evaluation options) and return the ViewOutcomes in one canonical order (house order, then view
index), so a results table never depends on the executor or on the number of workers. Every view
is one bench.evaluate.ViewTask (a source that loads its LabelledView, the methods, the options),
evaluated by bench.evaluate.evaluate_task; :func:`evaluate_local` also evaluates a photo run's
views (read by bench.real.adapters).

``local``
    renders the houses in a process pool of ``workers`` processes (one house per task, cached
    under the renders folder), then evaluates the views in a pool of as many.
``ray``
    splits each house's views into shards of ``shard_views`` views. A Ray actor per worker (one
    CPU each) renders a shard's views into the same render cache (its own renderer, pyrender
    imported inside the worker), evaluates them and writes the shard's outcomes to
    ``<run>/shards/<key>.parquet`` (the rows) and ``<run>/shards/<key>.json`` (its index: the
    parquet file's sha256 and row count, each view's row count, stage seconds, COCO gt/dt lists
    and false-positive counts, and the sha256 of all of that), each atomically; the driver merges the shards in canonical
    order. Nothing is unpickled from disk. A shard written by an interrupted run with the same
    code, config and methods is reused, as cached views are; one whose digest or row counts do
    not match its index is recomputed with a warning, never trusted and never silently short. Connects to a running cluster (``address``, e.g. "auto" or
    "127.0.0.1:6379") or starts a local one with ``workers`` CPUs.

Every worker runs with ``THREADS_PER_WORKER`` BLAS/OpenMP/OpenCV/torch threads, set before numpy
is imported, so N workers never oversubscribe N cores.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import multiprocessing as mp
import os
import re
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator

from fenestra.bench.evaluate import EvalOptions, ViewOutcome, ViewTask, evaluate_task
from fenestra.bench.results import SHARD_DIR
from fenestra.bench.profiles import Profile
from fenestra.errors import FenestraError
from fenestra.methods import Method
from fenestra.files import IMPORT_ROOT, PACKAGE_DIR, write_bytes
from fenestra.bench.render_adapter import RenderedViewRef
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn, TimeRemainingColumn
import numpy as np
from fenestra import outputs
from fenestra.renders.dataset import render_dataset

THREADS_PER_WORKER = 1
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
CODE_PACKAGES = ("bench", "pipeline", "renders", "scenes")  # subpackages of fenestra outcomes depend on (+ its ground floor)


@dataclass(frozen=True)
class HousePlan:
    """One house of a run: its name (bundled, IFC path or procedural:<seed>) and dataset config."""

    house: str
    dataset: object  # renders.dataset.DatasetConfig (kept untyped: no renders import at module load)


@dataclass(frozen=True)
class Plan:
    """Everything an executor needs (picklable): houses, methods, evaluation options, run folder."""

    houses: tuple[HousePlan, ...]
    profile: Profile
    methods: tuple[Method, ...]
    options: EvalOptions
    run_dir: str


def thread_env(threads: int = THREADS_PER_WORKER) -> dict[str, str]:
    """Environment variables that cap BLAS/OpenMP threads of a worker process."""
    return {k: str(threads) for k in THREAD_ENV}


@contextlib.contextmanager
def _environ(env: dict[str, str]) -> Iterator[None]:
    """Set environment variables for the block (spawned workers inherit them), then restore."""
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def worker_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A pool of ``workers`` spawned processes (no fork after EGL/torch state in the parent), each
    with capped BLAS/OpenMP/OpenCV threads (:func:`thread_env`, :func:`init_worker`)."""
    ctx = mp.get_context("spawn")
    with _environ(thread_env()), ProcessPoolExecutor(workers, mp_context=ctx, initializer=init_worker) as pool:
        yield pool


def init_worker(threads: int = THREADS_PER_WORKER) -> None:
    """Cap this process's OpenCV threads (BLAS/OpenMP ones come from :func:`thread_env`)."""
    os.environ.update(thread_env(threads))
    import cv2  # noqa: PLC0415

    cv2.setNumThreads(threads)


def view_tasks(plan: Plan, house: str, dataset_dir: Path, indices: range | None = None) -> list[ViewTask]:
    """ViewTasks of one rendered house (all its views, or the given view indices), in index order."""

    views = sorted(p for p in (Path(dataset_dir) / "views").iterdir() if (p / "view.json").is_file())
    if indices is not None:
        views = [p for p in views if int(p.name) in indices]
    return [ViewTask(RenderedViewRef(str(v), house, plan.profile.source.render.renderer), plan.methods, plan.options)
            for v in views]


def _progress(enabled: bool):
    """A rich progress bar (a context manager; disabled: prints nothing)."""

    return Progress("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), TimeRemainingColumn(), disable=not enabled, transient=False)


# ---------------------------------------------------------------- local

Keep = Callable[[ViewOutcome], ViewOutcome]  # what is kept of each outcome, called in canonical order


def _keep_all(o: ViewOutcome) -> ViewOutcome:
    return o


def _evaluate_to_frame(task: ViewTask) -> ViewOutcome:
    """evaluate_task with the rows moved into a DataFrame in the worker (ViewOutcome.to_frame):
    a compact pickle, and no per-row Python objects in the parent."""
    return evaluate_task(task).to_frame()


def evaluate_local(tasks: Iterable[ViewTask], workers: int, progress: bool = True,
                   total: int | None = None, keep: Keep | None = None) -> list[ViewOutcome]:
    """evaluate_task over all tasks, in order; a spawned process pool when workers > 1. tasks may
    be a generator (with workers <= 1 each view is loaded only when its turn comes); total: their
    number for the progress bar, when known; keep: called with each outcome (its rows in a
    DataFrame) as it arrives, in order, and returns what is kept of it (e.g. the outcome without
    its rows once they are spooled to disk: a run's memory stays bounded); default all."""
    keep = keep or _keep_all
    outcomes: list[ViewOutcome] = []
    with _progress(progress) as bar:
        job = bar.add_task("evaluating views", total=len(tasks) if total is None and hasattr(tasks, "__len__")
                           else total)
        if workers <= 1:
            init_worker()
            for t in tasks:
                outcomes.append(keep(_evaluate_to_frame(t)))
                bar.advance(job)
            return outcomes
        with worker_pool(workers) as pool:
            for o in pool.map(_evaluate_to_frame, tasks, chunksize=1):
                outcomes.append(keep(o))
                bar.advance(job)
    return outcomes


def _render_house(house: HousePlan, progress: bool = False) -> tuple[str, float]:
    """Render (or reuse) one house's dataset: its folder and the CPU seconds it took (this process's,
    its GL driver's threads included; a process-pool task)."""
    from fenestra.renders.dataset import render_dataset  # noqa: PLC0415  (pyrender: inside the worker)

    t0 = time.process_time()
    folder = str(render_dataset(house.dataset, progress=progress))
    return folder, time.process_time() - t0


def render_local(houses: tuple[HousePlan, ...], workers: int, progress: bool = True) -> tuple[list[Path], float]:
    """Every house's dataset folder, rendering houses in parallel (one renderer per process), and
    the CPU seconds the renders took (summed over the processes)."""
    if workers <= 1 or len(houses) <= 1:
        done = [_render_house(h, progress) for h in houses]
    else:
        done = []
        with _progress(progress) as bar:
            job = bar.add_task("rendering houses", total=len(houses))
            ctx = mp.get_context("spawn")
            with ProcessPoolExecutor(min(workers, len(houses)), mp_context=ctx) as pool:
                for d in pool.map(_render_house, houses, chunksize=1):
                    done.append(d)
                    bar.advance(job)
    return [Path(d) for d, _ in done], sum(s for _, s in done)


def run_local(plan: Plan, workers: int, progress: bool = True, keep: Keep | None = None, **_: object
              ) -> tuple[list[ViewOutcome], dict[str, float], list[tuple[str, Path]]]:
    """Render the houses in a process pool, then evaluate the views in one; (outcomes, each
    passed through ``keep`` in canonical order (evaluate_local), stage seconds (wall; the renders'
    CPU seconds as ``cpu.render``), datasets)."""
    t0 = time.perf_counter()
    folders, render_cpu = render_local(plan.houses, workers, progress)
    datasets = list(zip((h.house for h in plan.houses), folders))
    stage_s = {"render": time.perf_counter() - t0, "cpu.render": render_cpu}
    tasks = [t for house, ds in datasets for t in view_tasks(plan, house, ds)]
    if not tasks:
        raise FenestraError(f"profile {plan.profile.name!r} rendered no views")
    t0 = time.perf_counter()
    outcomes = evaluate_local(tasks, workers, progress, keep=keep)
    stage_s["evaluate_wall"] = time.perf_counter() - t0
    return outcomes, stage_s, datasets


# ---------------------------------------------------------------- ray

@dataclass(frozen=True)
class Shard:
    """A block of one house's views, and where its outcomes go."""

    house_index: int
    house: HousePlan
    views: range
    out: str


def code_version() -> str:
    """12 hex digits of the source of the packages outcomes depend on (shard cache key)."""
    root = PACKAGE_DIR
    h = hashlib.sha256()
    ground = sorted(f for f in root.glob("*") if f.is_file())
    for f in ground + [f for pkg in CODE_PACKAGES for f in sorted((root / pkg).rglob("*"))]:
        if f.suffix in (".py", ".toml", ".pt") and "__pycache__" not in f.parts:
            h.update(str(f.relative_to(root)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:12]


def plan_shards(plan: Plan, shard_views: int) -> list[Shard]:
    """Shards of every house, in canonical order; each named by a hash of what changes it."""
    if shard_views < 1:
        raise ValueError(f"shard_views must be >= 1, got {shard_views}")
    version = code_version()
    shards = []
    for i, h in enumerate(plan.houses):
        n = h.dataset.n_views
        for start in range(0, n, shard_views):
            views = range(start, min(n, start + shard_views))
            key = hashlib.sha256(repr((version, h.dataset, plan.options, plan.methods, views.start, views.stop))
                                 .encode()).hexdigest()[:16]
            shards.append(Shard(i, h, views, str(Path(plan.run_dir) / SHARD_DIR / f"{key}.json")))
    return shards


SHARD_FORMAT = 3  # version of the shard files (index JSON + rows Parquet); 2: the index's own digest; 3: export counts


def _index_digest(index: dict) -> str:
    """sha256 of a shard index's content (every key but ``index_sha256``), as canonical JSON
    (sorted keys): it covers the detections, false-positive and export counts and stage seconds
    that feed the figures, as ``rows_sha256`` covers the rows."""
    body = {k: v for k, v in index.items() if k != "index_sha256"}
    canon = json.dumps(json.loads(json.dumps(body, default=_jsonable)), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canon.encode()).hexdigest()


def _jsonable(x):
    """numpy scalars and arrays as JSON values (json.dumps default)."""

    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def write_shard(index_path: str | Path, dataset: str, outcomes: list[ViewOutcome], render_s: float) -> Path:
    """Write a shard: its rows as Parquet beside the JSON index (sha256 of the Parquet bytes, row
    counts, each view's stage seconds, COCO lists, false-positive and export counts); the index last,
    so it names a complete file."""

    import pandas as pd  # noqa: PLC0415 (pandas: imported when first used, not at the package's import)

    index_path = Path(index_path)
    index_path.parent.mkdir(parents=True, exist_ok=True)
    rows = [{**r, "_view": i} for i, o in enumerate(outcomes) for r in o.rows]
    buf = io.BytesIO()
    pd.DataFrame(rows).to_parquet(buf, index=False)
    data = buf.getvalue()
    write_bytes(index_path.with_suffix(".parquet"), data)
    index = {"format": SHARD_FORMAT, "dataset": dataset, "render_s": render_s,
             "rows_sha256": hashlib.sha256(data).hexdigest(), "n_rows": len(rows),
             "views": [{"n_rows": len(o.rows), "stage_s": o.stage_s, "coco_gt": o.coco_gt, "coco_dt": o.coco_dt,
                        "n_false_positives": o.n_false_positives, "export_counts": o.export_counts,
                        "dataset": o.dataset, "view": o.view,
                        "size": list(o.size), "window_ids": list(o.window_ids)} for o in outcomes]}
    index["index_sha256"] = _index_digest(index)
    write_bytes(index_path, json.dumps(index, default=_jsonable).encode())
    return index_path


def read_shard(index_path: str | Path) -> dict:
    """{"dataset", "outcomes", "render_s"} of a shard written by :func:`write_shard`; ValueError
    naming what does not match (index unreadable, Parquet digest, row counts) or OSError."""

    import pandas as pd  # noqa: PLC0415 (pandas: imported when first used, not at the package's import)

    index_path = Path(index_path)
    try:
        index = json.loads(index_path.read_bytes())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ValueError(f"index is not valid JSON ({e})") from e
    if not isinstance(index, dict) or index.get("format") != SHARD_FORMAT:
        raise ValueError(f"index is not a format-{SHARD_FORMAT} shard index")
    if _index_digest(index) != index.get("index_sha256"):
        raise ValueError("index does not match its own digest (detections or counts changed)")
    data = index_path.with_suffix(".parquet").read_bytes()
    if hashlib.sha256(data).hexdigest() != index.get("rows_sha256"):
        raise ValueError("rows file does not match the digest in its index")
    df = pd.read_parquet(io.BytesIO(data)) if data else pd.DataFrame()
    views = index.get("views")
    if len(df) != index.get("n_rows") or not isinstance(views, list) or sum(v["n_rows"] for v in views) != len(df):
        raise ValueError(f"{len(df)} rows, the index says {index.get('n_rows')}")
    outcomes = []
    for i, v in enumerate(views):
        sub = df[df["_view"] == i].drop(columns="_view") if len(df) else df
        if len(sub) != v["n_rows"]:
            raise ValueError(f"view {i} has {len(sub)} rows, the index says {v['n_rows']}")
        outcomes.append(ViewOutcome(sub.to_dict("records"), v["stage_s"], v["coco_gt"], v["coco_dt"],
                                    v["n_false_positives"], v["export_counts"], v["dataset"], v["view"],
                                    tuple(v["size"]), tuple(v["window_ids"])))
    return {"dataset": index["dataset"], "outcomes": outcomes, "render_s": float(index["render_s"])}


def run_shard(plan: Plan, shard: Shard) -> str:
    """Render and evaluate one shard; write its rows and index (:func:`write_shard`)."""
    from fenestra.renders.dataset import render_dataset  # noqa: PLC0415  (pyrender: inside the worker)

    t0 = time.perf_counter()
    ds = Path(render_dataset(shard.house.dataset, progress=False, only=shard.views))
    render_s = time.perf_counter() - t0
    outcomes = [evaluate_task(t) for t in view_tasks(plan, shard.house.house, ds, shard.views)]
    return str(write_shard(shard.out, str(ds), outcomes, render_s))


SHARD_NAME = re.compile(r"[0-9a-f]{16}\.(json|parquet)")  # plan_shards' names


def recognised_shards(run_dir: str | Path, listed: Iterable[str] = ()) -> list[str]:
    """The shard files under ``run_dir/SHARD_DIR`` that :func:`write_shard` wrote, as paths
    relative to ``run_dir``, those in ``listed`` (already in the run's manifest) not looked at: a
    named index whose own digest and rows file's digest check (both files), and a rows file whose
    index was never written (a worker killed between the two) when it is a Parquet file with the
    ``_view`` column. Nothing is unpickled or trusted: a shard is still checked when read."""
    import pyarrow.parquet as pq  # noqa: PLC0415 (pyarrow: imported when first used, not at the package's import)

    folder = Path(run_dir) / SHARD_DIR
    names = {p.name for p in folder.iterdir() if p.is_file() and not p.is_symlink() and SHARD_NAME.fullmatch(p.name)}
    skip = set(listed)
    found = []
    for n in sorted(n for n in names if f"{SHARD_DIR}/{n}" not in skip):
        stem, suffix = n.rsplit(".", 1)
        if suffix == "json" and _load_shard(str(folder / n), warn=False) is not None:
            found += [n, f"{stem}.parquet"]
        elif suffix == "parquet" and f"{stem}.json" not in names:
            with contextlib.suppress(Exception):  # not Parquet, unreadable: not recognised
                if "_view" in pq.read_schema(folder / n).names:
                    found.append(n)
    return [f"{SHARD_DIR}/{n}" for n in found]


def _record_shard(run_dir: str, path: str) -> None:
    """List a finished shard's two files in the run folder's manifest (fenestra.outputs)."""

    index = Path(path)
    outputs.record(run_dir, [p.relative_to(run_dir).as_posix() for p in (index, index.with_suffix(".parquet"))
                             if p.is_file()])


def _load_shard(path: str, warn: bool = True) -> dict | None:
    """A shard's content, or None if absent or damaged (then it is recomputed; a damaged one
    with a warning naming it)."""
    if not Path(path).exists():
        return None
    try:
        return read_shard(path)
    except (OSError, ValueError, KeyError, TypeError) as e:
        if warn:
            print(f"warning: shard {path} is damaged ({e}); recomputing it", file=sys.stderr)
        return None


class _ShardWorker:
    """Body of the Ray actor: one per worker CPU, reused for many shards."""

    def __init__(self) -> None:
        init_worker()

    def run(self, plan: Plan, shard: Shard) -> str:
        return run_shard(plan, shard)


RAY_RETRIES = 1  # a shard whose worker died is run again this many times on a fresh worker, then named


def _ray_map(ray, plan: Plan, shards: list[Shard], n_actors: int) -> Iterator[str]:
    """Run ``shards`` on ``n_actors`` Ray actors, yielding each shard's output path as it finishes.

    A shard whose actor dies (killed, out of memory, its node lost) is retried RAY_RETRIES times on
    a fresh actor, with a warning; then FenestraError names the shard. An exception raised by the
    shard's own code propagates as it is."""
    from ray.exceptions import RayActorError, WorkerCrashedError  # noqa: PLC0415 (Ray: imported when first used, not at the package's import)

    make = ray.remote(num_cpus=1)(_ShardWorker).remote
    actors = [make() for _ in range(n_actors)]
    queue = [(s, 0) for s in shards]
    pending: dict = {}  # object ref -> (actor index, shard, attempt)

    def submit(i: int) -> None:
        if queue:
            s, attempt = queue.pop(0)
            pending[actors[i].run.remote(plan, s)] = (i, s, attempt)

    for i in range(n_actors):
        submit(i)
    while pending:
        (ref,), _ = ray.wait(list(pending), num_returns=1)
        i, s, attempt = pending.pop(ref)
        try:
            path = ray.get(ref)
        except (RayActorError, WorkerCrashedError) as e:
            what = f"shard {Path(s.out).name} ({s.house.house}, views {s.views.start}-{s.views.stop - 1})"
            if attempt >= RAY_RETRIES:
                raise FenestraError(f"{what}: its Ray worker died {attempt + 1} times "
                                    f"({type(e).__name__}); see the Ray logs of that node") from e
            print(f"warning: {what}: its Ray worker died ({type(e).__name__}); running it again on a new worker",
                  file=sys.stderr)
            actors[i] = make()
            queue.insert(0, (s, attempt + 1))
        else:
            yield path
        submit(i)


def _shard_render_s(path: str, warn: bool = True) -> float | None:
    """A shard's render seconds if it is complete and sound (:func:`_load_shard`), else None;
    its rows are read to check them, not kept."""
    shard = _load_shard(path, warn)
    return None if shard is None else shard["render_s"]


def run_ray(plan: Plan, workers: int, progress: bool = True, address: str | None = None,
            shard_views: int = 20, keep: Keep | None = None, **_: object
            ) -> tuple[list[ViewOutcome], dict[str, float], list[tuple[str, Path]]]:
    """Render and evaluate shards on Ray actors, merge in canonical order (see the module docstring),
    one shard in memory at a time, each outcome passed through ``keep`` (evaluate_local)."""
    try:
        import ray  # noqa: PLC0415 (Ray: imported when first used, not at the package's import)
    except ImportError as e:  # pragma: no cover - ray is a pinned dependency
        raise FenestraError("the ray executor needs the `ray` package (make setup installs it)") from e

    keep = keep or _keep_all
    shards = plan_shards(plan, shard_views)
    done = {s.out: _shard_render_s(s.out) for s in shards}
    todo = [s for s in shards if done[s.out] is None]
    t0 = time.perf_counter()
    if todo:
        root = str(IMPORT_ROOT)  # the workers import this fenestra
        env = {**thread_env(), "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])),
               "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl")}
        started = not ray.is_initialized()
        if started:
            kw = {"address": address} if address else {"num_cpus": workers, "include_dashboard": False}
            ray.init(**kw, runtime_env={"env_vars": env}, log_to_driver=False, logging_level="ERROR")
        try:
            n_actors = max(1, min(len(todo), workers if not address else int(ray.cluster_resources().get("CPU", 1))))
            with _progress(progress) as bar:
                job = bar.add_task(f"shards on {n_actors} Ray workers", total=len(todo))
                for path in _ray_map(ray, plan, todo, n_actors):
                    done[path] = _shard_render_s(path)
                    _record_shard(plan.run_dir, path)  # listed as written: a killed run's shards are Fenestra's
                    bar.advance(job)
        finally:
            if started:
                ray.shutdown()
    stage_s = {"shards_wall": time.perf_counter() - t0, "shards_reused": float(len(shards) - len(todo))}
    missing = [s.out for s in shards if done[s.out] is None]
    if missing:
        raise FenestraError(f"{len(missing)} shard(s) produced no readable result, e.g. {missing[0]}")
    stage_s["cpu.render"] = sum(done[s.out] for s in todo)
    # the dataset-wide files (coco.json) once every shard of a house is there: no view is re-rendered

    datasets = [(h.house, Path(render_dataset(h.dataset, progress=False))) for h in plan.houses]
    outcomes = []
    for s in shards:  # canonical order, one shard's rows at a time
        shard = _load_shard(s.out)
        if shard is None:
            raise FenestraError(f"shard {s.out} changed while the run merged it")
        outcomes += [keep(o.to_frame()) for o in shard["outcomes"]]
    if not outcomes:
        raise FenestraError(f"profile {plan.profile.name!r} rendered no views")
    return outcomes, stage_s, datasets


EXECUTORS: dict[str, Callable[..., tuple[list[ViewOutcome], dict[str, float], list[tuple[str, Path]]]]] = {
    "local": run_local,
    "ray": run_ray,
}


def get_executor(name: str) -> Callable:
    """EXECUTORS[name], or a FenestraError listing the registered ones."""
    if name not in EXECUTORS:
        raise FenestraError(f"unknown executor {name!r}; choose from {sorted(EXECUTORS)}")
    return EXECUTORS[name]


__all__ = ["EXECUTORS", "HousePlan", "Plan", "Shard", "evaluate_local", "get_executor", "plan_shards",
           "run_shard", "thread_env", "view_tasks"]
