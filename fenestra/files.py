"""Small file helpers shared by every stage: digests, and the one atomic writer.

Atomic writes: every writer here writes to a hidden temporary name beside the target
(``.<stem>.tmp<pid><suffix>``) and renames it over the target, so a reader never sees half a
file, and a failed write (disk full, read-only folder, SIGTERM unwinding) leaves the old file or
none, and no temporary file. A failure raises OSError ``cannot write <target>: <reason>``.

    write_bytes(path, data)      write_text(path, text)      write_json(path, doc)
    write_image(path, image)     write_atomic(path, write)   (any writer that takes a path)
    with replace_dir(out) as tmp: ...   (a whole folder: tmp replaces out when the block succeeds)
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

PACKAGE_DIR = Path(__file__).resolve().parent  # the installed `fenestra` package
IMPORT_ROOT = PACKAGE_DIR.parent  # the folder `fenestra` is imported from: site-packages, or a source checkout


def file_sha256(path: str | Path) -> str:
    """sha256 hex digest of a file's bytes (read in 1 MiB blocks)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def source_digest(files: Iterable[str | Path], extra: str = "") -> str:
    """12 hex digits of sha256 over each file's name and bytes, in the given order, and ``extra``
    (e.g. a library version): a cache key that changes whenever that code changes, so no version
    number has to be bumped by hand."""
    h = hashlib.sha256()
    for f in files:
        p = Path(f)
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    h.update(extra.encode())
    return h.hexdigest()[:12]


# ---------------------------------------------------------------- atomic writes

def temp_name(path: Path, pid: int | None = None) -> Path:
    """The temporary name :func:`write_atomic` writes ``path`` under: ``.<stem>.tmp<pid><suffix>``
    beside it (pid: this process's)."""
    return path.with_name(f".{path.stem}.tmp{os.getpid() if pid is None else pid}{path.suffix}")


TEMP_NAME = re.compile(r"\.(?P<stem>.+)\.tmp(?P<pid>\d+)(?P<suffix>\.[^.]*)?")  # temp_name's names


_BEFORE_RENAME: list[Callable[[Path, Path], None]] = []  # before_rename's hooks, innermost last


@contextmanager
def before_rename(hook: Callable[[Path, Path], None]) -> Iterator[None]:
    """For the block, :func:`write_atomic` calls ``hook(path, tmp)`` once the temporary file is
    complete and before it takes its name (fenestra.outputs.listing lists it there)."""
    _BEFORE_RENAME.append(hook)
    try:
        yield
    finally:
        _BEFORE_RENAME.remove(hook)


def write_atomic(path: str | Path, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp)`` on a temporary name beside ``path`` (same suffix, so writers that pick
    the format by extension work), then rename it over ``path``; return ``path``. The hooks of
    :func:`before_rename` see the complete temporary file before the rename.

    OSError ``cannot write <path>: ...`` when the writer raises OSError, returns False or leaves
    no file; the temporary file is removed in every case.
    """
    path = Path(path)
    tmp = temp_name(path)
    try:
        try:
            ok = write(tmp)
        except OSError as e:
            raise OSError(f"cannot write {path}: {e.strerror or e}") from e
        if ok is False or not tmp.is_file():
            raise OSError(f"cannot write {path} (disk full or not writable?)")
        for hook in tuple(_BEFORE_RENAME):
            hook(path, tmp)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (:func:`write_atomic`)."""
    return write_atomic(path, lambda p: p.write_bytes(data) == len(data))


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`write_atomic`)."""
    return write_bytes(path, text.encode("utf-8"))


def write_ifc_file(model, path: str | Path) -> Path:
    """Write an ifcopenshell model to ``path`` atomically: a ``.ifc`` as its STEP text's bytes
    written here (so any path, a name that is not UTF-8 included, works), another suffix
    (``.ifczip``, ``.ifcxml``) by ifcopenshell in the format it names."""
    if Path(path).suffix.lower() == ".ifc":
        return write_bytes(path, model.to_string().encode())
    return write_atomic(path, lambda p: model.write(str(p)))


def write_json(path: str | Path, doc, indent: int | None = 1) -> Path:
    """Write ``doc`` as JSON (``json.dumps(doc, indent=indent)``) to ``path`` atomically."""
    return write_text(path, json.dumps(doc, indent=indent))


def write_image(path: str | Path, image: np.ndarray, scratch: bool = False) -> Path:
    """Write an image atomically, in the format of ``path``'s suffix (``.png``: lossless).

    image: (H, W, 3) uint8 **RGB** (stored as the file's BGR), or (H, W) uint8 / uint16 single
    channel (an instance map: 16-bit PNG). ``scratch``: the caller no longer needs ``image``, so
    an RGB one is turned BGR in place (no copy of a 100 Mpx image; it holds BGR afterwards).
    ValueError for another shape, OSError naming ``path`` when it cannot be encoded or written.
    """
    import cv2  # noqa: PLC0415  (only the image writers need OpenCV)

    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] == 3 and a.dtype == np.uint8:
        if scratch and a.flags.c_contiguous and a.flags.writeable:
            for y in range(0, a.shape[0], 256):  # in bands: cv2.cvtColor in place would copy the whole image
                a[y:y + 256] = a[y:y + 256, :, ::-1]
        else:
            a = a[..., ::-1]
    elif not (a.ndim == 2 and a.dtype in (np.uint8, np.uint16)):
        raise ValueError(f"image for {path} must be (H, W, 3) uint8 RGB or (H, W) uint8/uint16, "
                         f"got shape {a.shape}, dtype {a.dtype}")
    ok, buf = cv2.imencode(Path(path).suffix or ".png", np.ascontiguousarray(a))
    if not ok:
        raise OSError(f"cannot write {path}: cv2 cannot encode a {a.shape} {a.dtype} image as {Path(path).suffix}")
    return write_bytes(path, memoryview(buf.reshape(-1)))  # the encoded bytes, not copied again


def staging_dir(out: str | Path) -> Path:
    """A fresh hidden folder beside ``out`` (``.<name>.<random>``) with a normal folder's mode,
    where an output is built before it takes ``out``'s place."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    umask = os.umask(0o022)
    os.umask(umask)
    tmp.chmod(0o777 & ~umask)  # mkdtemp makes it 0o700; the result gets a normal folder's mode
    return tmp


@contextmanager
def replace_dir(out: str | Path) -> Iterator[Path]:
    """Yield a fresh hidden folder beside ``out`` (``.<name>.<random>``, a normal folder's mode);
    when the block ends without error it replaces ``out`` (an earlier ``out`` is removed), on any
    error (or SIGTERM unwinding) it is deleted and ``out`` is left as it was: never old files
    beside new ones. OSError (read-only, name too long) propagates."""
    out = Path(out)
    tmp = staging_dir(out)
    try:
        yield tmp
        old = out.with_name(f".{out.name}.old{os.getpid()}") if out.exists() else None
        if old is not None:
            out.rename(old)
        tmp.rename(out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
