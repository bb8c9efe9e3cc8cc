"""The K-free single-photo path measured on labelled photos: what a user gets from
``fenestra reconstruct PHOTO`` with no intrinsics, judged against the photo's labels.

    from fenestra.bench.photo_eval import KfreeSpec, run_kfree
    block = run_kfree(KfreeSpec(...), views_by_dataset, run_dir)   # -> summary.json "kfree"

Each LabelledView runs through the session ``fenestra reconstruct`` runs (pipeline.photo.photo_session
and run_options: the user's method without K, the focal chain with the photo's EXIF), once as it is
(with the export decision and the model the writer would write: pipeline.photo.written_model) and
once per photo transform (no export: the focal length, detections and walls). A
transform is a view transform: the image becomes the bytes of a file (bench.photo_transforms.TRANSFORMS),
which are decoded in memory as the CLI decodes a file, EXIF orientation applied, and whose EXIF
tags enter the session (bench.photo_transforms.decode); nothing is written. The photos of
``known_storey_datasets`` run once more as they are, with the export and ``--known-storey``
``known_storey_m`` (transform KNOWN_STOREY).

Per photo and transform one row of ``kfree.parquet`` (:func:`photo_row`): the run's identity, then
the columns of each of :func:`kfree_evaluators` (in the manner of bench.evaluators: each reads the
typed run, pipeline.session.Reconstruction and pipeline.export.WrittenModel, and returns its own
columns, NaN or None where the run has no such figure). The summary block (bench.kfree_summary)
per dataset, with the issue's targets (bench.results.KFREE_TARGETS) beside:

- output: share of photos whose run returned a reconstruction;
- export precision: exported windows (the export decision, Window.export) whose snapped quad's
  bounding box has IoU >= ``match_iou`` with a labelled window box (bench.metrics.box_iou_matrix),
  over all exported windows (pooled);
- export recall: labelled windows whose box has IoU >= ``match_iou`` with an exported window's
  (partial windows, cut by the photo's border, included: they are exported too), over all
  labelled windows (pooled; :func:`labels_matched`);
- windows per labelled window: exported windows / labelled windows (pooled);
- oversized: exported windows wider or taller than facade_model.MAX_WINDOW_M (4 m, the limit the
  pipeline flags by when no ``--known-*`` says otherwise; a partial window's visible extent),
  counted on the runs without ``--known-*`` (:func:`oversized`);
- walls per photo (median; the walls of the model, those holding a window it exports:
  Reconstruction.model_wall_ids; ``n_walls_fitted`` counts every fitted wall), and the share of
  photos with transforms whose wall count is the same under every transform as as is;
- wall tilt: per wall of the model (a wall with an exported window) the angle in degrees between
  its plane and the vertical of the written model (WrittenModel.up: the walls' agreeing up axes,
  i.e. their vertical vanishing directions, which also set the upright rotation;
  bench.evaluators.wall_tilts_deg); the median over walls. A consistency figure, not an
  independent truth: a wall whose windows share one rotation, alone in its photo or agreeing with
  the others, scores 0 by construction (a wall merged from fits up to facade_model.MERGE_DEG apart
  need not); on renders bench.evaluators.ModelEvaluator measures it against the true vertical;
- with a known storey (KNOWN_STOREY runs): exported windows taller than the storey
  (:func:`taller_than`), and per storey row of the written model the spread of the heights of its
  whole (not partial) exported windows, (max - min) / median, over rows of >= 2 such windows
  (bench.evaluators.row_spreads); the median over rows;
- focal spread: per photo the largest |f_t / f_as_is - 1| over the transforms; the median over
  photos (and per transform the median of |f_t / f_as_is - 1|);
- focal error (views with a calibration K): |f / f_K - 1| of the untransformed photo, median over
  the photos whose focal length was observed (source not the stated prior); on those photos, the
  share whose 90 % interval holds the calibrated focal length (bench.kfree_summary.interval_coverage).
"""
from __future__ import annotations

import math
import os
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd

from fenestra.bench.evaluators import exported_windows, row_spreads, wall_tilts_deg, window_size_m
from fenestra.bench.kfree_summary import summarize_kfree
from fenestra.bench.metrics import box_iou_matrix
from fenestra.bench.photo_transforms import TRANSFORMS, transformed
from fenestra.bench.results import AS_IS, KFREE_PARQUET, KNOWN_STOREY
from fenestra.bench.views import LabelledView
from fenestra.files import write_atomic
from fenestra.pipeline.facade_model import MAX_WINDOW_M, Known

NAN = math.nan


# ---------------------------------------------------------------- the spec ([kfree] of the real profile)

@dataclass(frozen=True)
class KfreeSpec:
    """``[kfree]`` of a real profile: datasets (profile dataset names measured), transforms (keys
    of TRANSFORMS besides as_is) applied to the photos of transform_datasets, mask_datasets (their
    labelled masks replace the detector, as ``fenestra reconstruct --masks``: the focal chain on
    ideal detections; not with transforms), max_photos per dataset (0: all), match_iou (export
    precision's and recall's box IoU), detector (registry name; "" = the CLI default),
    known_storey_datasets (their photos also run as they are with ``--known-storey``
    known_storey_m, in m: transform KNOWN_STOREY)."""

    datasets: tuple[str, ...] = ()
    transforms: tuple[str, ...] = ("gray", "jpeg", "exif_rot", "mirror", "crop")
    transform_datasets: tuple[str, ...] = ()
    mask_datasets: tuple[str, ...] = ()
    max_photos: int = 0
    match_iou: float = 0.3
    detector: str = ""
    known_storey_datasets: tuple[str, ...] = ()
    known_storey_m: float = 3.2

    def __post_init__(self) -> None:
        bad = [t for t in self.transforms if t not in TRANSFORMS or t == AS_IS]
        if bad:
            raise ValueError(f"[kfree] transforms {bad} unknown; choose from {sorted(set(TRANSFORMS) - {AS_IS})}")
        if not set(self.transform_datasets) <= set(self.datasets):
            raise ValueError(f"[kfree] transform_datasets {list(self.transform_datasets)} must be among "
                             f"datasets {list(self.datasets)}")
        if not set(self.mask_datasets) <= set(self.datasets) or set(self.mask_datasets) & set(self.transform_datasets):
            raise ValueError(f"[kfree] mask_datasets {list(self.mask_datasets)} must be among datasets and not "
                             f"among transform_datasets {list(self.transform_datasets)}")
        if not (isinstance(self.max_photos, int) and self.max_photos >= 0):
            raise ValueError(f"[kfree] max_photos must be an integer >= 0, got {self.max_photos!r}")
        if not 0 < self.match_iou <= 1:
            raise ValueError(f"[kfree] match_iou must be in (0, 1], got {self.match_iou!r}")
        if not set(self.known_storey_datasets) <= set(self.datasets):
            raise ValueError(f"[kfree] known_storey_datasets {list(self.known_storey_datasets)} must be among "
                             f"datasets {list(self.datasets)}")
        if not (math.isfinite(self.known_storey_m) and self.known_storey_m > 0):
            raise ValueError(f"[kfree] known_storey_m must be a positive length in m, got {self.known_storey_m!r}")


# ---------------------------------------------------------------- one run

@dataclass(frozen=True)
class KfreeTask:
    """One run of the K-free path (a process-pool task: the view travels in memory): the view, the
    transform (a key of TRANSFORMS, or KNOWN_STOREY: the photo as it is with ``known_storey_m``, m),
    match_iou (export precision's box IoU), detector ("" = the CLI default), use_masks (the view's
    labelled masks instead of the detector, as ``--masks``; untransformed only)."""

    view: LabelledView
    transform: str
    match_iou: float
    detector: str
    use_masks: bool
    known_storey_m: float = NAN

    def __post_init__(self) -> None:
        if self.use_masks and not self.exports:
            raise ValueError(f"labelled masks are in the untransformed frame, not under {self.transform!r}")
        if self.transform == KNOWN_STOREY and not self.known_storey_m > 0:
            raise ValueError(f"transform {KNOWN_STOREY!r} needs a known storey height, got {self.known_storey_m!r}")

    @property
    def exports(self) -> bool:
        """Whether the run exports (the photo as it is: AS_IS and KNOWN_STOREY)."""
        return self.transform in (AS_IS, KNOWN_STOREY)

    def instances(self) -> np.ndarray | None:
        """The instance map the run's session reads (use_masks and the view has masks), else None."""
        return self.view.instance_map() if self.use_masks else None

    @property
    def detections(self) -> str:
        """What detected the run's windows: "labelled masks", the detector's name, or "default"."""
        masks = self.use_masks and self.view.has_masks
        return "labelled masks" if masks else (self.detector or "default")


@dataclass(frozen=True)
class KfreeRun:
    """What one task's run gave, as the evaluators see it: rec, the pipeline.session.Reconstruction
    (None when the run raised: ``error``, "Type: message"); model, the pipeline.export.WrittenModel
    the export writes (export runs; else None); seconds, the run's wall time."""

    task: KfreeTask
    rec: object | None
    model: object | None
    error: str | None
    seconds: float


def run_task(task: KfreeTask) -> KfreeRun:
    """The task's run: the view's image under the transform, as a user's file of it reads
    (bench.photo_transforms.transformed), through ``fenestra reconstruct``'s session without K
    (pipeline.photo.photo_session, run_options); the written model when the run exports. An
    exception is recorded (``error``), not raised."""
    from fenestra.pipeline.photo import PhotoOptions, photo_session, run_options, written_model  # noqa: PLC0415 (fenestra.pipeline.photo loads IfcOpenShell, SciPy: imported when first used)

    storey = task.transform == KNOWN_STOREY
    opts = PhotoOptions(export=task.exports, **({"detector": task.detector} if task.detector else {}),
                        **({"known": Known(storey_m=task.known_storey_m)} if storey else {}))
    t0 = time.perf_counter()
    rec = model = error = None
    try:
        photo = transformed(task.view.image, AS_IS if storey else task.transform)
        rec = run_options(photo_session(photo.image, photo.exif, instances=task.instances()), opts)
        model = written_model(rec, opts.substitute) if task.exports else None
    except Exception as e:  # noqa: BLE001 - measured: a photo without an output is a figure
        error = f"{type(e).__name__}: {e}"
    return KfreeRun(task, rec, model, error, time.perf_counter() - t0)


# ---------------------------------------------------------------- the evaluators of a run (typed, pure)

def quad_box(quad) -> np.ndarray:
    """(4,) x0 y0 x1 y1 px: the bounding box of a (4, 2) quad."""
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    return np.array([*q.min(axis=0), *q.max(axis=0)])


def exported_boxes(rec) -> list[np.ndarray]:
    """The snapped quads' boxes (x0 y0 x1 y1 px) of the exported windows that have one."""
    return [quad_box(w.result.quad_snapped) for w in exported_windows(rec) if w.result.quad_snapped is not None]


def exported_matches(rec, label_boxes: list[np.ndarray], match_iou: float) -> tuple[int, int]:
    """(exported windows, those whose snapped quad's box has IoU >= match_iou with a label box)."""
    boxes = exported_boxes(rec)
    if not boxes:
        return 0, 0
    iou = box_iou_matrix(boxes, label_boxes)
    return len(boxes), int((iou.max(axis=1) >= match_iou).sum()) if label_boxes else 0


def labels_matched(rec, label_boxes: list[np.ndarray], match_iou: float) -> int:
    """Labelled windows (boxes x0 y0 x1 y1 px) whose box has IoU >= match_iou with an exported
    window's snapped-quad box (partial windows included): export recall's numerator."""
    boxes = exported_boxes(rec)
    if not boxes or not label_boxes:
        return 0
    return int((box_iou_matrix(boxes, label_boxes).max(axis=0) >= match_iou).sum())


def oversized(rec, limit_m: float = MAX_WINDOW_M) -> int:
    """Exported windows whose width or height (m, bench.evaluators.window_size_m; a partial
    window's visible extent) exceeds ``limit_m``."""
    return sum(any(x > limit_m for x in window_size_m(w.result)) for w in exported_windows(rec))


def taller_than(rec, storey_m: float) -> int:
    """Exported windows whose height (m) exceeds ``storey_m``."""
    return sum(window_size_m(w.result)[1] > storey_m for w in exported_windows(rec))


class RunEvaluator(Protocol):
    """One kind of figure of a K-free run (bench.evaluators.Evaluator's shape for a table of one row
    per run, not per labelled window): ``columns``, its schema; :meth:`process`, its columns of
    one run on the view (NaN or None where the run has no such figure)."""

    columns: tuple[str, ...]

    def process(self, view: LabelledView, run: KfreeRun) -> dict: ...


class FocalEvaluator:
    """The focal chain's answer (K_source, focal_px and its 90 % interval) and, with the view's
    calibration K, its relative error."""

    columns = ("K_source", "focal_px", "focal_lo_px", "focal_hi_px", "focal_true_px", "focal_err_rel")

    def process(self, view: LabelledView, run: KfreeRun) -> dict:
        chosen = None if run.rec is None else run.rec.resolved.chosen
        f, (lo, hi) = (NAN, (NAN, NAN)) if chosen is None else (chosen.focal_px, chosen.interval_px)
        f_true = float(view.K[0, 0]) if view.K is not None else NAN
        return {"K_source": None if chosen is None else chosen.source, "focal_px": float(f),
                "focal_lo_px": float(lo), "focal_hi_px": float(hi), "focal_true_px": f_true,
                "focal_err_rel": abs(f / f_true - 1) if f_true == f_true else NAN}


class DetectionCountEvaluator:
    """Labelled, detected and plausible windows (no failure, no flag of the façade model)."""

    columns = ("n_labelled", "n_detected", "n_plausible")

    def process(self, view: LabelledView, run: KfreeRun) -> dict:
        rec = run.rec
        wins = () if rec is None else rec.windows
        return {"n_labelled": len(view.windows), "n_detected": len(wins),
                "n_plausible": sum(w.result.failure is None and not rec.model.flags.get(w.index) for w in wins)}


class KfreeExportEvaluator:
    """What an export run exports against the labels (NaN for runs that do not export): exported
    windows and those matching a label box, labels matched, partial and oversized ones, and with a
    known storey those taller than it."""

    columns = ("n_exported", "n_exported_match", "n_labels_matched", "n_exported_partial", "n_exported_oversized",
               "known_storey_m", "n_taller_than_storey")

    def process(self, view: LabelledView, run: KfreeRun) -> dict:
        ks = run.task.known_storey_m
        out = {**dict.fromkeys(self.columns, NAN), "known_storey_m": float(ks)}
        if run.model is None:
            return out
        labels, iou = [w.bbox() for w in view.windows], run.task.match_iou
        out["n_exported"], out["n_exported_match"] = exported_matches(run.rec, labels, iou)
        out.update(n_labels_matched=labels_matched(run.rec, labels, iou),
                   n_exported_partial=sum(w.result.partial is not None for w in exported_windows(run.rec)),
                   n_exported_oversized=oversized(run.rec))
        if ks == ks:
            out["n_taller_than_storey"] = taller_than(run.rec, ks)
        return out


class KfreeModelEvaluator:
    """The written model (export runs): each model wall's tilt from the model's own vertical
    (WrittenModel.up) and each storey row's height spread (None for runs that do not export); the
    walls of the model and the walls fitted (NaN without a reconstruction)."""

    columns = ("wall_tilts_deg", "row_spreads", "n_walls", "n_walls_fitted")

    def process(self, view: LabelledView, run: KfreeRun) -> dict:
        rec, model = run.rec, run.model
        return {"wall_tilts_deg": None if model is None else list(wall_tilts_deg(rec, model.up).values()),
                "row_spreads": None if model is None else row_spreads(rec, model.rows()),
                "n_walls": NAN if rec is None else len(rec.model_wall_ids()),
                "n_walls_fitted": NAN if rec is None else len(rec.model.walls)}


def kfree_evaluators() -> list[RunEvaluator]:
    """The K-free block's evaluators, in kfree.parquet's column order."""
    return [FocalEvaluator(), DetectionCountEvaluator(), KfreeExportEvaluator(), KfreeModelEvaluator()]


def photo_row(run: KfreeRun, evaluators: list[RunEvaluator] | None = None) -> dict:
    """One row of kfree.parquet: the photo, the transform, whether the run gave a reconstruction
    (``output``), its error and seconds, every evaluator's columns, and what detected the windows."""
    view, task = run.task.view, run.task
    row = {"dataset": view.dataset, "photo": view.name, "transform": task.transform, "output": run.rec is not None,
           "error": run.error, "seconds": run.seconds}
    for e in kfree_evaluators() if evaluators is None else evaluators:
        row.update(e.process(view, run))
    return {**row, "detections": task.detections}


def kfree_tasks(spec: KfreeSpec, views: Iterable[LabelledView]) -> list[KfreeTask]:
    """The runs of spec over views, in table order: each view as is, then under spec.transforms
    for transform_datasets, then with the known storey (KNOWN_STOREY) for known_storey_datasets;
    at most spec.max_photos views per dataset (0: all)."""
    tasks: list[KfreeTask] = []
    taken: dict[str, int] = {}
    for v in views:
        if spec.max_photos and taken.get(v.dataset, 0) >= spec.max_photos:
            continue
        taken[v.dataset] = taken.get(v.dataset, 0) + 1
        kinds = (AS_IS, *spec.transforms) if v.dataset in spec.transform_datasets else (AS_IS,)
        kinds += (KNOWN_STOREY,) if v.dataset in spec.known_storey_datasets else ()
        tasks += [KfreeTask(v, t, spec.match_iou, spec.detector, v.dataset in spec.mask_datasets,
                            spec.known_storey_m if t == KNOWN_STOREY else NAN) for t in kinds]
    return tasks


def task_row(task: KfreeTask) -> dict:
    """The task's kfree.parquet row (:func:`run_task`, :func:`photo_row`)."""
    return photo_row(run_task(task))


def failed_row(task: KfreeTask, error: BaseException) -> dict:
    """The row of a task whose worker raised outside the run (or died)."""
    return photo_row(KfreeRun(task, None, None, f"{type(error).__name__}: {error}", NAN))


def _rows(tasks: list[KfreeTask], workers: int) -> Iterator[dict]:
    """Each task's row, in task order; ``workers`` > 1: in a spawned process pool (one BLAS/OpenMP
    /OpenCV thread per worker, as the bench's evaluation). A task that raises gives its
    :func:`failed_row`; the other rows are kept."""
    if workers <= 1 or len(tasks) <= 1:
        for t in tasks:
            try:
                yield task_row(t)
            except Exception as e:  # noqa: BLE001 - a failed run is a row
                yield failed_row(t, e)
        return
    from fenestra.bench.executors import worker_pool  # noqa: PLC0415 (fenestra.bench.executors loads SciPy, pandas, shapely: imported when first used)

    with worker_pool(min(workers, len(tasks))) as pool:
        futures = [pool.submit(task_row, t) for t in tasks]
        for t, f in zip(tasks, futures):
            try:
                yield f.result()
            except Exception as e:  # noqa: BLE001 - a raising (or dead) worker is a row, not the table
                yield failed_row(t, e)


def _progress_line(task: KfreeTask, r: dict) -> str:
    return (f"kfree {task.view.key} {task.transform}: f {r['focal_px']:.0f} px ({r['K_source']}), "
            f"walls {r['n_walls']}, exported {r['n_exported']}, {r['seconds']:.1f} s"
            + (f", {r['error']}" if r["error"] else ""))


def evaluate_kfree(spec: KfreeSpec, views: Iterable[LabelledView], progress: bool = False,
                   workers: int | None = None) -> pd.DataFrame:
    """kfree.parquet's table: each view as is, and under spec.transforms for transform_datasets,
    run in ``workers`` processes (None: all cores; capped by the number of runs); rows in view
    order whatever ``workers``, progress lines printed in that order."""
    workers = (os.cpu_count() or 1) if workers is None else workers
    rows = []
    tasks = kfree_tasks(spec, views)
    for t, r in zip(tasks, _rows(tasks, workers)):
        rows.append(r)
        if progress:
            print(_progress_line(t, r), flush=True)
    return pd.DataFrame(rows)


def run_kfree(spec: KfreeSpec, views: Iterable[LabelledView], run_dir: Path, progress: bool = False,
              workers: int | None = None) -> dict:
    """Evaluate (in ``workers`` processes, :func:`evaluate_kfree`), write run_dir/kfree.parquet,
    return the summary block (bench.kfree_summary.summarize_kfree)."""
    t0 = time.perf_counter()
    df = evaluate_kfree(spec, views, progress, workers)
    write_atomic(Path(run_dir) / KFREE_PARQUET, lambda p: df.to_parquet(p, index=False))
    return summarize_kfree(df, spec, time.perf_counter() - t0)
