"""Generated blocks of a Markdown file: the lines between ``<!-- name:begin -->`` and
``<!-- name:end -->``, which a repository command rewrites and nobody types."""
from __future__ import annotations

import re
from pathlib import Path

from fenestra.files import write_text



def fill_block(text: str, name: str, content: str) -> str:
    """text with the lines between ``<!-- name:begin -->`` and ``<!-- name:end -->`` replaced by content;
    ValueError naming the block if its markers are missing or repeated."""
    pattern = re.compile(rf"(<!-- {name}:begin -->\n)(.*?)(<!-- {name}:end -->)", re.S)
    found = pattern.findall(text)
    if len(found) != 1:
        raise ValueError(f"block {name!r}: expected one <!-- {name}:begin --> ... <!-- {name}:end --> pair, found {len(found)}")
    return pattern.sub(lambda m: m.group(1) + content.rstrip("\n") + "\n" + m.group(3), text)


def write_block(path: Path, name: str, content: str) -> None:
    """Replace block ``name`` of the Markdown file ``path`` by ``content`` (:func:`fill_block`,
    atomically) and say so."""
    path = Path(path)
    write_text(path, fill_block(path.read_text(), name, content))
    print(f"wrote block {name!r} of {path}")


def block(text: str, name: str) -> str:
    """The content of block ``name`` (without its markers)."""
    m = re.search(rf"<!-- {name}:begin -->\n(.*?)<!-- {name}:end -->", text, re.S)
    if m is None:
        raise ValueError(f"block {name!r} not found")
    return m.group(1)
