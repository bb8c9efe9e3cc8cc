"""Doors and storeys of ``fenestra reconstruct`` on labelled street photos: how many labelled doors
become an IfcDoor, whether a door or a signboard became an IfcWindow, and the floors model.ifc gets.

    .venv/bin/python tools/door_recall.py [--spb ../shared/real/spb_facades] [--part all|val] \
        [--out out/door-recall] [--runs DIR] [--json]

Runs ``fenestra reconstruct PHOTOS... --out OUT`` (tools/export_recall.py's run: the CLI itself, no
K) on the photos of the YOLO folder ``SPB`` unless ``--runs`` names an earlier run, then reads each
photo's ``windows.json`` and ``export.json`` and its label file (classes: ../shared/real/README.md;
door = 5, signboard = 3). A box is **on** a label when their IoU, or their intersection over the
box's own area, exceeds 0.5 (training.evaluate's rule for doors and signboards). Per photo and in all:

- ``doors``: labelled doors; ``detected``: those some detection is on (a window's snapped quad's
  box, or an opening's box: windows.json ``openings``, the verifier's doors and signboards);
  ``as_door_kind``: those a detection the verifier calls a door is on;
- ``as_door``: labelled doors an exported door (windows.json ``openings``, kind door, exported) is
  on; ``exported_doors``: exported doors, ``true_doors``: those on a labelled door;
- ``windows_on_door`` / ``windows_on_sign``: exported windows on a labelled door / signboard and on
  no labelled window (class 0 or 4, IoU >= 0.3);
- ``storeys``: model.ifc's floors (export.json ``storeys.floors``), ``min_spacing_m``: the smallest
  elevation step between consecutive floors (None with one floor), ``storey_source``.

The photos are not part of the repository (their licence is not verified: never copy them in);
without them the tool says so in one line and exits 2.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tools.export_recall import (exported_boxes, label_boxes, labelled_photo_arguments, photos_of,  # noqa: E402
                                 run_cli)

DOOR, SIGNBOARD, WINDOW_CLASSES = 5, 3, (0, 4)
WINDOW_IOU = 0.3  # an exported window on a labelled window at this box IoU is a window, whatever else it touches


def on(boxes: list, labels: list) -> np.ndarray:
    """(len(boxes), len(labels)) bool: box i is on label j (IoU or intersection over box i > 0.5)."""
    from fenestra.training.evaluate import HARD_NEGATIVE_OVERLAP, box_overlaps  # noqa: PLC0415

    if not len(boxes) or not len(labels):
        return np.zeros((len(boxes), len(labels)), bool)
    iou, iod = box_overlaps(np.asarray(boxes), np.asarray(labels))
    return (iou > HARD_NEGATIVE_OVERLAP) | (iod > HARD_NEGATIVE_OVERLAP)


def quad_box(quad) -> np.ndarray:
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    return np.array([*q.min(axis=0), *q.max(axis=0)])


def photo_counts(doc: dict, manifest: dict | None, label: Path) -> dict:
    """One photo's counts (see the module docstring) from its windows.json, export.json and labels."""
    from fenestra.training.evaluate import box_overlaps  # noqa: PLC0415

    size = tuple(doc["image_size"])
    doors, signs = label_boxes(label, size, (DOOR,)), label_boxes(label, size, (SIGNBOARD,))
    windows = label_boxes(label, size, WINDOW_CLASSES)
    openings = doc.get("openings") or []
    seen = [quad_box(w["quad_snapped"]) for w in doc["windows"] if w.get("quad_snapped") is not None]
    seen += [np.asarray(o["box"], dtype=np.float64) for o in openings]
    door_kind = [np.asarray(o["box"], dtype=np.float64) for o in openings if o["kind"] == "door"]
    exported_doors = [np.asarray(o["box"], dtype=np.float64) for o in openings if o["kind"] == "door" and o["exported"]]
    win = exported_boxes(doc)
    if win and windows:
        real = box_overlaps(np.asarray(win), np.asarray(windows))[0].max(axis=1) >= WINDOW_IOU
        win = [b for b, r in zip(win, real) if not r]
    floors = ((manifest or {}).get("storeys") or {}).get("floors") or []
    steps = np.diff([f["elevation_m"] for f in floors])
    return {"doors": len(doors), "detected": int(on(seen, doors).any(axis=0).sum()),
            "as_door_kind": int(on(door_kind, doors).any(axis=0).sum()),
            "as_door": int(on(exported_doors, doors).any(axis=0).sum()), "exported_doors": len(exported_doors),
            "true_doors": int(on(exported_doors, doors).any(axis=1).sum()),
            "windows_on_door": int(on(win, doors).any(axis=1).sum()),
            "windows_on_sign": int(on(win, signs).any(axis=1).sum()),
            "storeys": len(floors), "min_spacing_m": float(steps.min()) if len(steps) else None,
            "storey_source": ((manifest or {}).get("storeys") or {}).get("storey_source")}


def measure(spb: Path, photos: list[Path], runs: Path) -> dict:
    """{"photos": {stem: counts}, "total": the counts summed (storeys: their sum; min_spacing_m:
    the smallest)}."""
    out = {}
    for img in photos:
        doc = json.loads((runs / img.stem / "windows.json").read_text())
        ex = runs / img.stem / "export.json"
        out[img.stem] = photo_counts(doc, json.loads(ex.read_text()) if ex.is_file() else None,
                                     spb / "labels" / f"{img.stem}.txt")
    keys = [k for k in next(iter(out.values()), {}) if k not in ("min_spacing_m", "storey_source")]
    total = {k: sum(c[k] for c in out.values()) for k in keys}
    spacings = [c["min_spacing_m"] for c in out.values() if c["min_spacing_m"] is not None]
    total["min_spacing_m"] = min(spacings) if spacings else None
    total["storey_source"] = ", ".join(sorted({str(c["storey_source"]) for c in out.values()}))
    return {"photos": out, "total": total}


def main(argv: list[str] | None = None) -> int:
    ap = labelled_photo_arguments(argparse.ArgumentParser(description=__doc__.split("\n\n")[0]), "door-recall")
    ap.add_argument("--json", action="store_true", help="print the counts as JSON")
    a = ap.parse_args(argv)
    if not (a.spb / "images").is_dir() or not (a.spb / "labels").is_dir():
        print(f"error: no photos at {a.spb} (images/ and labels/): give --spb", file=sys.stderr)
        return 2
    photos = photos_of(a.spb, a.part)
    runs = a.runs
    if runs is None:
        run_cli(photos, a.out)
        runs = a.out
    res = measure(a.spb, photos, runs)
    if a.json:
        print(json.dumps(res, indent=2))
        return 0
    cols = ("doors", "detected", "as_door_kind", "as_door", "exported_doors", "true_doors", "windows_on_door", "windows_on_sign",
            "storeys", "min_spacing_m")
    print(f"{'photo':<10} " + " ".join(f"{c:>15}" for c in cols), flush=True)
    for stem, c in {**res["photos"], "total": res["total"]}.items():
        print(f"{stem:<10} " + " ".join(f"{'-' if c[k] is None else (f'{c[k]:.2f}' if isinstance(c[k], float) else c[k]):>15}"
                                        for k in cols))
    t = res["total"]
    print(f"labelled doors exported as IfcDoor: {t['as_door']}/{t['detected']} of those detected, {t['as_door']}/"
          f"{t['as_door_kind']} of those detected as doors ({t['doors']} labelled); door precision {t['true_doors']}/{t['exported_doors']}; exported windows on "
          f"a door {t['windows_on_door']}, on a signboard {t['windows_on_sign']}; storeys {t['storeys']} on "
          f"{len(res['photos'])} photos, smallest spacing {t['min_spacing_m']} m ({t['storey_source']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
