"""Output folders written whole or not at all (``fenestra reconstruct --out``).

    with staged_dir(out) as tmp:        # a fresh hidden folder beside ``out``
        write everything into tmp
    # on success tmp replaces out (an earlier result in out is removed); on any error or
    # SIGTERM tmp is deleted and out is left as it was: never old files beside new ones.

A non-empty ``out`` that holds no Fenestra result (no ``windows.json``) is refused unless
``force``; an existing file named ``out`` is always refused.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from fenestra.errors import PipelineError
from fenestra.files import replace_dir

MARKER = "windows.json"  # what makes a folder a reconstruct output


def check_out(out: Path, force: bool) -> None:
    """PipelineError if ``out`` is a file, or a non-empty folder not ours (unless force)."""
    if out.exists() and not out.is_dir():
        raise PipelineError(f"--out {out} is an existing file, not a folder")
    if out.is_dir() and not force and not (out / MARKER).is_file() and any(out.iterdir()):
        raise PipelineError(f"--out {out} is not empty and holds no reconstruct output ({MARKER}); "
                            "choose another folder or pass --force to replace its contents")


@contextmanager
def staged_dir(out: str | Path, force: bool = False) -> Iterator[Path]:
    """Yield a fresh temporary folder beside ``out``; swap it in as ``out`` when the block ends
    without error (see the module docstring; :func:`fenestra.files.replace_dir` after
    :func:`check_out`). OSError (read-only, name too long) propagates."""
    out = Path(out)
    check_out(out, force)
    with replace_dir(out) as tmp:
        yield tmp
