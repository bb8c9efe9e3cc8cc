"""Reading an IFC file as users bring it: schema check, tolerant attribute repair, class families.

    >>> f = open_ifc(Path("House.ifc"))      # SceneError in one line when nothing can be read
    >>> base_class(f.by_type("IfcWindow")[0])
    'IfcWindow'

Tolerant reading (:func:`repair_derived`): some exporters (Renga) write ``*`` (a derived value) for
explicit attributes such as an opening's Name; ifcopenshell's geometry kernel then refuses the
element ("Requested type <string> does not match actual type <derived>"). Those values are set to
unset (``$``), which is what they mean; attributes the schema really derives (IfcSIUnit.Dimensions)
are left alone.
"""
from __future__ import annotations

import re
from pathlib import Path

from fenestra.errors import SceneError

SUPPORTED_SCHEMAS: tuple[str, ...] = ("IFC2X3", "IFC4", "IFC4X3")  # prefixes: IFC4X3_ADD2 is IFC4X3
# What an element loads, looks and renders as (ElementMesh.base_class): the first of these it is_a().
BASE_CLASSES: tuple[str, ...] = (
    "IfcWindow", "IfcDoor", "IfcCurtainWall", "IfcWall", "IfcSlab", "IfcRoof", "IfcCovering",
    "IfcPlate", "IfcMember", "IfcColumn", "IfcBeam", "IfcRailing", "IfcStair", "IfcSite",
    "IfcOpeningElement")
# Never rendered, never occluders: spatial, virtual and annotation elements and subtraction features
# (is_a() includes subtypes: IfcOpeningStandardCase, IfcVoidingFeature). Absent classes are skipped.
SKIP_CLASSES: tuple[str, ...] = (
    "IfcFeatureElementSubtraction", "IfcSpace", "IfcExternalSpatialElement", "IfcSpatialZone",
    "IfcVirtualElement", "IfcAnnotation", "IfcGrid")
_DERIVED_ARG = re.compile(rb"#(\d+)\s*=\s*[A-Za-z0-9_]+\s*\([^;]*?[(,]\s*\*\s*[,)]")


def _check_envelope(path: Path) -> None:
    """SceneError unless the file starts as IFC-SPF and ends with END-ISO-10303-21."""
    with open(path, "rb") as f:
        head = f.read(64)
        f.seek(max(0, path.stat().st_size - 256))
        tail = f.read()
    if not head.lstrip().startswith(b"ISO-10303-21"):
        raise SceneError(f"{path}: not an IFC-SPF file (does not start with 'ISO-10303-21;')")
    if b"END-ISO-10303-21" not in tail:
        raise SceneError(f"{path}: truncated IFC file (no 'END-ISO-10303-21;' at the end)")


def header_schema(path: Path) -> str:
    """The FILE_SCHEMA name of an SPF file's header ("" when there is none)."""
    with open(path, "rb") as f:
        head = f.read(8192)
    m = re.search(rb"FILE_SCHEMA\s*\(\s*\(\s*'([^']*)'", head)
    return m.group(1).decode("ascii", "replace").upper() if m else ""


def check_schema(path: Path, schema: str) -> None:
    """SceneError naming the file and the schema unless it is one of SUPPORTED_SCHEMAS."""
    if schema and not any(schema.upper().startswith(s) for s in SUPPORTED_SCHEMAS):
        raise SceneError(f"{path}: unsupported IFC schema {schema} (Fenestra reads "
                         f"{', '.join(SUPPORTED_SCHEMAS)}; convert the file to one of them)")


def open_ifc(path: Path):
    """Open an IFC-SPF file with ifcopenshell, repaired by :func:`repair_derived`.

    SceneError (one line, naming the file) for a non-IFC, truncated, unreadable file or a schema
    other than SUPPORTED_SCHEMAS (IFC2X_FINAL and older).
    """
    import ifcopenshell  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    path = Path(path)
    _check_envelope(path)
    check_schema(path, header_schema(path))
    try:
        f = ifcopenshell.open(str(path))
    except Exception as e:  # ifcopenshell raises its own Error / RuntimeError types
        raise SceneError(f"{path}: unreadable IFC ({' '.join(str(e).split())})") from None
    check_schema(path, f.schema)
    repair_derived(f, path.read_bytes())
    return f


def spf_arguments(text: str) -> list[str]:
    """Top-level arguments of one SPF instance ``#1=IFCX(a,(b,c),'d,e');`` -> ['a', '(b,c)', "'d,e'"]."""
    body = text[text.index("(") + 1: text.rindex(")")]
    out, cur, depth, quoted = [], [], 0, False
    for ch in body:
        if quoted:
            quoted = ch != "'"
        elif ch == "'":
            quoted = True
        elif ch == "(":
            depth += 1
        elif ch == ")":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append("".join(cur).strip())
            cur = []
            continue
        cur.append(ch)
    out.append("".join(cur).strip())
    return out


def repair_derived(ifc_file, data: bytes) -> int:
    """Unset every ``*`` written for an attribute the schema does not derive; returns how many.

    data: the file's bytes (only instances with a ``*`` argument are looked at, so this costs
    milliseconds on files that have none).
    """
    import ifcopenshell.ifcopenshell_wrapper as wrapper  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    schema = wrapper.schema_by_name(getattr(ifc_file, "schema_identifier", ifc_file.schema))
    n = 0
    for m in _DERIVED_ARG.finditer(data):
        try:
            e = ifc_file.by_id(int(m.group(1)))
        except RuntimeError:
            continue
        derived = schema.declaration_by_name(e.is_a()).as_entity().derived()
        for i, arg in enumerate(spf_arguments(e.to_string())):
            if arg == "*" and i < len(derived) and not derived[i]:
                setattr(e, e.attribute_name(i), None)
                n += 1
    return n


def is_any(entity, classes: tuple[str, ...]) -> bool:
    """entity.is_a(c) for any c of classes that its schema has (IFC2X3 lacks IfcExternalSpatialElement)."""
    for c in classes:
        try:
            if entity.is_a(c):
                return True
        except RuntimeError:
            continue
    return False


def base_class(entity) -> str:
    """The first of BASE_CLASSES that ``entity`` is_a() (subtypes included), "" when none."""
    return next((c for c in BASE_CLASSES if is_any(entity, (c,))), "")


def by_types(ifc_file, classes: tuple[str, ...]) -> list:
    """Every instance of any of classes (subtypes included) that the file's schema has."""
    out = []
    for c in classes:
        try:
            out.extend(ifc_file.by_type(c))
        except RuntimeError:
            continue
    return out
