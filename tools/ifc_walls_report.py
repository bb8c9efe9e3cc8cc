"""What model.ifc holds as walls and window bodies, per photo of a ``fenestra reconstruct`` run.

    .venv/bin/python tools/ifc_walls_report.py OUT [--json FILE]

Reads every ``OUT/<photo>/model.ifc`` (and its windows.json) and prints, per photo:

- ``walls``: IfcWall count; ``fit``: the wall fit's groups of the exported windows (windows.json
  ``walls[].merged_from``); ``wall_body``: the walls' Body representation types;
- ``win_body``: the IfcWindow occurrences' Body representation types, ``type_body``: those of the
  IfcWindowTypes' RepresentationMaps, ``types``: IfcWindowType count;
- ``issues``: ifcopenshell.validate statements (schema and express rules);
- ``skew``: each IfcOpeningElement's extrusion direction against its wall's normal (the wall
  placement's y, its layer direction), degrees: the largest, and how many exceed 2 degrees.

A photo whose folder has no model.ifc is listed with its reason (windows.json ``export``).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SKEW_DEG = 2.0  # an opening further than this off its wall's normal counts as skewed


def _placement(product) -> np.ndarray:
    import ifcopenshell.util.placement  # noqa: PLC0415

    return np.asarray(ifcopenshell.util.placement.get_local_placement(product.ObjectPlacement))


def _body_types(product) -> list[str]:
    reps = product.Representation.Representations if product.Representation else ()
    return [r.RepresentationType for r in reps if r.RepresentationIdentifier == "Body"]


def opening_skew_deg(opening, wall) -> float:
    """Angle (deg) between ``opening``'s extrusion direction (its Body solid's, in the world) and
    ``wall``'s normal (its placement's y axis, the direction its layers are laid along)."""
    (solid,) = [i for r in opening.Representation.Representations for i in r.Items]
    M = _placement(opening)
    local = np.asarray(solid.ExtrudedDirection.DirectionRatios, dtype=np.float64)
    if solid.Position is not None and solid.Position.Axis is not None:  # the solid's own frame
        import ifcopenshell.util.placement  # noqa: PLC0415

        local = ifcopenshell.util.placement.get_axis2placement(solid.Position)[:3, :3] @ local
    d = M[:3, :3] @ local
    n = _placement(wall)[:3, 1]
    c = abs(float(d @ n)) / (np.linalg.norm(d) * np.linalg.norm(n))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def photo_row(folder: Path) -> dict:
    """The figures of one photo's output folder (see the module docstring)."""
    import ifcopenshell  # noqa: PLC0415
    import ifcopenshell.validate  # noqa: PLC0415

    doc = json.loads((folder / "windows.json").read_text()) if (folder / "windows.json").is_file() else {}
    exported = {w["index"] for w in doc.get("windows", []) if w.get("exported")}
    fit = sorted({g for w in doc.get("walls", []) if set(w["members"] + w.get("partial", [])) & exported
                  for g in w["merged_from"]})
    row = {"photo": folder.name, "fit": len(fit)}
    ifc_path = folder / "model.ifc"
    if not ifc_path.is_file():
        return {**row, "missing": "no model.ifc"}
    f = ifcopenshell.open(str(ifc_path))
    logger = ifcopenshell.validate.json_logger()
    ifcopenshell.validate.validate(f, logger, express_rules=True)
    skews = [opening_skew_deg(rel.RelatedOpeningElement, wall)
             for wall in f.by_type("IfcWall") for rel in wall.HasOpenings]
    type_body = sorted({m.MappedRepresentation.RepresentationType for t in f.by_type("IfcWindowType")
                        for m in (t.RepresentationMaps or ())})
    return {**row, "walls": len(f.by_type("IfcWall")),
            "wall_body": sorted({t for w in f.by_type("IfcWall") for t in _body_types(w)}),
            "windows": len(f.by_type("IfcWindow")),
            "win_body": sorted({t for w in f.by_type("IfcWindow") for t in _body_types(w)}),
            "types": len(f.by_type("IfcWindowType")), "type_body": type_body,
            "issues": len(logger.statements),
            "openings": len(skews), "skew_max_deg": max(skews, default=0.0),
            "skewed": sum(s > SKEW_DEG for s in skews)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="a `fenestra reconstruct` output folder (one subfolder per photo)")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    args = ap.parse_args(argv)
    folders = sorted(p.parent for p in args.out.glob("*/windows.json"))
    if not folders:
        print(f"{args.out}: no <photo>/windows.json in it (run fenestra reconstruct first)", file=sys.stderr)
        return 2
    rows = [photo_row(p) for p in folders]
    print(f"{'photo':10} {'fit':>3} {'walls':>5} {'wall body':12} {'win':>3} {'win body':22} {'types':>5} "
          f"{'type body':12} {'issues':>6} {'skew max':>8} {'skewed':>7}")
    for r in rows:
        if "missing" in r:
            print(f"{r['photo']:10} {r['fit']:>3} {r['missing']}")
            continue
        print(f"{r['photo']:10} {r['fit']:>3} {r['walls']:>5} {','.join(r['wall_body']):12} {r['windows']:>3} "
              f"{','.join(r['win_body']):22} {r['types']:>5} {','.join(r['type_body']) or '-':12} {r['issues']:>6} "
              f"{r['skew_max_deg']:>8.2f} {r['skewed']:>3}/{r['openings']:<3}")
    ok = [r for r in rows if "missing" not in r]
    n_open = sum(r["openings"] for r in ok)
    print(f"total: {sum(r['walls'] for r in ok)} IfcWall, {sum(r['windows'] for r in ok)} IfcWindow, "
          f"{sum(r['issues'] for r in ok)} validate issues, {sum(r['skewed'] for r in ok)} of {n_open} openings "
          f"skewed > {SKEW_DEG:g} deg (max {max((r['skew_max_deg'] for r in ok), default=0.0):.2f})")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
