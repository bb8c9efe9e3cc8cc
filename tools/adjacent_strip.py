"""Adjacent windows: does a detector keep neighbours 0.1-0.2 m apart apart? (issue 46's target)

    .venv/bin/python tools/adjacent_strip.py [--detectors default,quadnet] [--seeds 0,1,2] [--views 8] \
        [--json docs/results/adjacent_strip.json] [--doc docs/experiments.md --block adjacent-strip]

Authors a test house (IFC4, with fenestra/scenes/authored.py's parts; written under out/, never
trained on): a 13 x 7 m box of one 3.2 m storey whose front wall holds a strip of nine 1.0 x 2.3 m
windows 0.2 m apart (the Revit 2021 facade of issue 46) and whose back wall holds a ribbon of eight
0.6 x 1.4 m windows 0.1 m apart, every window set back 0.12 m. Renders it under each seed's look
(``fenestra render --look-per view``: walls, frames and light drawn per view), runs each detector
as the CLI does (pipeline.detectors.detect, score >= 0.5) and, per evaluable window (visible
fraction >= 0.9, all corners in the frame, sides >= 12 px: the bench's evaluation rule), says
whether a detection's mask covers it (IoU >= 0.5: found) and whether one detection covers two or
more windows by half of each (merged). Prints a table per detector and seed; the target is
found >= 95 % with no merge under every seed.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

LEN, DEPTH, WALL, STOREY = 13.0, 7.0, 0.3, 3.2
STRIP = (9, 1.0, 2.3, 0.2, 0.5)  # count, width, height, gap, sill (m)
RIBBON = (8, 0.6, 1.4, 0.1, 1.0)
SETBACK = 0.12


def strip_plan():
    """The test house's authored.Plan (see the module doc)."""
    from fenestra.scenes.authored import STYLES_STUDIO, Plan, Prism, Win, floor_slab, ring_walls  # noqa: PLC0415

    footprint = ((0.0, 0.0), (LEN, 0.0), (LEN, DEPTH), (0.0, DEPTH))
    walls = ring_walls("W", 0, footprint, WALL, 0.0, STOREY, (0.0, 0.0, 0.0, 0.0))
    wins = []
    for wall, (n, w, h, gap, sill) in (("W0", STRIP), ("W2", RIBBON)):
        start = (LEN - (n * w + (n - 1) * gap)) / 2
        wins += [Win(f"{wall} {k}", wall, start + k * (w + gap), sill, w, h, SETBACK, "frame", ("recessed",))
                 for k in range(n)]
    roof = Prism("Roof", "IfcSlab", 0, (-0.3, -0.3, STOREY), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                 ((0.0, 0.0), (LEN + 0.6, 0.0), (LEN + 0.6, DEPTH + 0.6), (0.0, DEPTH + 0.6)), 0.3, "roof", "ROOF")
    return Plan("Fenestra adjacent-strip test house", 4711, (("Ground", 0.0),), tuple(walls), tuple(wins), (),
                (floor_slab("Floor 0", 0, footprint, 0.0, 0.25), roof), STYLES_STUDIO)


def render(ifc: Path, seed: int, views: int, out: Path) -> Path:
    """The dataset folder of ``views`` raster views of the house under ``seed`` (a look per view)."""
    cmd = [sys.executable, "-m", "fenestra", "render", "--scene", str(ifc), "--views", str(views), "--seed",
           str(seed), "--renderer", "pyrender", "--out", str(out), "--look-per", "view", "--azimuth-max", "60"]
    line = subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=ROOT).stdout.strip().splitlines()[-1]
    return Path(line.split(":")[0])


def evaluable(w: dict, min_px: float = 12.0) -> bool:
    q = np.asarray(w["corners_px"], float)
    sides = np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1)
    return w["visible_fraction"] >= 0.9 and all(w["corner_visible"]) and sides.min() >= min_px


def full_mask(det, shape) -> np.ndarray:
    m = np.zeros(shape, bool)
    crop = np.asarray(det.mask, bool)
    (x0, y0), (h, w) = det.origin, crop.shape
    m[y0:y0 + h, x0:x0 + w] = crop[:shape[0] - y0, :shape[1] - x0]
    return m


def score_view(view, dets) -> dict:
    """found / evaluable / merged counts of one view's detections."""
    inst = view.instances
    windows = [w for w in view.meta["windows"] if evaluable(w)]
    masks = [full_mask(d, inst.shape) for d in dets]
    found, merged = 0, 0
    for w in windows:
        g = inst == w["instance_id"]
        ious = [float((g & m).sum()) / max(1, (g | m).sum()) for m in masks]
        found += bool(ious) and max(ious) >= 0.5
    for m in masks:
        covered = sum((m & (inst == w["instance_id"])).sum() >= 0.5 * (inst == w["instance_id"]).sum() for w in windows)
        merged += covered >= 2
    return {"evaluable": len(windows), "found": int(found), "merged_detections": int(merged)}


def measure(detectors: list[str], seeds: list[int], views: int, out: Path) -> dict:
    from fenestra.pipeline.detectors import detect  # noqa: PLC0415
    from fenestra.rendered_view import read_view  # noqa: PLC0415
    from fenestra.scenes.authored import write_plan  # noqa: PLC0415

    ifc = out / "adjacent-strip.ifc"
    write_plan(strip_plan(), ifc)
    res: dict = {}
    for seed in seeds:
        ds = render(ifc, seed, views, out / "renders")
        for name in detectors:
            tot = {"evaluable": 0, "found": 0, "merged_detections": 0}
            for vd in sorted((ds / "views").iterdir()):
                v = read_view(vd)
                s = score_view(v, detect(name, v.image))
                tot = {k: tot[k] + s[k] for k in tot}
            res.setdefault(name, {})[seed] = tot
            print(f"{name} seed {seed}: {tot}", flush=True)
    return res


def table(res: dict) -> str:
    lines = ["| detector | seed | evaluable windows | found | merged detections |", "|---|---|---|---|---|"]
    for name, per in res.items():
        for seed, t in sorted(per.items()):
            rate = t["found"] / t["evaluable"] if t["evaluable"] else float("nan")
            lines.append(f"| {name} | {seed} | {t['evaluable']} | {100 * rate:.0f} % | {t['merged_detections']} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--detectors", default="default,quadnet")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "adjacent-strip")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="adjacent-strip")
    a = ap.parse_args()
    res = measure(a.detectors.split(","), [int(s) for s in a.seeds.split(",")], a.views, a.out)
    text = (f"<!-- `python tools/adjacent_strip.py {' '.join(sys.argv[1:])}` -->\n"
            "The adjacent-strip test house (nine 1.0 x 2.3 m windows 0.2 m apart, eight 0.6 x 1.4 m windows "
            f"0.1 m apart; {a.views} views per seed, a look per view):\n\n" + table(res))
    print(text)
    if a.json is not None:
        from fenestra.files import write_json  # noqa: PLC0415

        write_json(a.json, {"views": a.views, "results": {n: {str(s): t for s, t in p.items()} for n, p in res.items()}})
    if a.doc is not None:
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)


if __name__ == "__main__":
    main()
