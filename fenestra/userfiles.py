"""Reading a user's files safely: only regular files, only inside the folder they belong to,
JSON only up to a stated size (fenestra.conventions.LIMITS.max_json_bytes).

    p = inside(folder, "images/../x.png", "annotations.json images[3] file_name")  # DatasetError: outside
    regular_file(p)                        # DatasetError for a FIFO, a device, a folder, a missing file
    doc = read_json(folder / "annotations.json", "COCO annotations")

    text = read_text(folder / "labels" / "a.txt", "YOLO label file", limit, "max_label_bytes")

Errors are fenestra.errors.DatasetError (a ValueError) naming the file and what is wrong, never
quoting a file's content.
"""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

from fenestra.conventions import LIMITS
from fenestra.errors import DatasetError, bounded


def inside(root: str | Path, name: str, where: str) -> Path:
    """``root / name`` if it stays inside ``root`` once resolved (symlinks and ``..`` followed);
    DatasetError naming ``where`` for an absolute name or one that leads outside."""
    if not isinstance(name, str) or not name:
        raise DatasetError(f"{where}: must be a non-empty relative path string, got {name!r}")
    if os.path.isabs(name) or Path(name).anchor:
        raise DatasetError(f"{where}: {name!r} is an absolute path; give it relative to the dataset folder {root}")
    base = resolved(root, f"dataset folder {str(root)!r}")
    p = resolved(base / name, f"{where}: {name!r}")
    if p != base and base not in p.parents:
        raise DatasetError(f"{where}: {name!r} leads outside the dataset folder {root}")
    return Path(root) / name


def resolved(path: str | Path, what: str) -> Path:
    """``path`` made absolute with every symlink followed; DatasetError "<what> is a symlink loop"
    (``what`` names the path as the user gave it) for a loop, or a link chain too long to follow."""
    try:
        return Path(path).resolve()
    except (RuntimeError, OSError) as e:  # Python < 3.13 reports a loop as RuntimeError
        raise DatasetError(f"{what} is a symlink loop (it cannot be resolved)") from e


def utf8_name(name: str, what: str) -> str:
    """``name`` (a file or folder name as Python decodes it: bytes that are not UTF-8 become lone
    surrogates) when it is valid UTF-8; DatasetError naming ``what`` otherwise (tables and JSON
    files hold UTF-8 text only)."""
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        raise DatasetError(f"{what} {name!r}: the name is not valid UTF-8, which a results table cannot "
                           "hold; rename it") from None
    return name


def is_regular(path: str | Path) -> bool:
    """True if ``path`` (symlinks followed) is a regular file: never a FIFO, socket or device."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def regular_file(path: str | Path, what: str = "file") -> Path:
    """``path`` if it is a regular file; DatasetError (missing, or a FIFO/device/folder) otherwise."""
    p = Path(path)
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError as e:
        raise DatasetError(f"{what} not found: {p}") from e
    except OSError as e:
        raise DatasetError(f"cannot read {what} {p}: {e.strerror}") from e
    if not stat.S_ISREG(mode):
        raise DatasetError(f"{what} {p} is not a regular file (a folder, FIFO or device); refused")
    return p


def read_bytes(path: str | Path, what: str, limit: int, limit_name: str) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (``limit_name``: its field of
    fenestra.conventions.LIMITS), the size checked before reading; DatasetError naming the file."""
    p = regular_file(path, what)
    size = p.stat().st_size
    if size > limit:
        raise DatasetError(f"{what} {p} is {size / 2**20:.1f} MB, more than the {limit / 2**20:.0f} MB "
                           f"limit (fenestra.conventions.LIMITS.{limit_name})")
    return p.read_bytes()


def read_text(path: str | Path, what: str, limit: int, limit_name: str) -> str:
    """The UTF-8 text of a regular file of at most ``limit`` bytes (:func:`read_bytes`);
    DatasetError naming the file when it is not text."""
    try:
        return read_bytes(path, what, limit, limit_name).decode("utf-8")
    except UnicodeDecodeError as e:
        raise DatasetError(f"{what} {path} is not UTF-8 text (byte {e.start})") from e


def read_json(path: str | Path, what: str = "JSON file", limit: int | None = None):
    """The parsed JSON of a regular file of at most ``limit`` bytes (default
    LIMITS.max_json_bytes), checked before reading; DatasetError naming the file otherwise."""
    p = Path(path)
    raw = read_bytes(p, what, LIMITS.max_json_bytes if limit is None else limit, "max_json_bytes")
    try:
        return json.loads(raw)
    except (ValueError, RecursionError) as e:  # ValueError: not UTF-8, not JSON, or a number of > 4300 digits
        why = "nested too deeply" if isinstance(e, RecursionError) else bounded(e)
        raise DatasetError(f"{what} {p} is not valid JSON: {why}") from e
