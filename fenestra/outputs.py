"""Which files Fenestra may delete or replace: one rule for every command that writes
(``fenestra reconstruct --out``, its batch mode, ``fenestra bench --out``, report, compare's
page, calibrate, ``scenes make`` and ``scenes author``).

    check_out(out, inputs, force=False, kind=K)  # before any work: refuse a bad --out
    with staged(out, inputs, force, kind=K) as tmp:  # write everything into tmp (a hidden child of out)
        ...
    # the new files are moved into out first, then the previous run's files that are not replaced
    # are removed: a failure at any point before leaves the previous result whole
    check_file(path, kind, hosts, inputs)        # before the work that makes one file
    write_file(path, write, kind, hosts, inputs) # one file, replacing only an owned one
    write_file(..., force=True, own=Recognised(...))  # also one of this writer's kind no manifest lists
    write_owned(out, "summary.json", data)       # the same, from bytes
    record(out, ["results.parquet", ...])        # add files written in place to the manifest
    remove_owned(out)                            # delete what the manifest lists, refuse the rest
    with locked(out, "benchmark run"): ...       # one writer at a time

The rule. Every output folder holds ``MANIFEST`` (.fenestra-output.json), ``{"format": 2,
"kind": KIND, "files": {relative path: sha256}}``: what kind of output the folder holds (KINDS)
and the files Fenestra wrote there with their digests.

- A command writes only into a folder of its own kind (``check_kind``; a report or comparison
  page also into the bench run it describes), ``--force`` or not: a reconstruction never
  replaces a bench run, a batch never replaces a run's summary.json. A manifest without a kind
  (an older Fenestra) has the kind of the files it lists (run.json, windows.json, summary.json).

- Fenestra deletes or replaces a file only when the manifest lists it and its bytes still have
  the listed digest. A file it did not write, or one edited since, is refused with its name:
  never overwritten, never deleted, ``--force`` or not.
- ``--force`` of a single-file writer (``own``: :class:`Recognised`) also replaces a file of
  that writer's own kind that no manifest lists, recognised by its content (a weights file, a
  generated doc committed without its folder's manifest), never any other file.
- A folder that contains, or lies inside, an input (a photo, ``--data``, ``--K``, ``--masks``, a
  profile) is refused, ``--force`` or not.
- ``rmtree`` is used only on the hidden staging folder this module made (``.fenestra-stage-*``);
  emptied folders are removed with ``rmdir`` only.

What the digests protect against: accidents (a file the user put or edited in an output
folder, a name clash, a file from a run that was killed before it listed it) and partial writes.
They do not protect against a writer who changes a file and rewrites its digest too: the
manifest is not signed.

Errors are :class:`OwnershipError` (a FenestraError): one line naming the folder and the file.
"""
from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from fenestra.errors import FenestraError, bounded
from fenestra.files import before_rename, file_sha256, TEMP_NAME, write_atomic, write_json

MANIFEST = ".fenestra-output.json"
STAGE_PREFIX = ".fenestra-stage-"
LOCK = ".fenestra.lock"
FORMAT = 2
MAX_NAMED = 5
NOT_LISTED = (MANIFEST, LOCK)  # bookkeeping of this module: never a result, never "foreign"
KINDS = {  # what an output folder holds -> how an error names it
    "bench": "a benchmark run",
    "reconstruction": "one photo's reconstruction",
    "batch": "a batch of reconstructions",
    "files": "files Fenestra wrote one by one (a comparison page, K.json, IFC houses)",
    "dataset": "a rendered dataset",
}
FILES_KIND = "files"
LEGACY_KIND = (("run.json", "bench"), ("windows.json", "reconstruction"), ("summary.json", "batch"))


class OwnershipError(FenestraError):
    """A folder or file Fenestra may not write (an input, a file it did not write); names it."""


@dataclass(frozen=True)
class Recognised:
    """A single-file writer's own kind of file, recognised by its content where no manifest lists
    it: what ``--force`` may replace (:func:`check_file`). words: how an error names such a file
    ("a weights file"); test(path) -> True for one (never raises)."""

    words: str
    test: Callable[[Path], bool]


def json_with(keys: Iterable[str], max_bytes: int = 1 << 26) -> Callable[[Path], bool]:
    """A :class:`Recognised` test: the file is a JSON object of at most ``max_bytes`` holding
    every one of ``keys``."""
    want = frozenset(keys)

    def test(path: Path) -> bool:
        try:
            if path.stat().st_size > max_bytes:
                return False
            doc = json.loads(path.read_bytes())
        except (OSError, ValueError, RecursionError):
            return False
        return isinstance(doc, dict) and want <= doc.keys()
    return test


# ---------------------------------------------------------------- reading the rule

def files_in(folder: str | Path) -> list[str]:
    """Relative paths of the regular files and symlinks under ``folder`` (symlinks not
    followed), this module's bookkeeping and staging folders left out."""
    out = []
    for root, dirs, names in os.walk(folder):
        dirs[:] = [d for d in dirs if not d.startswith(STAGE_PREFIX)]
        for n in names:
            rel = os.path.relpath(os.path.join(root, n), folder)
            if rel not in NOT_LISTED:
                out.append(rel)
    return sorted(out)


def _read_doc(out: str | Path) -> dict | None:
    """``out``'s manifest as stored, None when it holds none; OwnershipError for a damaged one."""
    m = Path(out) / MANIFEST
    if not m.is_file():
        return None
    try:
        doc = json.loads(m.read_bytes())
        doc["files"]
        return doc
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise OwnershipError(f"{m} is damaged ({type(e).__name__}); Fenestra cannot tell its files from "
                             "yours: remove them yourself or choose another --out") from e


def read_manifest(out: str | Path) -> dict[str, str | list[str]] | None:
    """{relative path: sha256 (a list of two while a swap is under way)} of the files Fenestra
    wrote into ``out``; None when it holds no manifest. OwnershipError for a damaged one, or an older manifest without digests."""
    m = Path(out) / MANIFEST
    doc = _read_doc(out)
    if doc is None:
        return None
    files = doc["files"]
    def digest(v) -> bool:
        return isinstance(v, str) or (isinstance(v, list) and all(isinstance(x, str) for x in v))
    if not isinstance(files, dict) or not all(isinstance(k, str) and digest(v) for k, v in files.items()):
        raise OwnershipError(f"{m} lists no file digests (written by an older Fenestra); Fenestra replaces only "
                             "files whose digest it recorded: remove the folder yourself or choose another --out")
    return {k: v for k, v in files.items() if _inside(Path(out), k)}


def read_kind(out: str | Path) -> str | None:
    """The kind of output ``out`` holds (a key of KINDS, or whatever a newer Fenestra recorded):
    its manifest's ``kind``, else (an older manifest) that of the first LEGACY_KIND file it lists;
    None for a folder without manifest, or one whose manifest says nothing of its kind."""
    doc = _read_doc(out)
    if doc is None:
        return None
    if isinstance(doc.get("kind"), str):
        return doc["kind"]
    files = doc["files"] if isinstance(doc["files"], dict) else {}
    return next((kind for name, kind in LEGACY_KIND if name in files), None)


def describe_kind(kind: str) -> str:
    """How an error names a kind of output: KINDS' words, or the recorded name."""
    return KINDS.get(kind, f"output of kind {kind!r}")


ENCLOSING = {"bench": (), "reconstruction": (), "batch": ("reconstruction",)}  # kind -> what may lie inside it


def enclosing_output(out: str | Path) -> tuple[Path, str] | None:
    """The nearest folder above ``out`` that holds a bench run, a reconstruction or a batch
    (ENCLOSING), with its kind; None when there is none (a folder of loose files does not count)."""
    for parent in Path(out).resolve().parents:
        if (parent / MANIFEST).is_file():
            try:
                kind = read_kind(parent)
            except OwnershipError:  # a damaged manifest above: not this command's to judge
                continue
            if kind in ENCLOSING:
                return parent, kind
    return None


def check_kind(out: str | Path, kind: str, option: str = "--out", hosts: Iterable[str] = ()) -> None:
    """OwnershipError (one line, naming both kinds) when ``out`` holds another kind of output than
    ``kind`` or ``hosts`` (kinds this writer may add files to: a run receives its report), or
    lies inside an output that may not hold it (:func:`enclosing_output`: a reconstruction only
    inside a batch). A folder without a recorded kind passes."""
    have = read_kind(out) if Path(out).is_dir() else None
    if have is not None and have != kind and have not in tuple(hosts):
        raise OwnershipError(f"{option} {out} holds {describe_kind(have)}, not {describe_kind(kind)}; choose another "
                             "folder (--force never replaces another kind of output)")
    above = enclosing_output(out)
    if above is not None and kind not in ENCLOSING[above[1]]:
        raise OwnershipError(f"{option} {out} lies inside {above[0]}, which holds {describe_kind(above[1])}; "
                             "choose a folder outside it")


def _inside(folder: Path, rel: str) -> bool:
    base = folder.resolve()
    return not os.path.isabs(rel) and base in (base / rel).resolve().parents


def _ours(out: Path, rel: str, digests: dict[str, str | list]) -> bool:
    """True if ``out/rel`` is a regular file (not a symlink) whose sha256 is the listed one."""
    p = out / rel
    want = digests.get(rel)
    if want is None or p.is_symlink() or not p.is_file():
        return False
    return file_sha256(p) in (want if isinstance(want, list) else [want])


def foreign_files(out: str | Path, digests: dict[str, str] | None = None) -> list[str]:
    """Files in ``out`` that its manifest (or ``digests``) does not list with their current digest."""
    out = Path(out)
    if not out.is_dir():
        return []
    digests = (read_manifest(out) or {}) if digests is None else digests
    return [f for f in files_in(out) if not _ours(out, f, digests)]


def _name(files: list[str]) -> str:
    return ", ".join(files[:MAX_NAMED]) + (f" and {len(files) - MAX_NAMED} more" if len(files) > MAX_NAMED else "")


def _overlaps(out: Path, path: str | Path) -> str | None:
    """'holds' when ``out`` contains ``path``, 'lies inside' when ``path`` is a folder holding
    ``out`` (or is ``out``), None otherwise (both resolved)."""
    o, p = out.resolve(), Path(path).resolve()
    if o == p or (p.is_dir() and p in o.parents):
        return "lies inside" if o != p else "is"
    if o in p.parents:
        return "holds"
    return None


def check_out(out: str | Path, inputs: Iterable[str | Path | None] = (), force: bool = False,
              option: str = "--out", kind: str | None = None) -> None:
    """OwnershipError (one line) when ``out`` may not receive an output: an existing file; a
    folder that contains, is, or lies inside one of ``inputs``; a folder holding another
    ``kind`` of output (:func:`check_kind`, ``force`` or not); a non-empty folder that holds no
    Fenestra manifest (``force``: allowed, its files stay and are never replaced)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OwnershipError(f"{option} {out} is an existing file, not a folder")
    for p in inputs:
        if p is None:
            continue
        how = _overlaps(out, p)
        if how == "holds":
            raise OwnershipError(f"{option} {out} holds the input {p}; write the result to another folder")
        if how is not None:
            raise OwnershipError(f"{option} {out} {how} the input folder {p}; write the result to another folder")
    if kind is not None:
        check_kind(out, kind, option)
    if out.is_dir() and not force and read_manifest(out) is None:
        mine = files_in(out)
        if mine:
            raise OwnershipError(f"{option} {out} is not empty ({_name(mine)}) and holds no Fenestra output; choose "
                                 "another folder, or pass --force to write beside its files (they are never replaced)")


# ---------------------------------------------------------------- writing under the rule

def _write_manifest(out: Path, files: dict, previous: dict | None = None, kind: str | None = None) -> None:
    """Write ``out``'s manifest listing ``files``; with ``previous`` (during a swap) a file with
    either set's digest is ours. kind: the folder's kind when it has none recorded yet (a
    recorded kind is kept)."""
    merged: dict[str, set[str]] = {}
    for src in (previous or {}, files):
        for k, v in src.items():
            merged.setdefault(k, set()).update(v if isinstance(v, list) else [v])
    kind = read_kind(out) or kind
    doc = {"format": FORMAT, **({"kind": kind} if kind else {}),
           "files": {k: sorted(v) if len(v) > 1 else next(iter(v)) for k, v in sorted(merged.items())}}
    write_json(out / MANIFEST, doc)


def _refuse_foreign(out: Path, names: Iterable[str], owned: dict[str, str], option: str = "--out") -> None:
    clash = [n for n in names if (out / n).exists() or (out / n).is_symlink()]
    clash = [n for n in clash if not _ours(out, n, owned)]
    if clash:
        raise OwnershipError(f"{option} {out}: would replace {_name(clash)}, which Fenestra did not write (or which "
                             "changed since); move it away or choose another folder")


def check_names(out: str | Path, names: Iterable[str], option: str = "--out") -> None:
    """OwnershipError naming those of ``names`` (paths relative to ``out``) that exist in ``out``
    and that its manifest does not list with their current digest: what a writer of those names
    would replace and may not."""
    out = Path(out)
    _refuse_foreign(out, names, read_manifest(out) or {}, option)


def _prune(out: Path, rel: str) -> None:
    """rmdir the emptied parent folders of ``out/rel`` up to ``out`` (never a non-empty one)."""
    d = (out / rel).parent
    while d != out and out in d.parents:
        try:
            d.rmdir()
        except OSError:
            return
        d = d.parent


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def clean_stale_stages(out: str | Path) -> list[str]:
    """Remove the staging folders in ``out`` that a process killed while writing left behind:
    ``STAGE_PREFIX<pid>-*`` of a process that no longer runs, and those of an older Fenestra
    (no process id in the name); returns their names. Only this module's own
    staging folders are ever removed with rmtree."""
    out = Path(out)
    gone = []
    for d in out.glob(STAGE_PREFIX + "*"):
        pid = re.match(re.escape(STAGE_PREFIX) + r"(\d+)-", d.name)
        if d.is_dir() and not d.is_symlink() and (pid is None or not _alive(int(pid.group(1)))):
            shutil.rmtree(d, ignore_errors=True)
            gone.append(d.name)
    return gone


def remove_dead_temp_files(out: str | Path) -> list[str]:
    """Remove the temporary files (fenestra.files.temp_name: ``.<stem>.tmp<pid><suffix>``) under
    ``out`` of a process that no longer runs: half-written files of a run killed while writing,
    never listed, never a result; returns their relative paths. Call it only on a folder that
    holds Fenestra's output (its manifest checked)."""

    out = Path(out)
    gone = []
    for rel in files_in(out):
        m = TEMP_NAME.fullmatch(Path(rel).name)
        if m and not (out / rel).is_symlink() and not _alive(int(m.group("pid"))):
            (out / rel).unlink(missing_ok=True)
            gone.append(rel)
    return gone


def _stage(out: Path) -> Path:
    clean_stale_stages(out)
    tmp = Path(tempfile.mkdtemp(prefix=f"{STAGE_PREFIX}{os.getpid()}-", dir=out))
    umask = os.umask(0o022)
    os.umask(umask)
    tmp.chmod(0o777 & ~umask)  # the result's folders get a normal folder's mode
    return tmp


@contextmanager
def staged(out: str | Path, inputs: Iterable[str | Path | None] = (), force: bool = False,
           kind: str | None = None) -> Iterator[Path]:
    """Yield a fresh hidden folder inside ``out`` (so the final renames stay on one filesystem);
    when the block ends without error its files take their place in ``out``: each moved in,
    replacing only a file of the previous output (:func:`check_out`, the rule above), then the
    previous output's files that were not replaced are removed, then the manifest lists the new
    set. On any error (SIGTERM, Ctrl-C) the staging folder is deleted and ``out`` is as it was.
    kind: the output's kind (KINDS): a folder of another kind is refused, a new one records it."""
    out = Path(out)
    inputs = tuple(inputs)
    check_out(out, inputs, force, kind=kind)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    tmp = None
    try:
        tmp = _stage(out)
        yield tmp
        old = read_manifest(out) or {}
        new = {f: file_sha256(tmp / f) for f in files_in(tmp)}
        _refuse_foreign(out, new, old)
        stale = [f for f in old if f not in new and _ours(out, f, old)]
        _write_manifest(out, new, old, kind)  # both sets are ours while they swap
        for f in new:  # new files in first: the previous result stays whole until they are
            (out / f).parent.mkdir(parents=True, exist_ok=True)
            os.replace(tmp / f, out / f)
        for f in stale:
            (out / f).unlink(missing_ok=True)
            _prune(out, f)
        _write_manifest(out, new)
    except BaseException:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
            tmp = None
        if created:
            try:
                out.rmdir()  # only if still empty
            except OSError:
                pass
        raise
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def write_owned(out: str | Path, name: str, data: bytes, kind: str | None = None, hosts: Iterable[str] = (),
                inputs: Iterable[str | Path | None] = (), option: str = "--out") -> Path:
    """Write ``data`` to ``out/name`` atomically and list it (with its digest) in ``out``'s
    manifest (:func:`write_file`)."""
    return write_file(Path(out) / name, lambda p: p.write_bytes(data) == len(data), kind, hosts, inputs, option)


def write_file(path: str | Path, write, kind: str | None = FILES_KIND, hosts: Iterable[str] = (),
               inputs: Iterable[str | Path | None] = (), option: str = "--out", force: bool = False,
               own: Recognised | None = None) -> Path:
    """Call ``write(tmp)`` on a temporary name beside ``path`` (fenestra.files.write_atomic, same
    suffix), rename it to ``path`` and list it with its digest in its folder's manifest.
    OwnershipError, before ``write`` runs, when ``path`` is one of ``inputs`` (files the command
    reads: never replaced, not even when Fenestra wrote them) or lies inside an input folder, when
    a file of that name exists that Fenestra did not write (``force``: unless ``own`` recognises
    it), or when its folder holds another kind of output than ``kind`` or ``hosts``
    (:func:`check_kind`; a folder new to Fenestra records ``kind``)."""

    path = Path(path)
    check_file(path, kind, hosts, inputs, option, force, own)
    path.parent.mkdir(parents=True, exist_ok=True)
    with listing(path.parent, kind):  # listed before it takes its name: a kill leaves no unlisted file of ours
        write_atomic(path, write)
    _write_manifest(path.parent, {**(read_manifest(path.parent) or {}), path.name: file_sha256(path)}, kind=kind)
    return path


def check_file(path: str | Path, kind: str | None = FILES_KIND, hosts: Iterable[str] = (),
               inputs: Iterable[str | Path | None] = (), option: str = "--out", force: bool = False,
               own: Recognised | None = None) -> None:
    """OwnershipError (one line) when :func:`write_file` would refuse ``path``: call it before the
    work that makes the file. own: this writer's kind of file; an existing one that no manifest
    lists is replaced with ``force`` (else refused, saying so), any other such file never."""
    path = Path(path)
    target = path.resolve()
    for p in (Path(p) for p in inputs if p is not None):
        if p.resolve() == target:
            raise OwnershipError(f"{option} {path} is an input of this command; write to another file")
        if p.is_dir() and p.resolve() in target.parents:
            raise OwnershipError(f"{option} {path} lies inside the input folder {p}; write to another folder")
    if path.is_dir():
        raise OwnershipError(f"{option} {path} is a folder, not a file")
    if kind is not None:
        check_kind(path.parent, kind, option, hosts)
    owned = read_manifest(path.parent) or {}
    if own is not None and path.is_file() and not path.is_symlink() and not _ours(path.parent, path.name, owned) \
            and own.test(path):
        if force:
            return
        raise OwnershipError(f"{option} {path} is {own.words} that Fenestra did not list (or that changed since); "
                             "pass --force to replace it")
    _refuse_foreign(path.parent, [path.name], owned, option)


def record(out: str | Path, names: Iterable[str] | None = None, kind: str | None = None) -> dict[str, str]:
    """List ``names`` (default: every file under ``out``) with their current digests in
    ``out``'s manifest, which then lists only files that exist; returns it. Call it only on files
    this run wrote (a run folder whose foreign files were refused up front). kind: the folder's
    kind, when none is recorded yet."""
    out = Path(out)
    owned = read_manifest(out) or {}
    names = files_in(out) if names is None else list(names)
    owned.update({n: file_sha256(out / n) for n in names if (out / n).is_file() and not (out / n).is_symlink()})
    owned = {n: d for n, d in owned.items() if (out / n).is_file()}
    _write_manifest(out, owned, kind=kind)
    return owned


def remove_owned(out: str | Path, names: Iterable[str] | None = None) -> None:
    """Delete the files of ``out``'s manifest (only ``names`` among them, when given: relative
    paths or folder prefixes), each only while it has its listed digest, and the folders they
    leave empty; OwnershipError naming the files that are in the way (unlisted or changed) when
    all files were to go."""
    out = Path(out)
    owned = read_manifest(out) or {}
    if names is None:
        foreign = foreign_files(out, owned)
        if foreign:
            raise OwnershipError(f"{out} holds {_name(foreign)}, which Fenestra did not write (or which changed "
                                 "since); it removes only its own files: move them away or choose another folder")
        targets = list(owned)
    else:
        prefixes = [n.rstrip("/") for n in names]
        targets = [f for f in owned if any(f == p or f.startswith(p + "/") for p in prefixes)]
    changed = [f for f in targets if (out / f).exists() and not _ours(out, f, owned)]
    if changed:
        raise OwnershipError(f"{out}: {_name(changed)} changed since Fenestra wrote it; it removes only its own "
                             "files: move it away or choose another folder")
    for f in targets:
        (out / f).unlink(missing_ok=True)
        _prune(out, f)
        owned.pop(f, None)
    _write_manifest(out, owned)


@contextmanager
def listing(out: str | Path, kind: str | None = None) -> Iterator[Path]:
    """While the block runs, every file that fenestra.files writes atomically under ``out`` (this
    process) is listed in ``out``'s manifest with its new digest beside its old one (as during a
    swap) before it takes its name: a run killed at any moment leaves no file of its own unlisted
    (a half-written one keeps its temporary name: :func:`remove_dead_temp_files`). kind: the
    folder's kind when it has none recorded yet (so a first file named like another kind's,
    LEGACY_KIND, does not decide it)."""

    root = Path(out).resolve()

    def hook(path: Path, tmp: Path) -> None:
        p = Path(path).resolve()
        if root not in p.parents:
            return
        rel = p.relative_to(root).as_posix()
        if rel in NOT_LISTED or TEMP_NAME.fullmatch(p.name):  # a write into another writer's temporary file
            return
        owned = read_manifest(root) or {}
        _write_manifest(root, {rel: file_sha256(tmp)}, owned, kind)

    with before_rename(hook):
        yield Path(out)


def running_command(argv: list[str] | None = None) -> str:
    """How this process was started, in a user's words: ``fenestra <command>`` for the CLI
    (``fenestra`` or ``python -m fenestra``), else the program's name (``argv``: sys.argv)."""

    argv = sys.argv if argv is None else argv
    prog = Path(argv[0]).name if argv else "python"
    if prog in ("fenestra", "__main__.py"):
        sub = next((a for a in argv[1:] if not a.startswith("-")), None)
        return "fenestra" + (f" {sub}" if sub else "")
    return prog


MAX_LOCK_BYTES = 512  # what a lock file's reader reads of it: the holder's pid and command


def lock_holder(text: str) -> str:
    """How an error names the holder a lock file records (``<pid> <command>``, or an older
    Fenestra's ``<pid>``): "`fenestra reconstruct` (process 1234)" or "process 1234"."""
    pid, _, command = " ".join(text.split()).partition(" ")
    command = bounded(command, 80).replace("`", "'")
    return f"`{command}` (process {pid or '?'})" if command else f"process {pid or '?'}"


@contextmanager
def locked(folder: str | Path, what: str = "run", keep: bool = True, command: str | None = None) -> Iterator[Path]:
    """Hold an exclusive lock on ``folder`` (flock on ``folder/LOCK``, which records the holder's
    process id and command, :func:`running_command` by default; released when the process ends
    however it ends) for the block; OwnershipError at once, naming that command and process,
    when another process holds it: concurrent runs into one folder are refused up front, not
    detected at the end. keep=False: the lock file is removed at the end (while still held)
    unless it was there before."""

    folder = Path(folder)
    existed = (folder / LOCK).exists()
    fd = os.open(folder / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    held = False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = lock_holder(os.pread(fd, MAX_LOCK_BYTES, 0).decode(errors="replace"))
            raise OwnershipError(f"{folder} is in use by {holder}: another {what} is writing into this folder "
                                 f"(it holds {LOCK}); wait for it to end or choose another --out") from None
        held = True
        os.ftruncate(fd, 0)
        line = " ".join((running_command() if command is None else command).split())
        os.write(fd, f"{os.getpid()} {line}\n".encode(errors="backslashreplace")[:MAX_LOCK_BYTES])
        yield folder
    finally:
        if held and not keep and not existed:
            (folder / LOCK).unlink(missing_ok=True)
        os.close(fd)  # releases the lock
