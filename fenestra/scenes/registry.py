"""The bundled IFC houses by short name, and resolution of a name or path to a file.

    >>> from scenes.registry import BUNDLED, resolve
    >>> resolve("fzk-haus").name
    'AC20-FZK-Haus.ifc'

Provenance and licences of the bundled files: ``fenestra/scenes/ifc/SOURCES.md``.
"""
from __future__ import annotations

from pathlib import Path

from fenestra.errors import SceneError

IFC_DIR = Path(__file__).resolve().parent / "ifc"

# Short name -> bundled file. Order: smallest/simplest first (fzk-haus is the smoke-test house).
BUNDLED: dict[str, Path] = {
    "fzk-haus": IFC_DIR / "AC20-FZK-Haus.ifc",
    "duplex": IFC_DIR / "Duplex_A_20110907.ifc",
    "samplehouse4": IFC_DIR / "SampleHouse4.ifc",
    "jasmin-sun": IFC_DIR / "AC90R1-Jasmin-Sun-105-2x3.ifc",
    "niedriha": IFC_DIR / "AC90R1-niedriha-V2-2x3.ifc",
    "office-a": IFC_DIR / "Office_A_20110811.ifc",  # a Revit office: a held-out family, never trained on
    # hand-authored here (fenestra/scenes/authored.py, `fenestra scenes author`): held-out families
    "authored-terrace": IFC_DIR / "authored-terrace.ifc",
    "authored-studio": IFC_DIR / "authored-studio.ifc",
}


def resolve(name_or_path: str | Path) -> Path:
    """Bundled short name (e.g. ``"duplex"``) or path to an .ifc file -> existing file path.

    Raises SceneError naming the value when it is neither a bundled name nor an existing file.
    """
    key = str(name_or_path)
    if key in BUNDLED:
        path = BUNDLED[key]
        if not path.is_file():
            raise SceneError(f"bundled scene '{key}' is missing its file {path}")
        return path
    path = Path(key).expanduser()
    if path.is_file():
        return path.resolve()
    if path.exists():
        raise SceneError(f"{path}: not a file")
    if path.suffix.lower() != ".ifc" and "/" not in key:
        raise SceneError(f"unknown scene '{key}': not a bundled name ({', '.join(BUNDLED)}) "
                         f"and no such file")
    raise SceneError(f"{path}: no such file")


def scene_name(path: Path) -> str:
    """Short name of a bundled file, else the file's stem."""
    path = Path(path).resolve()
    for name, p in BUNDLED.items():
        if p.resolve() == path:
            return name
    return path.stem
