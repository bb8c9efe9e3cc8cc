"""Real photo -> BIM on labelled street photos, against the targets of "a façade model a BIM
modeller would keep": one command, its figures generated into docs/usage.md.

    .venv/bin/python tools/bim_photos.py [--spb ../shared/real/spb_facades] [--out out/bim-photos] \
        [--runs DIR] [--doc docs/usage.md] [--json PATH]

Runs ``fenestra reconstruct PHOTOS... --out OUT/<set>`` (the CLI itself, no K:
tools/export_recall.py's run) on two sets of the YOLO folder ``SPB``: ``test`` (``SPB/images``,
never trained on) and ``val`` (the validation part of ``SPB/train``: every 5th photo, the part
``make train`` leaves out), unless ``--runs`` names an earlier ``--out``. Then per set:

- export precision: exported windows whose box matches a labelled window (classes 0, 4: window,
  balcony window; box IoU >= 0.3, one to one) over exported windows; recall: matched labelled
  windows (class 0) over labelled windows (tools/export_recall.py);
- doors: labelled doors (class 5) an IfcDoor is on, of those some detection is on; IfcWindow on a
  labelled door or signboard (class 3) and on no labelled window (tools/door_recall.py);
- walls (IfcWall per photo), floors (model.ifc's storeys; the smallest spacing), window bodies
  (their representation types), ``ifcopenshell.validate`` issues (tools/ifc_walls_report.py);
- windows at their visible size: exported partial windows that were not completed (no
  ``visible_fraction``);
- messages: every failure sentence, flag and opening reason of windows.json read for "nan", an
  exponent or an internal name (tests/pipeline/test_messages.py's rule).

The photos are not part of the repository (their licence is not verified: never copy them in);
without them the tool says so in one line and exits 2.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tools import door_recall, export_recall, ifc_walls_report  # noqa: E402

BLOCK = "bim-photos"
BAD = re.compile(r"nan|inf\b|\d[eE][+-]?\d|\b[a-z]+_[a-z_]+\b|=|\s<\s|\d\s*px\b", re.I)
TARGETS = (  # (key, words, comparison, value)
    ("precision", "export precision", ">=", 0.95), ("recall", "export recall", ">=", 0.85),
    ("door_share", "labelled doors exported as IfcDoor, of those detected", ">=", 0.80),
    ("windows_on_door_or_sign", "IfcWindow on a door or a signboard", "==", 0),
    ("min_floor_spacing_m", "smallest floor spacing, m", ">=", 2.2),
    ("visible_size", "windows exported at their visible size", "==", 0),
    ("non_swept_bodies", "IfcWindow bodies not swept solids", "==", 0),
    ("issues", "ifcopenshell.validate issues", "==", 0), ("bad_messages", "messages with nan, e+0 or names", "==", 0),
)


def photo_sets(spb: Path) -> dict[str, list[Path]]:
    """{"test": the test photos, "val": the train folder's validation part}."""
    from fenestra.training.dataset import real_box_photos  # noqa: PLC0415 (torch: imported when first used)

    return {"test": real_box_photos(spb, "all"), "val": real_box_photos(spb / "train", "val")}


def messages(doc: dict) -> list[str]:
    """Every sentence windows.json says to a person: failure sentences, flags, opening reasons."""
    out = [w.get("failure_message") for w in doc.get("windows", [])]
    out += [f for w in doc.get("windows", []) for f in w.get("flags") or []]
    out += [o.get("not_exported") for o in doc.get("openings") or []]
    return [m for m in out if m]


def set_figures(spb: Path, photos: list[Path], runs: Path) -> dict:
    """The figures of one photo set's run folder ``runs`` (see the module docstring)."""
    win = export_recall.measure(spb, photos, runs, 0.3, (0,))["total"]
    win_any = export_recall.measure(spb, photos, runs, 0.3, (0, 4))["total"]
    doors = door_recall.measure(spb, photos, runs)["total"]
    rows = [ifc_walls_report.photo_row(runs / p.stem) for p in photos]
    docs = [json.loads((runs / p.stem / "windows.json").read_text()) for p in photos]
    said = [m for d in docs for m in messages(d)]
    exported = max(win["exported"], 1)
    return {
        "photos": len(photos), "labelled": win["labelled"], "exported": win["exported"],
        "precision": win_any["matched"] / exported, "recall": win["matched"] / max(win["labelled"], 1),
        "doors": doors["doors"], "doors_detected": doors["detected"], "doors_as_ifcdoor": doors["as_door"],
        "door_share": doors["as_door"] / max(doors["detected"], 1),
        "windows_on_door_or_sign": doors["windows_on_door"] + doors["windows_on_sign"],
        "walls": [r.get("walls", 0) for r in rows], "floors": doors["storeys"],
        "min_floor_spacing_m": doors["min_spacing_m"] if doors["min_spacing_m"] is not None else float("inf"),
        "visible_size": sum(1 for d in docs for w in d["windows"]
                            if w.get("exported") and w.get("partial") and w.get("visible_fraction") is None),
        "non_swept_bodies": sum(1 for r in rows for b in r.get("win_body", []) if b not in ("MappedRepresentation",)
                                ) + sum(1 for r in rows for b in r.get("type_body", []) if b != "SweptSolid"),
        "issues": sum(r.get("issues", 0) for r in rows), "messages": len(said),
        "bad_messages": sum(bool(BAD.search(m)) for m in said),
    }


def met(value, op: str, target) -> bool:
    return value >= target if op == ">=" else value == target


def markdown(figs: dict[str, dict], command: str) -> str:
    """The block: one row per target, a column per photo set."""
    sets = list(figs)
    lines = [f"Generated by `{command}` (the CLI's defaults, no K).", "",
             "| target | " + " | ".join(f"{s} ({figs[s]['photos']} photos)" for s in sets) + " |",
             "|---|" + "---|" * len(sets)]
    for key, words, op, target in TARGETS:
        cells = []
        for s in sets:
            v = figs[s][key]
            shown = f"{100 * v:.0f} %" if key in ("precision", "recall", "door_share") else (
                "-" if v == float("inf") else f"{v:.2f}" if isinstance(v, float) else str(v))
            cells.append(shown + ("" if met(v, op, target) else " (**missed**)"))
        goal = f"{op} {100 * target:.0f} %" if key in ("precision", "recall", "door_share") else f"{op} {target:g}"
        lines.append(f"| {words} ({goal}) | " + " | ".join(cells) + " |")
    for s in sets:
        f = figs[s]
        lines.append("")
        lines.append(f"- {s}: {f['exported']} windows exported for {f['labelled']} labelled; "
                     f"{f['doors_as_ifcdoor']} of {f['doors_detected']} detected labelled doors (of {f['doors']}) as "
                     f"IfcDoor; IfcWall per photo {sorted(f['walls'])}; {f['floors']} floors; "
                     f"{f['messages']} messages read.")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spb", type=Path, default=export_recall.SPB, help="the YOLO folder (images/, labels/, train/)")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bim-photos", help="where the runs go (one folder per set)")
    ap.add_argument("--runs", type=Path, default=None, help="an earlier --out: read, not run")
    ap.add_argument("--doc", type=Path, default=None, help="write the figures into this Markdown file's block")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    a = ap.parse_args(argv)
    if not (a.spb / "images").is_dir():
        print(f"error: {a.spb}/images not found: the labelled street photos are not here", file=sys.stderr)
        return 2
    runs = a.runs or a.out
    figs = {}
    for name, photos in photo_sets(a.spb).items():
        if a.runs is None:
            export_recall.run_cli(photos, runs / name)
        figs[name] = set_figures(a.spb if name == "test" else a.spb / "train", photos, runs / name)
    command = "python tools/bim_photos.py" + (f" --doc {a.doc}" if a.doc else "")  # --runs only rereads its runs
    text = markdown(figs, command)
    print(text)
    if a.json:
        a.json.write_text(json.dumps(figs, indent=1, default=float))
    if a.doc:
        from lab.docs.blocks import write_block  # noqa: PLC0415 (the lab: only from a checkout)

        write_block(a.doc, BLOCK, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
