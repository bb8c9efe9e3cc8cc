"""Small file helpers shared by every stage."""
from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Iterable


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
