"""The K-free single-photo path measured on labelled photos (issue 24 item 7): what a user gets from
``fenestra reconstruct PHOTO`` with no intrinsics, judged against the photo's labels.

    from fenestra.bench.photo_eval import KfreeSpec, run_kfree
    block = run_kfree(KfreeSpec(...), views_by_dataset, run_dir)   # -> summary.json "kfree"

Each LabelledView's image is written losslessly (PNG) to a temporary file and run through
pipeline.photo.reconstruct_photo without K (exactly the CLI's path: a file, its EXIF read), once as
it is (with the model export, so ``exported`` is the exporter's own verdict) and once per transform
of issue 24 item 2 (no export: the focal length, detections and walls). A transform is a pure
function image -> Encoded (the bytes of a file and its suffix): :data:`TRANSFORMS`. The photos of
``known_storey_datasets`` run once more as they are, with the export and ``--known-storey``
``known_storey_m`` (transform KNOWN_STOREY).

Per photo and transform one row of ``kfree.parquet`` (:func:`photo_row`); the summary block
(:func:`summarize_kfree`) per dataset, with the issue's targets (bench.results.KFREE_TARGETS) beside:

- output: share of photos whose run returned a document and wrote windows.json;
- export precision: exported windows whose snapped quad's bounding box has IoU >= ``match_iou``
  with a labelled window box (bench.metrics.box_iou_matrix), over all exported windows (pooled);
- export recall: labelled windows whose box has IoU >= ``match_iou`` with an exported window's
  (partial windows, cut by the photo's border, included: they are exported too), over all
  labelled windows (pooled; :func:`labels_matched`);
- windows per labelled window: exported windows / labelled windows (pooled);
- oversized: exported windows wider or taller than facade_model.MAX_WINDOW_M (4 m, the limit the
  pipeline flags by when no ``--known-*`` says otherwise; windows.json ``width_m`` / ``height_m``,
  a partial window's its visible extent), counted on the runs without ``--known-*`` (:func:`oversized`);
- walls per photo (median; the walls of the model, those holding a window it exports:
  :func:`model_walls`; ``n_walls_fitted`` counts every fitted wall), and the share of photos with
  transforms whose wall count is the same under every transform as as is (:func:`walls_stable_share`);
- wall tilt: per wall of the model (a wall with an exported window) the angle in degrees between
  its plane and the vertical of the exported model (export.json ``world_frame``: the walls' agreeing
  up axes, i.e. their vertical vanishing directions, which also set the upright rotation;
  :func:`wall_tilts_deg`); the median over walls. A consistency figure, not an independent truth:
  a wall whose windows share one rotation, alone in its photo or agreeing with the others, scores 0
  by construction (a wall merged from fits up to facade_model.MERGE_DEG apart need not);
- with a known storey (KNOWN_STOREY runs): exported windows taller than the storey
  (:func:`taller_than`), and per row of windows (export.json ``storeys.rows``) the spread of the
  heights of its whole (not partial) exported windows, (max - min) / median, over rows of >= 2 such
  windows (:func:`row_spreads`); the median over rows;
- focal spread: per photo the largest |f_t / f_as_is - 1| over the transforms; the median over
  photos (and per transform the median of |f_t / f_as_is - 1|);
- focal error (views with a calibration K): |f / f_K - 1| of the untransformed photo, median over
  the photos whose focal length was observed (source not the stated prior); on those photos, the
  share whose 90 % interval holds the calibrated focal length (:func:`interval_coverage`).
"""
from __future__ import annotations

import io
import json
import math
import os
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from fenestra.bench.metrics import box_iou_matrix
from fenestra.bench.results import AS_IS, KFREE_PARQUET, KFREE_TARGETS, KNOWN_STOREY, focal_spreads
from fenestra.bench.views import LabelledView
from fenestra.files import write_atomic
from fenestra.pipeline.facade_model import MAX_WINDOW_M, Known
from fenestra.pipeline.photo import model_walls

CROP_PER_SIDE = 0.05  # 10 % of each dimension, centred (the principal point stays at the centre)
JPEG_QUALITY = 80  # the "re-saved JPEG" transform
EXIF_ORIENTATION_TAG = 0x0112
UNOBSERVED_SOURCES = ("prior",)  # focal sources that observe nothing of the photo



# ---------------------------------------------------------------- transforms (pure)

@dataclass(frozen=True)
class Encoded:
    """An image file's bytes and its suffix (".png", ".jpg")."""

    data: bytes
    suffix: str


def _pil(image: np.ndarray):
    from PIL import Image  # noqa: PLC0415

    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError(f"image must be (H, W, 3) uint8 RGB, got {img.shape} {img.dtype}")
    return Image.fromarray(img)


def _save(im, fmt: str, **kw) -> bytes:
    buf = io.BytesIO()
    im.save(buf, format=fmt, **kw)
    return buf.getvalue()


def png(image: np.ndarray) -> Encoded:
    """The image as it is (lossless PNG)."""
    return Encoded(_save(_pil(image), "PNG"), ".png")


def mirror_image(image: np.ndarray) -> np.ndarray:
    """Left-right mirror."""
    return np.ascontiguousarray(np.asarray(image)[:, ::-1])


def crop_image(image: np.ndarray, per_side: float = CROP_PER_SIDE) -> np.ndarray:
    """The centre of the image without ``per_side`` of each dimension on each side (round(W *
    per_side) columns left and right, round(H * per_side) rows top and bottom)."""
    if not 0 <= per_side < 0.5:
        raise ValueError(f"crop per side must be in [0, 0.5), got {per_side!r}")
    h, w = np.shape(image)[:2]
    dx, dy = round(w * per_side), round(h * per_side)
    return np.ascontiguousarray(np.asarray(image)[dy:h - dy, dx:w - dx])


def gray_image(image: np.ndarray) -> np.ndarray:
    """Grayscale (ITU-R 601 luma, as PIL's "L"), replicated to three channels."""
    return np.repeat(np.asarray(_pil(image).convert("L"))[..., None], 3, axis=2)


def jpeg(image: np.ndarray, quality: int = JPEG_QUALITY) -> Encoded:
    """The image re-saved as JPEG at ``quality``."""
    return Encoded(_save(_pil(image), "JPEG", quality=quality), ".jpg")


def exif_rotated(image: np.ndarray) -> Encoded:
    """The pixels turned 90 deg counter-clockwise and stored (lossless PNG) with EXIF orientation
    6, which tells a reader to turn them back: a reader that honours EXIF gets ``image``."""
    from PIL import Image  # noqa: PLC0415

    exif = Image.Exif()
    exif[EXIF_ORIENTATION_TAG] = 6
    return Encoded(_save(_pil(np.rot90(image, 1)), "PNG", exif=exif.tobytes()), ".png")


TRANSFORMS: dict[str, Callable[[np.ndarray], Encoded]] = {
    AS_IS: png,
    "gray": lambda im: png(gray_image(im)),
    "jpeg": jpeg,
    "exif_rot": exif_rotated,
    "mirror": lambda im: png(mirror_image(im)),
    "crop": lambda im: png(crop_image(im)),
}


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


# ---------------------------------------------------------------- one photo

def quad_box(quad) -> np.ndarray:
    """(4,) x0 y0 x1 y1 px: the bounding box of a (4, 2) quad."""
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    return np.array([*q.min(axis=0), *q.max(axis=0)])


def _exported(doc: dict) -> list[dict]:
    """The windows.json entries the export wrote (``exported`` true; partial windows among them)."""
    return [w for w in doc.get("windows") or [] if w.get("exported")]


def _exported_boxes(doc: dict) -> list[np.ndarray]:
    return [quad_box(w["quad_snapped"]) for w in _exported(doc) if w.get("quad_snapped")]


def exported_matches(doc: dict, label_boxes: list[np.ndarray], match_iou: float) -> tuple[int, int]:
    """(exported windows, those whose snapped quad's box has IoU >= match_iou with a label box)."""
    boxes = _exported_boxes(doc)
    if not boxes:
        return 0, 0
    iou = box_iou_matrix(boxes, label_boxes)
    return len(boxes), int((iou.max(axis=1) >= match_iou).sum()) if label_boxes else 0


def labels_matched(doc: dict, label_boxes: list[np.ndarray], match_iou: float) -> int:
    """Labelled windows (boxes x0 y0 x1 y1 px) whose box has IoU >= match_iou with an exported
    window's snapped-quad box (partial windows included): export recall's numerator."""
    boxes = _exported_boxes(doc)
    if not boxes or not label_boxes:
        return 0
    return int((box_iou_matrix(boxes, label_boxes).max(axis=0) >= match_iou).sum())


def _metres(v) -> float:
    return math.nan if v is None else float(v)


def oversized(doc: dict, limit_m: float = MAX_WINDOW_M) -> int:
    """Exported windows whose ``width_m`` or ``height_m`` (m, windows.json; a partial window's
    visible extent) exceeds ``limit_m``."""
    return sum(_metres(w.get("width_m")) > limit_m or _metres(w.get("height_m")) > limit_m for w in _exported(doc))


def taller_than(doc: dict, storey_m: float) -> int:
    """Exported windows whose ``height_m`` (m) exceeds ``storey_m``."""
    return sum(_metres(w.get("height_m")) > storey_m for w in _exported(doc))


def export_up(manifest: dict) -> np.ndarray:
    """The exported model's up direction (3,) in the camera frame: the z row of export.json's
    ``world_frame.camera_to_export`` (the walls' agreeing up axes, or the camera's -y when the
    export fell back to the camera-level frame)."""
    up = np.asarray(manifest["world_frame"]["camera_to_export"], dtype=np.float64)[2]
    return up / np.linalg.norm(up)


def wall_tilts_deg(doc: dict, up) -> list[float]:
    """Per wall of the model (windows.json ``walls`` with an exported window on it, by ``wall`` id)
    the angle in degrees between its plane and ``up`` (3,) camera frame: asin |normal . up|; 0 for
    a plumb wall."""
    up = np.asarray(up, dtype=np.float64).reshape(3)
    up = up / np.linalg.norm(up)
    on = {w.get("wall") for w in _exported(doc)}
    out = []
    for wall in doc.get("walls") or []:
        if wall["id"] in on:
            n = np.asarray(wall["normal"], dtype=np.float64)
            out.append(float(np.degrees(np.arcsin(min(1.0, abs(n @ up) / np.linalg.norm(n))))))
    return out


def row_spreads(doc: dict, manifest: dict) -> list[float]:
    """Per row of windows of the model (export.json ``storeys.rows``, their window indices) with at
    least two whole (not partial) exported windows: (max - min) / median of their ``height_m``
    (windows.json); dimensionless, 0 when they agree."""
    height = {w["index"]: _metres(w.get("height_m")) for w in _exported(doc) if not w.get("partial")}
    out = []
    for row in (manifest.get("storeys") or {}).get("rows") or []:
        h = np.array([height[i] for i in row["windows"] if i in height])
        h = h[np.isfinite(h)]
        if len(h) >= 2:
            out.append(float((h.max() - h.min()) / np.median(h)))
    return out


def photo_row(view: LabelledView, transform: str, doc: dict | None, error: str | None, seconds: float,
              match_iou: float, wrote: bool, manifest: dict | None = None, known_storey_m: float = math.nan) -> dict:
    """One row of kfree.parquet: the photo, the transform, what the run gave and what the labels say.
    manifest: the export's export.json (wall tilts and rows; None without one); known_storey_m: the
    run's --known-storey (m; NaN: none)."""
    nan = math.nan
    ks = (doc or {}).get("K_source") or {}
    f = ks.get("focal_px", nan)
    f_true = float(view.K[0, 0]) if view.K is not None else nan
    export = transform in (AS_IS, KNOWN_STOREY) and doc is not None
    labels = [w.bbox() for w in view.windows]
    n_exp, n_match = exported_matches(doc, labels, match_iou) if export else (nan, nan)
    mf = manifest if export else None
    wins = (doc or {}).get("windows") or []
    return {"dataset": view.dataset, "photo": view.name, "transform": transform, "output": bool(wrote),
            "error": error, "seconds": seconds, "K_source": ks.get("source"), "focal_px": float(f),
            "focal_lo_px": float((ks.get("interval_px") or [nan, nan])[0]),
            "focal_hi_px": float((ks.get("interval_px") or [nan, nan])[1]),
            "focal_true_px": f_true, "focal_err_rel": abs(f / f_true - 1) if f_true == f_true else nan,
            "n_labelled": len(view.windows), "n_detected": len(wins),
            "n_plausible": sum(bool(w.get("plausible")) for w in wins),
            "n_exported": n_exp, "n_exported_match": n_match,
            "n_labels_matched": labels_matched(doc, labels, match_iou) if export else nan,
            "n_exported_partial": sum(bool(w.get("partial")) for w in _exported(doc)) if export else nan,
            "n_exported_oversized": oversized(doc) if export else nan,
            "known_storey_m": float(known_storey_m),
            "n_taller_than_storey": taller_than(doc, known_storey_m) if export and known_storey_m == known_storey_m else nan,
            "wall_tilts_deg": None if mf is None else wall_tilts_deg(doc, export_up(mf)),
            "row_spreads": None if mf is None else row_spreads(doc, mf),
            "n_walls": model_walls(doc) if doc is not None else nan,
            "n_walls_fitted": len((doc or {}).get("walls") or []) if doc is not None else nan}



def write_masks(view: LabelledView, path: Path) -> Path | None:
    """The view's labelled masks as a 16-bit instance-map PNG (``--masks``); None without masks."""
    import cv2  # noqa: PLC0415

    inst = view.instance_map()
    if inst is None:
        return None
    if not cv2.imwrite(str(path), inst.astype(np.uint16)):
        raise OSError(f"could not write {path}")
    return path


def run_photo(view: LabelledView, transform: str, tmp: Path, match_iou: float, detector: str = "",
              use_masks: bool = False, known_storey_m: float = math.nan) -> dict:
    """Run reconstruct_photo (no K) on the view's image under ``transform``; its kfree.parquet row.
    The untransformed photo is exported (into ``tmp``; its export.json read for the row); an
    exception is recorded, not raised. use_masks: the view's labelled masks instead of the detector
    (untransformed only). Transform KNOWN_STOREY: the photo as it is with --known-storey
    ``known_storey_m`` (m)."""
    from fenestra.pipeline.photo import PhotoOptions, reconstruct_photo  # noqa: PLC0415

    untransformed = transform in (AS_IS, KNOWN_STOREY)
    if use_masks and not untransformed:
        raise ValueError(f"labelled masks are in the untransformed frame, not under {transform!r}")
    storey = transform == KNOWN_STOREY
    if storey and not known_storey_m > 0:
        raise ValueError(f"transform {KNOWN_STOREY!r} needs a known storey height, got {known_storey_m!r}")
    enc = TRANSFORMS[AS_IS if storey else transform](view.image)
    photo = tmp / f"{view.name}_{transform}{enc.suffix}"
    photo.write_bytes(enc.data)
    masks = write_masks(view, tmp / f"{view.name}_masks.png") if use_masks else None
    out = tmp / f"{view.name}_{transform}_out" if untransformed else None
    opts = PhotoOptions(export=out is not None, **({"detector": detector} if detector else {}),
                        **({"known": Known(storey_m=known_storey_m)} if storey else {}))
    t0 = time.perf_counter()
    doc, error = None, None
    try:
        doc = reconstruct_photo(photo, out, options=opts, masks=masks, force=True).to_json()
    except Exception as e:  # noqa: BLE001 - measured: a photo without an output is a figure
        error = f"{type(e).__name__}: {e}"
    seconds = time.perf_counter() - t0
    wrote = doc is not None and (out is None or (out / "windows.json").is_file())
    manifest = out / "export.json" if out is not None else None
    manifest = json.loads(manifest.read_text()) if manifest is not None and manifest.is_file() else None
    row = photo_row(view, transform, doc, error, seconds, match_iou, wrote, manifest,
                    known_storey_m if storey else math.nan)
    return {**row, "detections": "labelled masks" if masks is not None else (detector or "default")}


@dataclass(frozen=True)
class KfreeTask:
    """One run of :func:`run_photo` (a process-pool task: the view travels in memory); ``tmp`` is
    its own folder."""

    view: LabelledView
    transform: str
    tmp: str
    match_iou: float
    detector: str
    use_masks: bool
    known_storey_m: float = math.nan


def kfree_tasks(spec: KfreeSpec, views: Iterable[LabelledView], tmp: Path) -> list[KfreeTask]:
    """The runs of spec over views, in table order: each view as is, then under spec.transforms
    for transform_datasets, then with the known storey (KNOWN_STOREY) for known_storey_datasets;
    at most spec.max_photos views per dataset (0: all). Each task's folder is a numbered subfolder
    of ``tmp`` (created)."""
    tasks: list[KfreeTask] = []
    taken: dict[str, int] = {}
    for v in views:
        if spec.max_photos and taken.get(v.dataset, 0) >= spec.max_photos:
            continue
        taken[v.dataset] = taken.get(v.dataset, 0) + 1
        kinds = (AS_IS, *spec.transforms) if v.dataset in spec.transform_datasets else (AS_IS,)
        kinds += (KNOWN_STOREY,) if v.dataset in spec.known_storey_datasets else ()
        for t in kinds:
            d = Path(tmp) / str(len(tasks))
            d.mkdir()
            tasks.append(KfreeTask(v, t, str(d), spec.match_iou, spec.detector, v.dataset in spec.mask_datasets,
                                   spec.known_storey_m if t == KNOWN_STOREY else math.nan))
    return tasks


def run_task(task: KfreeTask) -> dict:
    """The task's kfree.parquet row (:func:`run_photo`)."""
    return run_photo(task.view, task.transform, Path(task.tmp), task.match_iou, task.detector, task.use_masks,
                     task.known_storey_m)


def failed_row(task: KfreeTask, error: BaseException) -> dict:
    """The row of a task whose run raised outside reconstruct_photo (or whose worker died)."""
    row = photo_row(task.view, task.transform, None, f"{type(error).__name__}: {error}", math.nan,
                    task.match_iou, False, known_storey_m=task.known_storey_m)
    return {**row, "detections": "labelled masks" if task.use_masks else (task.detector or "default")}


def _rows(tasks: list[KfreeTask], workers: int) -> Iterator[dict]:
    """Each task's row, in task order; ``workers`` > 1: in a spawned process pool (one BLAS/OpenMP
    /OpenCV thread per worker, as the bench's evaluation). A task that raises gives its
    :func:`failed_row`; the other rows are kept."""
    if workers <= 1 or len(tasks) <= 1:
        for t in tasks:
            try:
                yield run_task(t)
            except Exception as e:  # noqa: BLE001 - a failed run is a row
                yield failed_row(t, e)
        return
    from fenestra.bench.executors import worker_pool  # noqa: PLC0415

    with worker_pool(min(workers, len(tasks))) as pool:
        futures = [pool.submit(run_task, t) for t in tasks]
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
    with tempfile.TemporaryDirectory(prefix="fenestra-kfree-") as d:
        tasks = kfree_tasks(spec, views, Path(d))
        for t, r in zip(tasks, _rows(tasks, workers)):
            rows.append(r)
            if progress:
                print(_progress_line(t, r), flush=True)
    return pd.DataFrame(rows)


# ---------------------------------------------------------------- summary

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


def run_kfree(spec: KfreeSpec, views: Iterable[LabelledView], run_dir: Path, progress: bool = False,
              workers: int | None = None) -> dict:
    """Evaluate (in ``workers`` processes, :func:`evaluate_kfree`), write run_dir/kfree.parquet,
    return the summary block."""
    t0 = time.perf_counter()
    df = evaluate_kfree(spec, views, progress, workers)
    write_atomic(Path(run_dir) / KFREE_PARQUET, lambda p: df.to_parquet(p, index=False))
    return summarize_kfree(df, spec, time.perf_counter() - t0)


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
