"""Results tables and summary.json of a benchmark run.

A run folder holds ``results.parquet`` (one row per view x GT window x method combination, errors
with their unit in the column name; ``results.csv``, the same table, only when asked for:
``fenestra bench --csv``) and ``summary.json``::

    {"metadata": {commit, versions, seed, profile, config, config_hash, wall_time_s, stage_time_s, ...},
     "results": {method: {n_gt, n_evaluable, detection_rate, failure_rate,
                          corner_err_px_{mask,snap,reproj}: {median, p90, max, mean, n, n_valid,
                                                             fail_rate, recall: {"1": .., "2": ..}},
                          aspect_err_rel / rot_err_deg / normal_err_deg / trans_err_m / iou_2d: {...},
                          bim: {...}, export: {precision, n_exported, n_matched, n_on_ignore, n_on_nothing,
                                               n_on_door, n_views}}},
     "detection": {detector: {bbox_AP, bbox_AP50, segm_AP, segm_AP50, ...}}}

Statistics are over *evaluable* rows (see bench.evaluate.window_base). Medians/p90 are
over windows with an estimate; recall counts a missed or failed window as not recalled.
"""
from __future__ import annotations

import importlib.metadata
import json
import math
import platform
import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from fenestra.bench.metrics import error_stats, recall_at
from fenestra.errors import DatasetError, bounded
from fenestra.files import IMPORT_ROOT, file_sha256, write_atomic, write_text
from fenestra.pipeline.facade_model import MAX_WINDOW_M
from fenestra.tolerances import TOL
from fenestra.userfiles import read_json

RESULTS_PARQUET = "results.parquet"
RESULTS_CSV = "results.csv"
SUMMARY_JSON = "summary.json"

CORNER_STAGES = ("mask", "snap", "reproj")
STAGE_LABELS = {"mask": "mask-fit", "snap": "snapped", "reproj": "reprojected"}
CALIBRATION_COLUMNS = ("aspect_in90", "rot_in90", "trans_in90")  # bench.uncertainty
OTHER_ERRORS = ("aspect_err_rel", "rot_err_deg", "normal_err_deg", "trans_err_m", "iou_2d")
# summarised when present: fenestra/bench/real's; corner_err_px_head: the detector's corner head (its
# predicted corners, where it has one), beside the mask fit, for the same matched windows
OPTIONAL_ERRORS = ("reproj_consistency_px", "rel_size_err", "corner_err_px_head")
# what a BIM user gets (bench.evaluate.BIM_COLUMNS), summarised when present: the window at its
# wall's metric scale with nothing known (the assumed window height) and with the true storey height
METRIC_ERRORS = ("width_err_m", "height_err_m", "pos_err_m", "width_err_m_storey", "height_err_m_storey",
                 "pos_err_m_storey")
K_SOURCES = ("K", "exif", "vanishing points", "prior")  # pipeline.intrinsics: the focal chain's sources
# Where a table says which windows have the truth an error needs (the real bench: fenestra/bench/real),
# that error's statistics are over those windows only: absent truth is not a failure.
TRUTH_FLAGS = {**{f"corner_err_px_{s}": "has_quad" for s in CORNER_STAGES}, "iou_2d": "has_quad",
               "aspect_err_rel": "has_aspect", "rot_err_deg": "has_pose", "normal_err_deg": "has_pose",
               "trans_err_m": "has_pose", "rel_size_err": "has_size", "reproj_consistency_px": "known_K"}
REQUIRED_COLUMNS = ("method", "detector", "snapper", "pose", "evaluable", "status",
                    *(f"corner_err_px_{s}" for s in CORNER_STAGES), *OTHER_ERRORS)
# a results table's columns of names and ids (text even when they look like numbers: a view "000001")
TEXT_COLUMNS = ("profile", "house", "dataset", "renderer", "view", "window_id", "detector", "snapper",
                "pose", "method", "eval_reason", "aspect_case", "status", "reason", "K_source", "scale_source",
                "scale_source_storey")
SUMMARY_REQUIRED = tuple(c for c in REQUIRED_COLUMNS if c not in ("detector", "snapper", "pose"))  # what summarize reads
VERSIONED_PACKAGES = ("numpy", "scipy", "opencv-python-headless", "ifcopenshell", "trimesh",
                      "torch", "torchvision", "mitsuba", "pyrender", "shapely", "pandas",
                      "pycocotools", "pyoidn")


def check_table(df: pd.DataFrame, where: str = "results", required: tuple[str, ...] = REQUIRED_COLUMNS
                ) -> pd.DataFrame:
    """Raise ValueError naming the missing columns if ``df`` is not a results table (lacks one of
    ``required``)."""
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise ValueError(f"{where} lacks column(s) {missing}")
    return df


def write_results(df: pd.DataFrame, run_dir: str | Path, csv: bool = False) -> list[Path]:
    """Write results.parquet (the results table) into run_dir, and results.csv when ``csv``
    (a stale one is removed otherwise), each atomically; return the paths written. (A run
    streams its rows instead: :class:`RowSpool`.)"""
    check_table(df)
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    parquet, csv_path = run_dir / RESULTS_PARQUET, run_dir / RESULTS_CSV
    write_atomic(parquet, lambda p: df.to_parquet(p, index=False))
    if not csv:
        csv_path.unlink(missing_ok=True)
        return [parquet]
    write_atomic(csv_path, lambda p: df.to_csv(p, index=False))
    return [parquet, csv_path]


VIEWS_PER_SHARD = 16  # views whose rows go to one spool file (bounds the rows held in memory)
SPOOL_DIR = ".rows"  # a run folder's spool of view shards while the evaluation runs
SHARD_DIR = "shards"  # a run folder's Ray shards (bench.executors), kept for a resumed run


class RowSpool:
    """A run's rows streamed to Parquet by view shard as the views arrive, then written as the
    results table; what a run holds in memory is one shard's rows, not the table.

        spool = RowSpool(run_dir / SPOOL_DIR)
        for outcome in outcomes_in_canonical_order:
            spool.add(outcome.table())                     # every VIEWS_PER_SHARD views: one file
        spool.finish(run_dir, profile="default")            # results.parquet (+ results.csv), spool removed

    The results table is exactly the one ``pd.concat`` of every view's rows (then a first column
    ``profile``) gave: the same rows, columns, order and dtypes (each column's dtype is the common
    dtype of that column over every view, found from the shards' empty dtype samples, and every
    shard is cast to it), and the Parquet file is the same to the cell (its schema is inferred from
    the values, as ``DataFrame.to_parquet`` does, and unified over the shards). Shards are cut
    every ``views_per_shard`` views counted from the first, so they do not depend on the executor
    or on the number of workers. Every file is written atomically (fenestra.files.write_atomic).
    results.csv (on request) holds the same values; only an integer in a column whose views mix
    integers, floats and None (an object column) prints as ``1.0`` where its shard also held floats.
    owner: the run folder whose Fenestra manifest (fenestra.outputs) lists each shard as soon as it
    is written, so that a run killed before its end (kill -9) leaves no file a later run of the same
    folder must refuse as foreign.
    """

    def __init__(self, folder: str | Path, views_per_shard: int = VIEWS_PER_SHARD, owner: str | Path | None = None) -> None:
        if views_per_shard < 1:
            raise ValueError(f"views_per_shard must be >= 1, got {views_per_shard}")
        self.folder = Path(folder)
        self.views_per_shard = views_per_shard
        self.owner = None if owner is None else Path(owner)
        self.n_rows = 0
        self.n_views = 0
        self._frames: list[pd.DataFrame] = []
        self._shards: list[tuple[Path, pd.DataFrame]] = []  # (file, its empty dtype sample)
        if self.folder.exists():  # an interrupted run's spool
            shutil.rmtree(self.folder)
        self.folder.mkdir(parents=True)

    def add(self, frame: pd.DataFrame) -> None:
        """One view's rows (possibly none), in canonical view order."""
        self.n_views += 1
        if len(frame):
            self._frames.append(frame)
            self.n_rows += len(frame)
        if self.n_views % self.views_per_shard == 0:
            self._flush()

    def _flush(self) -> None:
        if not self._frames:
            return
        chunk = pd.concat(self._frames, ignore_index=True)
        self._frames = []
        path = self.folder / f"{len(self._shards):06d}.parquet"
        write_atomic(path, lambda p: chunk.to_parquet(p, index=False))
        if self.owner is not None:  # listed as it is written: a killed run's spool is Fenestra's, not a stranger's
            from fenestra import outputs  # noqa: PLC0415

            outputs.record(self.owner, [path.relative_to(self.owner).as_posix()])
        self._shards.append((path, chunk.iloc[:0].copy()))  # a copy: a slice would keep the rows alive

    def _template(self, profile: str) -> pd.DataFrame:
        """The results table's columns and dtypes, no rows."""
        t = pd.concat([sample for _, sample in self._shards], ignore_index=True)
        t.insert(0, "profile", profile)
        return t

    @staticmethod
    def _shard_table(path: Path, template: pd.DataFrame, profile: str) -> pd.DataFrame:
        """A shard's rows with the template's columns and dtypes (all, or those of a template
        with fewer columns)."""
        names = set(parquet_columns(path))
        df = pd.read_parquet(path, columns=[c for c in template.columns if c in names])
        if "profile" in template.columns:
            df.insert(0, "profile", profile)
        return df.reindex(columns=template.columns).astype(template.dtypes.to_dict())

    def _schema(self, template: pd.DataFrame, profile: str):
        """The Arrow schema ``to_parquet`` gives the whole table: each column's type as inferred
        from its dtype, or (object columns) from every shard's values, unified."""
        import pyarrow as pa  # noqa: PLC0415  (pyarrow: only where Parquet is written, not at import)

        objects = [c for c in template.columns if template[c].dtype == object]
        types = pa.Schema.from_pandas(template.drop(columns=objects), preserve_index=False)
        found = [pa.Schema.from_pandas(self._shard_table(p, template[objects], profile), preserve_index=False)
                 .remove_metadata() for p, _ in self._shards] if objects else []
        unified = pa.unify_schemas(found, promote_options="permissive") if found else pa.schema([])
        fields = [unified.field(c) if c in objects else types.field(c) for c in template.columns]
        return pa.Table.from_pandas(template, schema=pa.schema(fields), preserve_index=False).schema

    def finish(self, run_dir: str | Path, profile: str, csv: bool = False) -> list[Path]:
        """Write results.parquet (and results.csv with ``csv``; a stale one is removed otherwise)
        from the shards, shard by shard, each atomically; remove the spool; return the paths
        written. ValueError when no view had a row (nothing to write)."""
        self._flush()
        if not self._shards:
            raise ValueError("no view has a row: no results table to write")
        import pyarrow as pa  # noqa: PLC0415 (pyarrow: imported when first used, not at the package's import)
        import pyarrow.parquet as pq  # noqa: PLC0415 (pyarrow: imported when first used, not at the package's import)

        run_dir = Path(run_dir)
        template = self._template(profile)
        check_table(template)
        schema = self._schema(template, profile)

        def parquet(p: Path) -> None:
            with pq.ParquetWriter(p, schema) as w:
                for path, _ in self._shards:
                    w.write_table(pa.Table.from_pandas(self._shard_table(path, template, profile), schema=schema,
                                                       preserve_index=False))

        def text(p: Path) -> None:
            for i, (path, _) in enumerate(self._shards):
                self._shard_table(path, template, profile).to_csv(p, index=False, header=i == 0, mode="w" if i == 0 else "a")

        written = [write_atomic(run_dir / RESULTS_PARQUET, parquet)]
        if csv:
            written.append(write_atomic(run_dir / RESULTS_CSV, text))
        else:
            (run_dir / RESULTS_CSV).unlink(missing_ok=True)
        shutil.rmtree(self.folder, ignore_errors=True)
        return written


def parquet_columns(path: str | Path) -> list[str]:
    """The column names of a Parquet table (its schema; no rows read)."""
    import pyarrow.parquet as pq  # noqa: PLC0415 (pyarrow: imported when first used, not at the package's import)

    return list(pq.read_schema(path).names)


def load_results(run_dir: str | Path) -> pd.DataFrame:
    """The results table of a run folder (Parquet, else CSV)."""
    run_dir = Path(run_dir)
    if (run_dir / RESULTS_PARQUET).is_file():
        df = pd.read_parquet(run_dir / RESULTS_PARQUET)
    elif (run_dir / RESULTS_CSV).is_file():  # CSV has no types: names and ids stay text ("000001", not 1)
        df = pd.read_csv(run_dir / RESULTS_CSV, dtype=dict.fromkeys(TEXT_COLUMNS, str))
    else:
        raise FileNotFoundError(f"{run_dir} has no {RESULTS_PARQUET} or {RESULTS_CSV}: not a run folder")
    return check_table(df, str(run_dir))


def load_summary(run_dir: str | Path) -> dict:
    """summary.json of a run folder: a JSON object whose "metadata" (with the "profile" name) and
    "results" (method -> statistics) are objects; DatasetError naming the file and the field
    otherwise (a file that is not JSON, too large, or another command's summary)."""
    p = Path(run_dir) / SUMMARY_JSON
    if not p.is_file():
        raise FileNotFoundError(f"{run_dir} has no {SUMMARY_JSON}")
    doc = read_json(p, "run summary")
    if not isinstance(doc, dict):
        raise DatasetError(f"run summary {p} must be a JSON object with 'metadata' and 'results', got "
                           f"{type(doc).__name__}: not a benchmark run's summary")
    for key in ("metadata", "results"):
        if not isinstance(doc.get(key), dict):
            raise DatasetError(f"run summary {p}: '{key}' must be a JSON object, got {bounded(repr(doc.get(key)))}")
    if not isinstance(doc["metadata"].get("profile"), str):
        raise DatasetError(f"run summary {p}: metadata 'profile' must be a profile name, got "
                           f"{bounded(repr(doc['metadata'].get('profile')))}")
    bad = next((m for m, v in doc["results"].items() if not isinstance(v, dict)), None)
    if bad is not None or not isinstance(doc.get("detection", {}), dict):
        field = f"results[{bounded(repr(bad))}]" if bad is not None else "'detection'"
        raise DatasetError(f"run summary {p}: {field} must be a JSON object of statistics")
    return doc


def _stats_with_recall(errors: np.ndarray) -> dict:
    s = error_stats(errors)
    s["recall"] = {f"{k:g}": v for k, v in recall_at(errors, TOL.recall_thresholds_px).items()}
    return s


def summary_columns(columns) -> list[str]:
    """The columns of a results table (any iterable of names) that :func:`summarize` reads."""
    want = ("method", "evaluable", "status", *(f"corner_err_px_{s}" for s in CORNER_STAGES), *OTHER_ERRORS,
            *OPTIONAL_ERRORS, "focal_err_rel", *CALIBRATION_COLUMNS, *TRUTH_FLAGS.values(), *METRIC_ERRORS,
            "exported", "K_source", "scale_source", "scale_source_storey")
    return [c for c in dict.fromkeys(want) if c in set(columns)]


def _columns(df: pd.DataFrame) -> dict[str, np.ndarray]:
    """The summarised columns of a table as arrays: evaluable and truth flags as bool, status as
    two flags (``detected``: not "missed", ``failed``), errors as float64."""
    out = {}
    for c in summary_columns(df.columns):
        if c == "status":
            out["detected"] = (df[c] != "missed").to_numpy(bool)
            out["failed"] = (df[c] == "failed").to_numpy(bool)
        elif c == "evaluable" or c in TRUTH_FLAGS.values():
            out[c] = df[c].astype(bool).to_numpy()
        elif c == "K_source":  # one flag per source of the focal chain
            for s in K_SOURCES:
                out[f"K_source={s}"] = (df[c] == s).to_numpy(bool)
        elif c.startswith("scale_source"):
            out[f"{c}=assumed"] = (df[c] == "assumed").to_numpy(bool)
        elif c != "method":
            out[c] = df[c].to_numpy(float)
    return out


def _summarize_columns(cols: dict[str, np.ndarray], n_gt: int) -> dict:
    """summarize_method of one method's rows given as :func:`_columns` arrays (n_gt rows)."""
    ev = {c: v[cols["evaluable"]] for c, v in cols.items()}
    n = int(cols["evaluable"].sum())
    detected = int(ev["detected"].sum())
    failed = int(ev["failed"].sum())
    out: dict = {
        "n_gt": int(n_gt),
        "n_evaluable": n,
        "n_detected": detected,
        "detection_rate": detected / n if n else float("nan"),
        "failure_rate": failed / detected if detected else float("nan"),
    }
    for s in CORNER_STAGES:
        out[f"corner_err_px_{s}"] = _stats_with_recall(_with_truth(ev, f"corner_err_px_{s}"))
    for col in (*OTHER_ERRORS, *(c for c in OPTIONAL_ERRORS if c in cols)):
        out[col] = error_stats(_with_truth(ev, col))
    if "focal_err_rel" in ev:  # per-wall strategies with K withheld (bench.uncertainty)
        out["focal_err_rel"] = error_stats(ev["focal_err_rel"])
    out["calibration"] = _calibration(ev)
    if "exported" in ev:
        out["bim"] = _bim(ev)
    return out


def _bim(ev: dict[str, np.ndarray]) -> dict:
    """What a BIM user gets, over the evaluable windows the method reconstructed (status ok):
    ``n``; the share of them exported into the model; the share whose K came from each source of
    the focal chain; the share whose wall's scale was assumed (``assumed_rate``; ``_storey``: with
    the true storey height given, where the wall showed too few rows to use it); and the metric
    errors (m) with their statistics (METRIC_ERRORS)."""
    ok = ev["detected"] & ~ev["failed"]
    n = int(ok.sum())

    def rate(flag: np.ndarray) -> float:
        return float(flag[ok].mean()) if n else float("nan")

    out: dict = {"n": n, "exported_rate": float(np.nanmean(ev["exported"][ok])) if n else float("nan"),
                 "K_source": {s: rate(ev[f"K_source={s}"]) for s in K_SOURCES if f"K_source={s}" in ev}}
    for c in ("scale_source", "scale_source_storey"):
        if f"{c}=assumed" in ev:
            out["assumed_rate" + c.removeprefix("scale_source")] = rate(ev[f"{c}=assumed"])
    for c in METRIC_ERRORS:
        if c in ev:
            out[c] = error_stats(ev[c][ok])
    return out


def export_precision(outcomes: list) -> dict[str, dict]:
    """{method: its export precision over the views it ran on}: the bench.evaluate.EXPORT_COUNTS of
    every view's ``export_counts`` (bench.evaluate.ViewOutcome) summed, ``n_views``, and
    ``precision`` = n_matched / n_exported (the exported detections that are labelled windows; a
    detection on an ignore region, a glazed door or curtain-wall glazing, counts as a false export;
    NaN when nothing was exported). Not in the results table: the counts are per detection, and a
    detection on no labelled window has no row."""
    from fenestra.bench.evaluate import EXPORT_COUNTS  # noqa: PLC0415 (fenestra.bench.evaluate loads SciPy, shapely: imported when first used)

    out: dict[str, dict] = {}
    for o in outcomes:
        for m, c in o.export_counts.items():
            t = out.setdefault(m, {**dict.fromkeys(EXPORT_COUNTS, 0), "n_views": 0})
            for k in EXPORT_COUNTS:
                t[k] += int(c.get(k, 0))  # a view spooled before a count existed: none
            t["n_views"] += 1
    for t in out.values():
        t["precision"] = t["n_matched"] / t["n_exported"] if t["n_exported"] else float("nan")
    return {m: out[m] for m in sorted(out)}


def add_export_precision(results: dict[str, dict], outcomes: list) -> dict[str, dict]:
    """``results`` (:func:`summarize`'s) with each method's :func:`export_precision` as its
    ``export`` block (in place; returned)."""
    for m, block in export_precision(outcomes).items():
        if m in results:
            results[m]["export"] = block
    return results


def summarize_method(df: pd.DataFrame) -> dict:
    """Summary of one method's rows (any rows; only evaluable ones are counted)."""
    return _summarize_columns(_columns(df), len(df))


def calibration(ev: pd.DataFrame) -> dict:
    """Fraction of windows whose true error lies in their 90 % interval, per quantity (aspect, rot,
    trans; NaN where no window has intervals), and ``n`` windows with intervals."""
    return _calibration({c: ev[c].to_numpy(float) for c in CALIBRATION_COLUMNS if c in ev})


def _calibration(ev: dict[str, np.ndarray]) -> dict:
    cols = [c for c in CALIBRATION_COLUMNS if c in ev]
    out: dict = {"n": int((~np.isnan(ev[cols[0]])).sum()) if cols else 0}
    for c in CALIBRATION_COLUMNS:
        v = ev[c] if c in ev else np.array([])
        v = v[np.isfinite(v)]
        out[c.removesuffix("_in90")] = float(v.mean()) if v.size else float("nan")
    return out


def _with_truth(ev: dict[str, np.ndarray], col: str) -> np.ndarray:
    """Column ``col`` of the rows whose TRUTH_FLAGS flag is set (all rows without the flag column)."""
    flag = TRUTH_FLAGS.get(col)
    return ev[col] if flag is None or flag not in ev else ev[col][ev[flag]]


def summarize(df: pd.DataFrame) -> dict[str, dict]:
    """{method: summarize_method(rows)} for every method of a results table, sorted by name.

    Grouped once: the summarised columns as arrays, the rows ordered by method with one stable
    sort and each method's slice summarised (the same values, in the same order, as a per-method
    filter of the table gives, so the same statistics to the last bit)."""
    check_table(df, required=SUMMARY_REQUIRED)
    codes, names = pd.factorize(df["method"], sort=True)
    order = np.argsort(codes, kind="stable")
    bounds = np.searchsorted(codes[order], np.arange(len(names) + 1))
    cols = {c: v[order] for c, v in _columns(df).items()}
    return {str(m): _summarize_columns({c: v[bounds[i]:bounds[i + 1]] for c, v in cols.items()},
                                       int(bounds[i + 1] - bounds[i]))
            for i, m in enumerate(names)}


def _git_dirs(root: Path) -> tuple[Path, Path]:
    """(the checkout's git folder, its common folder): .git itself, or, in a worktree whose .git
    is a file ("gitdir: PATH"), that PATH and the folder its ``commondir`` names."""
    if root.is_file():
        root = Path(root.read_text().split(":", 1)[1].strip())
    common = root / "commondir"
    return root, ((root / common.read_text().strip()).resolve() if common.is_file() else root)


def _commit() -> str | None:
    """The commit of the source checkout fenestra runs from, read from its .git files (no git
    process; worktrees too); None when installed from a wheel."""
    try:
        git, common = _git_dirs(IMPORT_ROOT / ".git")
        head = (git / "HEAD").read_text().strip()
        if not head.startswith("ref:"):
            return head
        ref = head.split(" ", 1)[1]
        for d in (git, common):
            if (d / ref).is_file():
                return (d / ref).read_text().strip()
        packed = common / "packed-refs"
        for line in packed.read_text().splitlines() if packed.is_file() else []:
            if line.endswith(" " + ref):
                return line.split(" ", 1)[0]
    except (OSError, IndexError):
        return None
    return None


def versions() -> dict[str, str | None]:
    """Installed versions of the packages that affect results, plus Python's."""
    out: dict[str, str | None] = {"python": platform.python_version()}
    for pkg in VERSIONED_PACKAGES:
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def model_digests() -> dict[str, str]:
    """{file name: sha256} of the shipped weights (fenestra/pipeline/models/*.pt): which networks a
    run used, also where the tree differs from its commit."""
    from fenestra.pipeline.detectors import MODELS_DIR  # noqa: PLC0415 (cv2: only when a run is written)

    return {p.name: file_sha256(p) for p in sorted(MODELS_DIR.glob("*.pt"))}


def make_metadata(profile: dict, config_hash: str, seed: int, wall_time_s: float,
                  stage_time_s: dict[str, float], commit: str | None = None, models: dict | None = None,
                  **extra) -> dict:
    """The metadata block of summary.json. commit, models (:func:`model_digests`): the run's, read
    when it started (None: read now)."""
    return {"commit": _commit() if commit is None else commit,
            "models": model_digests() if models is None else models, "versions": versions(), "seed": seed,
            "profile": profile.get("name"), "config": profile, "config_hash": config_hash,
            "wall_time_s": wall_time_s, "stage_time_s": stage_time_s, **extra}


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_summary(run_dir: str | Path, metadata: dict, results: dict,
                  detection: dict | None = None, **blocks: dict) -> Path:
    """Write summary.json (NaN written as null); return its path. blocks: further top-level
    blocks (e.g. ``kfree``: bench.photo_eval)."""
    doc = {"metadata": metadata, "results": results, "detection": detection or {}, **blocks}
    return write_text(Path(run_dir) / SUMMARY_JSON, json.dumps(_jsonable(doc), indent=2))


def headline_table(results: dict) -> list[dict]:
    """One flat dict per method: the numbers the CLI prints and the report leads with."""
    rows = []
    for m, r in results.items():
        snap = r["corner_err_px_snap"]
        rows.append({
            "method": m, "n_evaluable": r["n_evaluable"], "detected": r["detection_rate"],
            "mask_med_px": r["corner_err_px_mask"]["median"],
            "head_med_px": r.get("corner_err_px_head", {}).get("median", float("nan")),
            "snap_med_px": snap["median"],
            "snap_p90_px": snap["p90"], "reproj_med_px": r["corner_err_px_reproj"]["median"],
            "recall_2px_snap": snap["recall"]["2"], "aspect_p90_rel": r["aspect_err_rel"]["p90"],
            "rot_med_deg": r["rot_err_deg"]["median"],
            "focal_med_rel": r.get("focal_err_rel", {}).get("median", float("nan")),
            "cover90_rot": r.get("calibration", {}).get("rot", float("nan")),
        })
    return rows


# ---------------------------------------------------------------- the K-free photo table (bench.photo_eval)

KFREE_PARQUET = "kfree.parquet"  # one row per photo per transform: dataset, photo, transform, focal_px, ...
AS_IS = "as_is"  # the transform name of the photo as given
# the "transform" of the photo as given, run with a known storey height (bench.photo_eval): not a
# transform of the image, so not in the focal spread
KNOWN_STOREY = "known_storey"


# the K-free block's targets: (summary key, comparison, value, words)
KFREE_TARGETS: tuple[tuple[str, str, float, str], ...] = (
    ("output_share", ">=", 1.0, "photos with an output"),
    ("export_precision", ">=", 0.95, "exported windows that are labelled windows"),
    ("export_recall", ">=", 0.8, "labelled windows exported (partial windows included)"),
    ("n_exported_oversized", "<=", 0, f"exported windows over {MAX_WINDOW_M:g} m wide or tall (no --known-*)"),
    ("focal_spread_observed_median", "<=", 0.03, "focal spread under the transforms, photos whose focal length the "
                                                 "vanishing points observed (median)"),
    ("walls_median", "<=", 2.0, "walls per photo (median)"),
    ("walls_stable_share", ">=", 0.8, "photos with the same wall count under every transform"),
    ("wall_tilt_median_deg", "<=", 2.0, "wall tilt from the model's vertical, deg (median over walls; "
                                        "self-consistency: that vertical is the walls' own)"),
    ("known_storey_taller", "<=", 0, "exported windows taller than the known storey (--known-storey)"),
    ("known_storey_row_spread_median", "<=", 0.05, "window height spread within a row, --known-storey "
                                                   "(median over rows)"),
    ("focal_err_median", "<=", 0.03, "focal error vs calibration, K withheld (median where observed)"),
)


def focal_spreads(df: pd.DataFrame) -> pd.DataFrame:
    """Per photo and transform: |f_t / f_as_is - 1| (rows of transforms with a focal length and an
    as-is focal length; not the KNOWN_STOREY runs); columns dataset, photo, transform, rel."""
    base = df[df["transform"] == AS_IS].set_index(["dataset", "photo"]).focal_px
    t = df[~df["transform"].isin((AS_IS, KNOWN_STOREY))].copy()
    t["rel"] = [abs(f / base.get((d, p), math.nan) - 1) for d, p, f in zip(t.dataset, t.photo, t.focal_px)]
    return t[["dataset", "photo", "transform", "rel"]].dropna(subset=["rel"])
