"""A run's manifest: the rows its results table must hold, and the table's checksum.

``fenestra bench`` writes ``manifest.json`` beside ``results.parquet``::

    {"format": 2, "profile": "smoke", "profile_hash": "1a2b3c4d", "n_rows": 2880,
     "keys": ["house", "view", "window_id", "method"],
     "methods": ["oracle/none/lm", ...],
     "views": [["fzk-haus", "000000", ["w-17", "w-18", ...]], ...],
     "sha256": {"results.parquet": "..."}}

The expected rows come from the rendered views (every ground-truth window of every ``view.json``)
times the planned methods, not from the evaluation's output: a view or method the evaluation
dropped is missing from the table but not from the manifest. They are stored compactly, as each
view's window ids and the methods (every row is a window x method); a set of rows that is not
such a product (a table sealed as it is) is stored row by row, ``"rows": [[house, view,
window_id, method], ...]`` (format 1's only form, still read). ``sha256`` holds the digest of
each results file the run wrote (results.parquet; results.csv only when asked for). :func:`load_verified_results` is
what ``fenestra gate`` and ``fenestra report`` read: it refuses a table that lacks or adds rows
(naming them, grouped by method), or whose bytes changed after the run (edited values).

A run folder is also claimed by its profile (:func:`claim_run_dir`, under a lock: :func:`claimed`):
``run.json`` records the profile name and hash and the run's status; a folder holding another
profile's run is refused unless ``force`` (then exactly the files Fenestra listed there are
removed, fenestra.outputs' rule), a folder holding files Fenestra did not write is refused
whatever ``force`` says, and no stale report or figure survives beside new results.
"""
from __future__ import annotations

import contextlib
import json
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd

from fenestra.bench.results import RESULTS_CSV, RESULTS_PARQUET, SHARD_DIR, SPOOL_DIR, load_results
from fenestra import outputs
from fenestra.errors import FenestraError, one_line
from fenestra.files import file_sha256, write_json

MANIFEST_JSON = "manifest.json"
RUN_JSON = "run.json"
KEY_COLUMNS = ("house", "view", "window_id", "method")
FORMAT = 2
MAX_NAMED = 5  # how many missing/extra rows an error message names


class RunIntegrityError(FenestraError):
    """A run folder whose results table does not match its manifest, or a foreign run folder."""


def expected_rows(views: list[tuple[str, Path]], methods: list[str]) -> dict:
    """The expected rows, every GT window of each (house, view folder) x method, in the manifest's
    compact form (:func:`compact_rows`): {"methods": [...], "views": [[house, view, [window ids]], ...]}."""
    out = []
    for house, vdir in views:
        meta = json.loads((Path(vdir) / "view.json").read_text())
        out.append([house, Path(vdir).name, [str(w["id"]) for w in meta["windows"]]])
    return {"methods": list(methods), "views": out}


def n_expected(doc: dict) -> int:
    """How many rows a manifest's expected rows (either form of :func:`compact_rows`) are."""
    if "rows" in doc:
        return len(doc["rows"])
    return len(doc["methods"]) * sum(len(ws) for _, _, ws in doc["views"])


def expected_frame(doc: dict) -> pd.DataFrame:
    """The expected rows of a manifest (either form of :func:`compact_rows`) as a table with the
    KEY_COLUMNS (categoricals for the compact form), in :func:`expand_rows` order, built with
    array operations."""
    if "rows" in doc:
        return pd.DataFrame([list(r) for r in doc["rows"]], columns=list(KEY_COLUMNS), dtype="str")
    windows = [(h, v, w) for h, v, ws in doc["views"] for w in ws]
    n_methods = len(doc["methods"])
    cols = {c: np.repeat(pd.Categorical([str(w[i]) for w in windows]), n_methods)
            for i, c in enumerate(KEY_COLUMNS[:3])}
    method = pd.Categorical([str(m) for m in doc["methods"]])
    cols["method"] = pd.Categorical.from_codes(np.tile(method.codes, len(windows)), method.categories)
    return pd.DataFrame(cols)


def _key_digests(keys: pd.DataFrame) -> np.ndarray:
    """Sorted 64-bit hashes of the rows of a KEY_COLUMNS table, each value as a string: two tables
    hold the same rows, as multisets, when these arrays are equal (up to a 2**-64 collision)."""
    keys = pd.DataFrame({c: keys[c] if isinstance(keys[c].dtype, pd.CategoricalDtype) else keys[c].astype("str")
                         for c in KEY_COLUMNS})
    return np.sort(pd.util.hash_pandas_object(keys, index=False).to_numpy())


def table_rows(df: pd.DataFrame) -> list[tuple[str, str, str, str]]:
    """The KEY_COLUMNS of every row of a results table, as strings."""
    missing = [c for c in KEY_COLUMNS if c not in df.columns]
    if missing:
        raise RunIntegrityError(f"results table lacks key column(s) {missing}")
    return [tuple(map(str, r)) for r in df[list(KEY_COLUMNS)].itertuples(index=False)]


def compact_rows(rows: list[tuple]) -> dict:
    """The manifest's form of expected rows (house, view, window_id, method): {"methods": [...],
    "views": [[house, view, [window ids]], ...]} when they are every window of those views x
    every method, once each, in that order; else {"rows": [[house, view, window_id, method], ...]}."""
    if not rows:
        return {"methods": [], "views": []}
    methods = list(dict.fromkeys(r[3] for r in rows))
    views: dict[tuple[str, str], list[str]] = {}
    for h, v, w, m in rows:
        if m == methods[0]:
            views.setdefault((h, v), []).append(w)
    compact = {"methods": methods, "views": [[h, v, ws] for (h, v), ws in views.items()]}
    if expand_rows(compact) == [tuple(r) for r in rows]:
        return compact
    return {"rows": [list(r) for r in rows]}


def expand_rows(doc: dict) -> list[tuple[str, str, str, str]]:
    """The expected rows of a manifest (either form of :func:`compact_rows`), in order."""
    if "rows" in doc:
        return [tuple(r) for r in doc["rows"]]
    return [(h, v, w, m) for h, v, ws in doc["views"] for w in ws for m in doc["methods"]]


def write_manifest(run_dir: str | Path, rows: list[tuple] | dict, profile: str, profile_hash: str) -> Path:
    """manifest.json of a run whose results tables are already written (their checksums go in).
    rows: the expected rows, (house, view, window_id, method) tuples or already in compact form
    (:func:`expected_rows`, :func:`compact_rows`)."""
    run_dir = Path(run_dir)
    sums = {name: file_sha256(run_dir / name) for name in (RESULTS_PARQUET, RESULTS_CSV)
            if (run_dir / name).is_file()}
    expected = rows if isinstance(rows, dict) else compact_rows(rows)
    doc = {"format": FORMAT, "profile": profile, "profile_hash": profile_hash, "n_rows": n_expected(expected),
           "keys": list(KEY_COLUMNS), **expected, "sha256": sums}
    return write_json(run_dir / MANIFEST_JSON, doc, indent=None)


def seal(run_dir: str | Path, df: pd.DataFrame, profile: str, profile_hash: str = "") -> Path:
    """Write the manifest of a table built outside run_benchmark (expected rows = the table's)."""
    return write_manifest(run_dir, table_rows(df), profile, profile_hash)


def load_manifest(run_dir: str | Path, expand: bool = True) -> dict:
    """manifest.json of a run folder, its expected rows as tuples under "rows" (``expand``; else
    as stored: see :func:`compact_rows`); RunIntegrityError if absent or unreadable."""
    p = Path(run_dir) / MANIFEST_JSON
    if not p.is_file():
        raise RunIntegrityError(f"{run_dir} has no {MANIFEST_JSON}: not a complete benchmark run "
                                "(re-run `fenestra bench`)")
    try:
        doc = json.loads(p.read_text())
        return doc | {"rows": expand_rows(doc)} if expand else doc | {"n_rows": n_expected(doc)}
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise RunIntegrityError(f"{p}: unreadable manifest ({e})") from e


def describe_rows(rows: Counter, what: str, total: int) -> str:
    """'lacks 96 of 480 expected rows (method a/b/c: 96, ...; e.g. house/view/window/method, ...)'."""
    n = sum(rows.values())
    per_method = Counter(r[3] for r in rows.elements())
    methods = ", ".join(f"{m}: {k}" for m, k in per_method.most_common(MAX_NAMED))
    examples = ", ".join("/".join(r) for r in list(rows)[:MAX_NAMED])
    return f"{what} {n} of {total} expected rows (by method {methods}; e.g. {examples})"


def verify_table(run_dir: str | Path, df: pd.DataFrame, manifest: dict) -> None:
    """RunIntegrityError naming missing/extra rows, or a table whose bytes changed since the run.
    manifest: :func:`load_manifest`'s, either form. The rows are compared as sorted hashes first
    (array operations); only a table that differs is compared row by row, to name the rows."""
    missing_keys = [c for c in KEY_COLUMNS if c not in df.columns]
    if missing_keys:
        raise RunIntegrityError(f"results table lacks key column(s) {missing_keys}")
    if not np.array_equal(_key_digests(expected_frame(manifest)), _key_digests(df)):
        _name_row_differences(run_dir, df, manifest)
    _verify_digests(run_dir, manifest)


def _name_row_differences(run_dir: str | Path, df: pd.DataFrame, manifest: dict) -> None:
    """RunIntegrityError naming the rows the table lacks or adds against the manifest (none: the
    rows match after all, and nothing is raised)."""
    expected, got = Counter(expand_rows(manifest)), Counter(table_rows(df))
    missing, extra = expected - got, got - expected
    problems = []
    if missing:
        problems.append(describe_rows(missing, "lacks", manifest["n_rows"]))
    if extra:
        problems.append(describe_rows(extra, "has unexpected", manifest["n_rows"]))
    if problems:
        raise RunIntegrityError(f"{run_dir}: results table " + "; ".join(problems))


def _verify_digests(run_dir: str | Path, manifest: dict) -> None:
    """RunIntegrityError if a results file's bytes changed since the run (its sha256)."""
    run_dir = Path(run_dir)
    for name, digest in manifest.get("sha256", {}).items():
        p = run_dir / name
        if p.is_file() and file_sha256(p) != digest:
            raise RunIntegrityError(f"{p} was modified after the run (sha256 differs from {MANIFEST_JSON}); "
                                    "re-run `fenestra bench`")


def load_verified_results(run_dir: str | Path) -> pd.DataFrame:
    """The results table of a run folder, checked against its manifest (see the module doc)."""
    df = load_results(run_dir)
    manifest = load_manifest(run_dir, expand=False)
    verify_table(run_dir, df, manifest)
    return df


STALE = (MANIFEST_JSON, "report.html", "report.md", "figures", SPOOL_DIR)  # an earlier run's outputs
COMPARE_PREFIX = "compare-"  # a comparison page written into the run (fenestra compare): stale too
KIND = "bench"  # the kind of output a run folder is (fenestra.outputs.KINDS)


def adopt_shards(run_dir: Path) -> list[str]:
    """List in ``run_dir``'s manifest the Ray shards a killed run wrote but did not list
    (bench.executors.recognised_shards: recognised by name and digest); returns them."""
    if not (run_dir / SHARD_DIR).is_dir():
        return []
    from fenestra.bench.executors import recognised_shards  # noqa: PLC0415 (fenestra.bench.executors loads SciPy, pandas, shapely: imported when first used)

    owned = outputs.read_manifest(run_dir) or {}
    found = [f for f in recognised_shards(run_dir, listed=owned) if f not in owned]
    if found:
        outputs.record(run_dir, found)
    return found


def claim_run_dir(run_dir: str | Path, profile: str, profile_hash: str, force: bool = False,
                  inputs: tuple = ()) -> Path:
    """Make ``run_dir`` this profile's run folder (see the module doc); returns it.

    File ownership is fenestra.outputs' rule: a folder that holds or lies inside one of
    ``inputs`` (the datasets, the render cache, profiles, --sim/--real runs) is refused; so is a
    folder holding any file that Fenestra's manifest there does not list with its digest
    (``force`` or not: a user's file is never deleted). A folder holding this profile's run (same
    name and hash) is reused, its earlier outputs (STALE) removed; another profile's run needs
    ``force``, and then exactly the files Fenestra listed are removed, never the folder.
    """
    run_dir = Path(run_dir)
    if run_dir.exists() and not run_dir.is_dir():
        raise RunIntegrityError(f"--out {run_dir} is a file, not a folder")
    outputs.check_out(run_dir, inputs, force=True, kind=KIND)  # a file, a folder overlapping an input or of another kind
    if run_dir.is_dir() and outputs.read_manifest(run_dir) is not None:  # a run Fenestra wrote, killed:
        outputs.remove_dead_temp_files(run_dir)  # its half-written files go,
        adopt_shards(run_dir)  # its unlisted shards are recognised
    owned = outputs.read_manifest(run_dir) if run_dir.is_dir() else None
    foreign = outputs.foreign_files(run_dir, owned or {})
    if foreign:
        named = ", ".join(foreign[:MAX_NAMED]) + (", ..." if len(foreign) > MAX_NAMED else "")
        if owned is None:
            raise RunIntegrityError(f"{run_dir} is not empty and holds no benchmark run Fenestra listed ({named}); "
                                    "choose another --out (--force replaces only a run Fenestra wrote)")
        raise RunIntegrityError(f"{run_dir} holds files that Fenestra did not write or that changed since ({named}); "
                                "move them away or choose another --out (--force never deletes them)")
    if owned:
        owner = _read_run_json(run_dir)
        if owner is None or (owner.get("profile"), owner.get("profile_hash")) != (profile, profile_hash):
            if not force:
                raise RunIntegrityError(f"{run_dir} holds a run of profile {(owner or {}).get('profile')!r} (hash "
                                        f"{(owner or {}).get('profile_hash')}), not {profile!r} (hash {profile_hash}); "
                                        "choose another --out or pass --force to replace it")
            outputs.remove_owned(run_dir)  # exactly the files listed, each with its digest
    run_dir.mkdir(parents=True, exist_ok=True)
    outputs.remove_owned(run_dir, [*STALE, *(f for f in owned or {} if f.startswith(COMPARE_PREFIX))])
    write_json(run_dir / RUN_JSON, {"profile": profile, "profile_hash": profile_hash, "status": "running"})
    outputs.record(run_dir, [RUN_JSON], kind=KIND)
    return run_dir


@contextlib.contextmanager
def run_status(run_dir: str | Path):
    """Mark the claimed run folder's run.json ``complete`` when the block ends, or ``failed`` with
    the error's one line when it raises (a SIGTERM or Ctrl-C too): a run that did not finish is
    never mistaken for one that did (its folder says so, and ``fenestra gate`` refuses it). Either
    way every file in the folder is then listed, with its digest, in Fenestra's manifest
    (fenestra.outputs), so a later run may replace them."""
    path = Path(run_dir) / RUN_JSON
    doc = json.loads(path.read_text())
    try:
        yield
    except BaseException as e:
        write_json(path, {**doc, "status": "failed", "error": f"{type(e).__name__}: {one_line(e)}"})
        outputs.record(run_dir)
        raise
    write_json(path, {**doc, "status": "complete"})
    outputs.record(run_dir)


@contextlib.contextmanager
def claimed(run_dir: str | Path, profile: str, profile_hash: str, force: bool = False, inputs: tuple = ()):
    """The run folder for one run: refused at once when another process is running into it
    (fenestra.outputs.locked), claimed (:func:`claim_run_dir`) and marked by :func:`run_status`.
    A folder this call made is removed again (rmdir) when the claim is refused."""
    run_dir = Path(run_dir)
    outputs.check_out(run_dir, inputs, force=True, kind=KIND)  # another kind: refused before the lock file is made
    created = not run_dir.exists()
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        if not created and outputs.read_manifest(run_dir) is None and outputs.files_in(run_dir):
            claim_run_dir(run_dir, profile, profile_hash, force, inputs)  # refuses: no lock file left there
        with outputs.locked(run_dir, "benchmark run"):
            claim_run_dir(run_dir, profile, profile_hash, force, inputs)
            with outputs.listing(run_dir), run_status(run_dir):  # every file listed as it is written
                yield run_dir
    except BaseException:
        if created and not outputs.files_in(run_dir):
            (run_dir / outputs.LOCK).unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                run_dir.rmdir()
        raise


def require_complete(run_dir: str | Path) -> None:
    """RunIntegrityError unless the run folder's run.json says ``complete`` (a run that failed,
    was interrupted, or is still running is never gated). A folder without run.json (a table
    sealed outside ``fenestra bench``, :func:`seal`) passes, unless Fenestra's manifest there
    (fenestra.outputs) lists run.json: then its absence is a failure, never a pass."""
    p = Path(run_dir) / RUN_JSON
    if not p.is_file():
        if RUN_JSON in (outputs.read_manifest(run_dir) or {}):
            raise RunIntegrityError(f"{p} is missing, but {Path(run_dir) / outputs.MANIFEST} lists it: the run "
                                    "folder is incomplete; re-run `fenestra bench`")
        return
    try:
        doc = json.loads(p.read_bytes())
        status = doc.get("status") if isinstance(doc, dict) else None
    except (OSError, ValueError) as e:
        raise RunIntegrityError(f"{p} is unreadable ({type(e).__name__}); re-run `fenestra bench`") from e
    if status != "complete":
        why = f": {doc.get('error')}" if isinstance(doc, dict) and doc.get("error") else ""
        raise RunIntegrityError(f"{p} says status {status!r}{why}, not 'complete': the run did not finish; "
                                "re-run `fenestra bench`")


def _read_run_json(run_dir: Path) -> dict | None:
    """{"profile", "profile_hash"} of the run in run_dir (run.json, else an older run's summary.json)."""
    for name, keys in ((RUN_JSON, ("profile", "profile_hash")), ("summary.json", ("profile", "config_hash"))):
        try:
            doc = json.loads((run_dir / name).read_text())
        except (OSError, ValueError):
            continue
        doc = doc.get("metadata", doc) if isinstance(doc, dict) else None
        if isinstance(doc, dict) and keys[0] in doc:
            return {"profile": doc.get(keys[0]), "profile_hash": doc.get(keys[1])}
    return None
