"""Export recall on labelled street photos: how many labelled windows an exported window of
``fenestra reconstruct`` matches (issue 35: windows cut by the photo's border).

    .venv/bin/python tools/export_recall.py [--spb ../shared/real/spb_facades] [--part all|val] \
        [--out out/export-recall] [--runs DIR] [--iou 0.3] [--classes 0]

Runs ``fenestra reconstruct PHOTOS... --out OUT`` (the command itself, in a subprocess: the CLI's
detector, resolution and defaults, no K) on the photos of the YOLO folder ``SPB`` (``images/``,
``labels/``; ``--part``: every photo, or the validation part of a train folder, every 5th photo by
sorted name, the one ``make train`` leaves out: training.dataset.real_box_photos) unless ``--runs``
names the folder of an earlier run, then reads each photo's ``OUT/<stem>/windows.json`` and
``SPB/labels/<stem>.txt`` (YOLO boxes, normalised; classes: ../shared/real/README.md, window = 0)
and counts, per photo and in all:

- ``labelled``: label boxes of ``--classes``;
- ``matched``: labelled windows matched one-to-one (Hungarian on box IoU, bench.matching.match) to
  an exported window (``exported`` true) with box IoU >= ``--iou``; an exported window's box is the
  bounding box of its ``quad_snapped`` (for a partial window: its visible quad);
- ``matched_whole``: the same with the partial windows (``partial`` true) left out: what the run
  matches without them (windows.json before partial windows carried no ``partial``: all whole);
- ``exported``, ``exported_partial``, ``partial`` (detections cut by the border), and
  ``at_border``: labelled windows whose box reaches within 3 px of the photo's edge.

The photos are not part of the repository (their licence is not verified: never copy them in);
without them the tool says so in one line and exits 2.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SPB = ROOT.parent / "shared" / "real" / "spb_facades"


def label_boxes(label: Path, size: tuple[int, int], classes: tuple[int, ...]) -> list[np.ndarray]:
    """(4,) x0 y0 x1 y1 px of the label file's boxes of ``classes`` in a photo of size (W, H)."""
    from fenestra.yolo import read_label_file, yolo_boxes  # noqa: PLC0415

    W, H = size
    return list(yolo_boxes(read_label_file(label), W, H, classes, str(label)))


def exported_boxes(doc: dict, whole_only: bool = False) -> list[np.ndarray]:
    """(4,) x0 y0 x1 y1 px: the bounding box of each exported window's snapped quad (a partial
    window's visible quad); ``whole_only``: the partial windows left out."""
    out = []
    for w in doc["windows"]:
        if w.get("exported") and w.get("quad_snapped") is not None and not (whole_only and w.get("partial")):
            q = np.asarray(w["quad_snapped"], dtype=np.float64).reshape(4, 2)
            out.append(np.array([*q.min(axis=0), *q.max(axis=0)]))
    return out


def matched(det: list[np.ndarray], gt: list[np.ndarray], min_iou: float) -> int:
    """Labelled boxes ``gt`` matched one-to-one by boxes ``det`` at box IoU >= min_iou."""
    from fenestra.bench.matching import match  # noqa: PLC0415
    from fenestra.bench.metrics import box_iou_matrix  # noqa: PLC0415

    if not det or not gt:
        return 0
    return len(match(box_iou_matrix(det, gt), min_iou).pairs)


def at_border(box: np.ndarray, size: tuple[int, int], px: float = 3.0) -> bool:
    """Does a box (4,) x0 y0 x1 y1 px reach within ``px`` of the edge of a (W, H) photo?"""
    W, H = size
    return bool(box[0] < px or box[1] < px or box[2] > W - 1 - px or box[3] > H - 1 - px)


def photo_counts(doc: dict, gt: list[np.ndarray], min_iou: float) -> dict:
    """One photo's counts (see the module docstring) from its windows.json ``doc`` and label boxes."""
    wins = doc["windows"]
    size = tuple(doc["image_size"])
    return {"labelled": len(gt), "at_border": sum(at_border(b, size) for b in gt),
            "matched": matched(exported_boxes(doc), gt, min_iou),
            "matched_whole": matched(exported_boxes(doc, whole_only=True), gt, min_iou),
            "exported": sum(bool(w.get("exported")) for w in wins),
            "exported_partial": sum(bool(w.get("exported")) and bool(w.get("partial")) for w in wins),
            "partial": sum(bool(w.get("partial")) for w in wins)}


def photos_of(spb: Path, part: str) -> list[Path]:
    """The photos of the YOLO folder ``spb`` with a label file: every one (``all``) or its
    validation part (``val``, training.dataset.real_box_photos)."""
    from fenestra.training.dataset import real_box_photos  # noqa: PLC0415

    return real_box_photos(spb, part)


def run_cli(photos: list[Path], out: Path) -> None:
    """``fenestra reconstruct PHOTOS... --out OUT --force``: an earlier batch there is replaced
    under the command's own rule (only what that batch wrote; any other folder is refused)."""
    cmd = [sys.executable, "-m", "fenestra", "reconstruct", *map(str, photos), "--out", str(out), "--force"]
    print("$", " ".join(cmd[:4]), f"<{len(photos)} photos>" if len(photos) > 3 else " ".join(cmd[4:-2]),
          *cmd[-2:], flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT)


def measure(spb: Path, photos: list[Path], runs: Path, min_iou: float, classes: tuple[int, ...]) -> dict:
    """{"photos": {stem: counts}, "total": counts summed} over ``photos`` of the YOLO folder ``spb``."""
    out, total = {}, {}
    for img in photos:
        doc = json.loads((runs / img.stem / "windows.json").read_text())
        gt = label_boxes(spb / "labels" / f"{img.stem}.txt", tuple(doc["image_size"]), classes)
        out[img.stem] = photo_counts(doc, gt, min_iou)
        for k, v in out[img.stem].items():
            total[k] = total.get(k, 0) + v
    return {"photos": out, "total": total}


def labelled_photo_arguments(ap: argparse.ArgumentParser, out_name: str) -> argparse.ArgumentParser:
    """The labelled-photo tools' common options: --spb, --part, --out (out/<out_name>), --runs."""
    ap.add_argument("--spb", type=Path, default=SPB,
                    help="a YOLO folder (images/, labels/); default: the spb_facades test photos")
    ap.add_argument("--part", choices=("all", "val"), default="all",
                    help="every photo, or the validation part (every 5th by name) of a train folder")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / out_name, help="where the run goes")
    ap.add_argument("--runs", type=Path, default=None, help="an earlier run's --out folder: read, not run")
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = labelled_photo_arguments(argparse.ArgumentParser(description=__doc__.split("\n\n")[0]), "export-recall")
    ap.add_argument("--iou", type=float, default=0.3, help="box IoU of a match")
    ap.add_argument("--classes", default="0", help="label classes counted, comma-separated (window = 0)")
    ap.add_argument("--json", action="store_true", help="print the counts as JSON")
    a = ap.parse_args(argv)
    if not (a.spb / "images").is_dir() or not (a.spb / "labels").is_dir():
        print(f"error: no photos at {a.spb} (images/ and labels/): give --spb", file=sys.stderr)
        return 2
    classes = tuple(int(c) for c in a.classes.split(","))
    photos = photos_of(a.spb, a.part)
    runs = a.runs
    if runs is None:
        run_cli(photos, a.out)
        runs = a.out
    res = measure(a.spb, photos, runs, a.iou, classes)
    if a.json:
        print(json.dumps(res, indent=2))
        return 0
    print(f"{'photo':<10} {'labelled':>8} {'at edge':>7} {'matched':>8} {'whole':>6} {'exported':>8} {'partial':>8}")
    for stem, c in {**res["photos"], "total": res["total"]}.items():
        print(f"{stem:<10} {c['labelled']:>8} {c['at_border']:>7} {c['matched']:>8} {c['matched_whole']:>6} "
              f"{c['exported']:>8} {c['exported_partial']:>8}")
    t = res["total"]
    print(f"export recall (box IoU >= {a.iou:g}, classes {classes}): {t['matched']}/{t['labelled']} with partial "
          f"windows, {t['matched_whole']}/{t['labelled']} whole windows only")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
