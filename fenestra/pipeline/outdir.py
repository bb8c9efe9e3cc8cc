"""Output folders written whole or not at all (``fenestra reconstruct --out``).

    with staged_dir(out, inputs=(photo, K_json)) as tmp:   # a fresh hidden folder beside ``out``
        write everything into tmp
    # on success tmp's files replace the earlier result in out; on any error or SIGTERM tmp is
    # deleted and out is left as it was: never old files beside new ones.

Every output folder holds ``MANIFEST`` (.fenestra-output.json): the files Fenestra wrote there.
Replacing an output removes exactly those files, never anything else: ``force`` lets a non-empty
folder that is not an output receive the result, and its own files stay. A folder that holds an
input (the photo, K, masks) is refused whatever ``force`` says; an existing file named ``out``
is always refused.
"""
from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from fenestra.errors import PipelineError
from fenestra.files import staging_dir

MARKER = "windows.json"  # what makes a folder a reconstruct output
MANIFEST = ".fenestra-output.json"  # {"files": [relative paths Fenestra wrote]}


def written_files(out: Path) -> list[str] | None:
    """The files a previous run wrote into ``out`` (its MANIFEST), None when there is none. A
    legacy output (MARKER, no MANIFEST) lists only MARKER. Entries leading outside ``out`` are dropped."""
    m = out / MANIFEST
    if not m.is_file():
        return [MARKER] if (out / MARKER).is_file() else None
    try:
        names = json.loads(m.read_text())["files"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise PipelineError(f"--out {out}: its {MANIFEST} is damaged ({e}); remove the folder yourself") from e
    base = out.resolve()
    return [n for n in names if isinstance(n, str) and base in (base / n).resolve().parents]


def _holds(out: Path, path: str | Path) -> bool:
    """True if ``path`` (resolved) lies inside folder ``out`` (resolved)."""
    base, p = out.resolve(), Path(path).resolve()
    return base in p.parents


def check_out(out: Path, force: bool, inputs: Iterable[str | Path | None] = ()) -> None:
    """PipelineError if ``out`` is a file, holds one of ``inputs``, or is a non-empty folder
    that is not ours (unless force)."""
    if out.exists() and not out.is_dir():
        raise PipelineError(f"--out {out} is an existing file, not a folder")
    for p in inputs:
        if p is not None and _holds(out, p):
            raise PipelineError(f"--out {out} holds the input {p}; write the result to another folder")
    if out.is_dir() and not force and written_files(out) is None and any(out.iterdir()):
        raise PipelineError(f"--out {out} is not empty and holds no reconstruct output ({MARKER}); "
                            "choose another folder or pass --force to write into it (its files stay)")


def _list_files(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def _merge_into(tmp: Path, out: Path, old: list[str]) -> None:
    """Remove the files ``old`` (a previous run's) from ``out``, then move tmp's files in."""
    for n in old:
        (out / n).unlink(missing_ok=True)
    for n in _list_files(tmp):
        (out / n).parent.mkdir(parents=True, exist_ok=True)
        os.replace(tmp / n, out / n)


@contextmanager
def staged_dir(out: str | Path, force: bool = False, inputs: Iterable[str | Path | None] = ()) -> Iterator[Path]:
    """Yield a fresh temporary folder beside ``out``; when the block ends without error its files
    (and a MANIFEST listing them) replace the previous output's in ``out`` (see the module
    docstring). OSError (read-only, name too long) propagates."""
    out = Path(out)
    inputs = tuple(inputs)
    check_out(out, force, inputs)
    tmp = staging_dir(out)
    try:
        yield tmp
        (tmp / MANIFEST).write_text(json.dumps({"files": [*_list_files(tmp), MANIFEST]}, indent=1))
        old = written_files(out) if out.is_dir() else None
        if not out.exists():
            tmp.rename(out)
        elif old is not None and set(_list_files(out)) <= set(old) | {MANIFEST}:
            side = out.with_name(f".{out.name}.old{os.getpid()}")  # only our files: swap whole
            out.rename(side)
            tmp.rename(out)
            shutil.rmtree(side, ignore_errors=True)
        else:  # foreign files beside ours (or --force): replace ours only, theirs stay
            _merge_into(tmp, out, old or [])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
