"""Reading the project's TOML files (bench profiles, gates, training configs) with clear errors."""
from __future__ import annotations

import tomllib
from pathlib import Path


def read_toml(path: str | Path, error: type[Exception] = ValueError, what: str = "file") -> dict:
    """Parse a TOML file into a dict.

    Raises ``error`` naming the path when the file is missing or is not valid TOML; ``what``
    names the kind of file in the message (e.g. "profile file").
    """
    p = Path(path)
    if not p.is_file():
        raise error(f"{what} {p} does not exist")
    try:
        return tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as e:
        raise error(f"{p}: not valid TOML: {e}") from e
