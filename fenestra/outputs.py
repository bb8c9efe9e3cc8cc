"""Which files Fenestra may delete or replace: one rule for every command that writes a folder
(``fenestra reconstruct --out``, its batch mode, ``fenestra bench --out``).

    check_out(out, inputs, force=False)          # before any work: refuse a bad --out
    with staged(out, inputs, force) as tmp:      # write everything into tmp (a hidden child of out)
        ...
    # the new files are moved into out first, then the previous run's files that are not replaced
    # are removed: a failure at any point before leaves the previous result whole
    write_owned(out, {"summary.json": data})     # one file, replacing only an owned one
    record(out, ["results.parquet", ...])        # add files written in place to the manifest
    remove_owned(out)                            # delete what the manifest lists, refuse the rest

The rule. Every output folder holds ``MANIFEST`` (.fenestra-output.json), ``{"format": 2,
"files": {relative path: sha256}}``: the files Fenestra wrote there and their digests.

- Fenestra deletes or replaces a file only when the manifest lists it and its bytes still have
  the listed digest. A file it did not write, or one edited since, is refused with its name:
  never overwritten, never deleted, ``--force`` or not.
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

import json
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from fenestra.errors import FenestraError
from fenestra.files import file_sha256, write_json

MANIFEST = ".fenestra-output.json"
STAGE_PREFIX = ".fenestra-stage-"
LOCK = ".fenestra.lock"
FORMAT = 2
MAX_NAMED = 5
NOT_LISTED = (MANIFEST, LOCK)  # bookkeeping of this module: never a result, never "foreign"


class OwnershipError(FenestraError):
    """A folder or file Fenestra may not write (an input, a file it did not write); names it."""


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


def read_manifest(out: str | Path) -> dict[str, str | list[str]] | None:
    """{relative path: sha256 (a list of two while a swap is under way)} of the files Fenestra
    wrote into ``out``; None when it holds no manifest. OwnershipError for a damaged one, or an older manifest without digests."""
    m = Path(out) / MANIFEST
    if not m.is_file():
        return None
    try:
        doc = json.loads(m.read_bytes())
        files = doc["files"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise OwnershipError(f"{m} is damaged ({type(e).__name__}); Fenestra cannot tell its files from "
                             "yours: remove them yourself or choose another --out") from e
    def digest(v) -> bool:
        return isinstance(v, str) or (isinstance(v, list) and all(isinstance(x, str) for x in v))
    if not isinstance(files, dict) or not all(isinstance(k, str) and digest(v) for k, v in files.items()):
        raise OwnershipError(f"{m} lists no file digests (written by an older Fenestra); Fenestra replaces only "
                             "files whose digest it recorded: remove the folder yourself or choose another --out")
    return {k: v for k, v in files.items() if _inside(Path(out), k)}


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
              option: str = "--out") -> None:
    """OwnershipError (one line) when ``out`` may not receive an output: an existing file; a
    folder that contains, is, or lies inside one of ``inputs``; a non-empty folder that holds no
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
    if out.is_dir() and not force and read_manifest(out) is None:
        mine = files_in(out)
        if mine:
            raise OwnershipError(f"{option} {out} is not empty ({_name(mine)}) and holds no Fenestra output; choose "
                                 "another folder, or pass --force to write beside its files (they are never replaced)")


# ---------------------------------------------------------------- writing under the rule

def _write_manifest(out: Path, files: dict, previous: dict | None = None) -> None:
    """Write ``out``'s manifest listing ``files``; with ``previous`` (during a swap) a file with
    either set's digest is ours."""
    merged: dict[str, set[str]] = {}
    for src in (previous or {}, files):
        for k, v in src.items():
            merged.setdefault(k, set()).update(v if isinstance(v, list) else [v])
    doc = {"format": FORMAT, "files": {k: sorted(v) if len(v) > 1 else next(iter(v)) for k, v in sorted(merged.items())}}
    write_json(out / MANIFEST, doc)


def _refuse_foreign(out: Path, names: Iterable[str], owned: dict[str, str]) -> None:
    clash = [n for n in names if (out / n).exists() or (out / n).is_symlink()]
    clash = [n for n in clash if not _ours(out, n, owned)]
    if clash:
        raise OwnershipError(f"--out {out}: would replace {_name(clash)}, which Fenestra did not write (or which "
                             "changed since); move it away or choose another folder")


def _prune(out: Path, rel: str) -> None:
    """rmdir the emptied parent folders of ``out/rel`` up to ``out`` (never a non-empty one)."""
    d = (out / rel).parent
    while d != out and out in d.parents:
        try:
            d.rmdir()
        except OSError:
            return
        d = d.parent


def _stage(out: Path) -> Path:
    tmp = Path(tempfile.mkdtemp(prefix=STAGE_PREFIX, dir=out))
    umask = os.umask(0o022)
    os.umask(umask)
    tmp.chmod(0o777 & ~umask)  # the result's folders get a normal folder's mode
    return tmp


@contextmanager
def staged(out: str | Path, inputs: Iterable[str | Path | None] = (), force: bool = False) -> Iterator[Path]:
    """Yield a fresh hidden folder inside ``out`` (so the final renames stay on one filesystem);
    when the block ends without error its files take their place in ``out``: each moved in,
    replacing only a file of the previous output (:func:`check_out`, the rule above), then the
    previous output's files that were not replaced are removed, then the manifest lists the new
    set. On any error (SIGTERM, Ctrl-C) the staging folder is deleted and ``out`` is as it was."""
    out = Path(out)
    inputs = tuple(inputs)
    check_out(out, inputs, force)
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
        _write_manifest(out, new, old)  # both sets are ours while they swap
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


def write_owned(out: str | Path, name: str, data: bytes) -> Path:
    """Write ``out/name`` atomically and list it (with its digest) in ``out``'s manifest;
    OwnershipError when a file of that name exists that Fenestra did not write."""
    from fenestra.files import write_bytes  # noqa: PLC0415

    out = Path(out)
    owned = read_manifest(out) or {}
    _refuse_foreign(out, [name], owned)
    path = write_bytes(out / name, data)
    _write_manifest(out, {**owned, name: file_sha256(path)})
    return path


def record(out: str | Path, names: Iterable[str] | None = None) -> dict[str, str]:
    """List ``names`` (default: every file under ``out``) with their current digests in
    ``out``'s manifest, which then lists only files that exist; returns it. Call it only on files
    this run wrote (a run folder whose foreign files were refused up front)."""
    out = Path(out)
    owned = read_manifest(out) or {}
    names = files_in(out) if names is None else list(names)
    owned.update({n: file_sha256(out / n) for n in names if (out / n).is_file() and not (out / n).is_symlink()})
    owned = {n: d for n, d in owned.items() if (out / n).is_file()}
    _write_manifest(out, owned)
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
def locked(folder: str | Path, what: str = "run") -> Iterator[Path]:
    """Hold an exclusive lock on ``folder`` (flock on ``folder/LOCK``, released when the process
    ends however it ends) for the block; OwnershipError at once when another process holds it:
    concurrent runs into one folder are refused up front, not detected at the end."""
    import fcntl  # noqa: PLC0415

    folder = Path(folder)
    fd = os.open(folder / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise OwnershipError(f"{folder}: another {what} is writing into this folder (it holds {LOCK}); "
                                 "wait for it to end or choose another --out") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield folder
    finally:
        os.close(fd)  # releases the lock
