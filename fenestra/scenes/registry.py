"""The bundled IFC houses by short name, and resolution of a name or path to a file.

    >>> from scenes.registry import BUNDLED, resolve
    >>> resolve("fzk-haus").name
    'AC20-FZK-Haus.ifc'

Provenance and licences of the bundled files: ``fenestra/scenes/ifc/SOURCES.md``.
"""
from __future__ import annotations

import os
from pathlib import Path

from fenestra.errors import SceneError

IFC_DIR = Path(__file__).resolve().parent / "ifc"
# Public IFC models from the wild (../shared/ifc/wild: README.md and manifest.json give provenance and
# licences; several are GPL or unlicensed, so they are read from there, never bundled). A name
# "wild:<key>" resolves to WILD_HOUSES[key] in :func:`wild_dir`.
WILD_ENV = "FENESTRA_WILD_IFC"
WILD_PREFIX = "wild:"
WILD_HOUSES: dict[str, str] = {
    "ifcopenhouse-ifc4": "IfcOpenHouse_IFC4.ifc",
    "curved-wall": "06-03-01_windows_in_curved_wall_vw.ifc",
    "ac11-institute": "AC11-Institute-Var-2-IFC.ifc",
    "vectorworks-unicode": "vectorworks_unicode.ifc",
    "largebuilding": "LargeBuilding.ifc",
    "renga-house": "House.ifc",
    "roof-bricscad": "Roof-01_BCAD.ifc",
    "examplehom": "ExampleHOM.ifc",
    "kit-edc": "KIT-EDC_with_SB.ifc",
    "ifcopenhouse-cvillagrasa": "IfcOpenHouse_cvillagrasa.ifc",
    "lanternhollow": "LanternHollow_FreeCAD_export.ifc",
    "allplan-smiley": "Allplan-Smiley-West.ifc",  # IFC2X_FINAL: refused in one line
}

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


def wild_dir() -> Path:
    """The folder of the wild IFC models: ``$FENESTRA_WILD_IFC``, else ../shared/ifc/wild from the
    working directory (beside a checkout, run from its root)."""
    env = os.environ.get(WILD_ENV)
    return Path(env) if env else Path.cwd().parent / "shared" / "ifc" / "wild"


def resolve_wild(name: str) -> Path:
    """"wild:<key>" -> its file in :func:`wild_dir`; SceneError saying plainly what is missing."""
    key = name[len(WILD_PREFIX):]
    if key not in WILD_HOUSES:
        raise SceneError(f"unknown wild house '{name}'; known: {', '.join(WILD_PREFIX + k for k in WILD_HOUSES)}")
    folder = wild_dir()
    if not folder.is_dir():
        raise SceneError(f"wild house '{name}': the wild IFC folder {folder} is not there (set "
                         f"{WILD_ENV} to the folder that holds {WILD_HOUSES[key]})")
    path = folder / WILD_HOUSES[key]
    if not path.is_file():
        raise SceneError(f"wild house '{name}': {path} is missing from the wild IFC folder")
    return path


def resolve(name_or_path: str | Path) -> Path:
    """Bundled short name (e.g. ``"duplex"``), wild name (``"wild:kit-edc"``) or path to an .ifc
    file -> existing file path.

    Raises SceneError naming the value when it is none of these.
    """
    key = str(name_or_path)
    if key.startswith(WILD_PREFIX):
        return resolve_wild(key)
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
    """Short name of a bundled file, "wild:<key>" of a wild one, else the file's stem."""
    path = Path(path).resolve()
    for name, p in BUNDLED.items():
        if p.resolve() == path:
            return name
    for key, file in WILD_HOUSES.items():
        if path.name == file and path.parent == wild_dir().resolve():
            return WILD_PREFIX + key
    return path.stem


def is_known(name: str) -> bool:
    """A bundled name, a wild name or an existing file (what a profile's scenes.houses may list)."""
    return name in BUNDLED or name.startswith(WILD_PREFIX) or Path(name).is_file()
