"""Output folders written whole or not at all (``fenestra reconstruct --out``), under the one
file-ownership rule of :mod:`fenestra.outputs` (shared with the batch mode and ``fenestra bench``).

    with staged_dir(out, inputs=(photo, K_json)) as tmp:   # a fresh hidden folder inside ``out``
        write everything into tmp
    # on success tmp's files replace the earlier result in out (new files moved in first, then the
    # earlier result's other files removed); on any error or SIGTERM tmp is deleted and out is
    # left as it was: never old files beside new ones.

Every output folder holds ``MANIFEST`` (.fenestra-output.json): the files Fenestra wrote there,
with their sha256. Replacing an output removes or replaces only those files, and only while they
have their recorded digest; a file of the user's is never replaced (``force`` lets a non-empty
folder that is not an output receive the result beside its files). A folder that holds, or lies
inside, an input (the photo, K, masks) is refused whatever ``force`` says; an existing file named
``out`` is always refused. Errors are PipelineError, one line naming the folder and the file.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from fenestra import outputs
from fenestra.errors import PipelineError

MANIFEST = outputs.MANIFEST


KIND = "reconstruction"  # the kind of output a reconstruct folder is (fenestra.outputs.KINDS)


def check_out(out: Path, force: bool, inputs: Iterable[str | Path | None] = ()) -> None:
    """PipelineError if ``out`` may not receive a reconstruct output (fenestra.outputs.check_out:
    an input, a folder of another kind, a user's folder without ``force``)."""
    try:
        outputs.check_out(Path(out), inputs, force, kind=KIND)
    except outputs.OwnershipError as e:
        raise PipelineError(str(e)) from e


@contextmanager
def held_out(out: str | Path, force: bool = False, inputs: Iterable[str | Path | None] = ()) -> Iterator[Path]:
    """``out`` checked (:func:`check_out`) and locked for the block (fenestra.outputs.locked,
    the lock file removed at the end): a second reconstruct into it is refused at once, naming
    the process that holds it, before its pipeline runs. The folders this made are removed
    again (rmdir) when they stay empty."""
    out = Path(out)
    check_out(out, force, inputs)
    made = [p for p in (out, *out.parents) if not p.exists()]  # deepest first
    out.mkdir(parents=True, exist_ok=True)
    try:
        with outputs.locked(out, "reconstruct", keep=False):
            yield out
    except outputs.OwnershipError as e:
        raise PipelineError(str(e)) from e
    finally:
        for p in made:
            try:
                p.rmdir()  # only if still empty
            except OSError:
                break


@contextmanager
def staged_dir(out: str | Path, force: bool = False, inputs: Iterable[str | Path | None] = ()) -> Iterator[Path]:
    """Yield a fresh hidden folder inside ``out``; when the block ends without error its files
    replace the previous output's in ``out`` (fenestra.outputs.staged). OSError (read-only,
    name too long) propagates; a refusal is a PipelineError."""
    try:
        with outputs.staged(Path(out), inputs, force, kind=KIND) as tmp:
            yield tmp
    except outputs.OwnershipError as e:
        raise PipelineError(str(e)) from e
