"""CPU seconds of `fenestra reconstruct PHOTO` (no intrinsics) per photo, beside issue 35's targets.

    .venv/bin/python tools/photo_speed.py [--transforms native,12mp,12mp-q80] [--limit N] \
        [--json docs/results/photo_speed.json] [--doc docs/performance.md --block photo-speed]

Inputs: the bundled curtain-wall photos (data/real/curtainwall/images) and, when present, the St
Petersburg test photos (../shared/real/spb_facades/images, never copied into the repository), each
through every transform of ``--transforms`` (:data:`TRANSFORMS`: ``native`` as it is; ``12mp``
resized to 12 megapixels at its aspect ratio, Lanczos; ``12mp-q80`` the same saved as JPEG quality
80, the others at 95; ``12mp-gray``, ``12mp-mirror``; ``crop10`` the middle 80 % of each side, then
12 MP), written to a temporary folder. Each is reconstructed in its own subprocess (``python -m fenestra reconstruct
PHOTO --out DIR``: the CLI's defaults, no --K, so the focal chain runs) and its CPU time is the
child's user + system time (``resource.getrusage(RUSAGE_CHILDREN)``, threads included). Printed:
one row per photo (CPU-s, wall s, K source, focal px, windows), then the median over the 12 MP
inputs and the maximum over all, beside the targets (:data:`TARGET_MEDIAN_12MP_CPU_S`,
:data:`TARGET_MAX_CPU_S`). Exit status 1 when a target is missed or a run failed.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

CURTAIN = ROOT / "data" / "real" / "curtainwall" / "images"
SPB = (ROOT.parent / "shared" / "real" / "spb_facades" / "images", ROOT.parent / "shared" / "real" / "spb_facades" / "test" / "images")
TARGET_MEDIAN_12MP_CPU_S = 10.0  # issue 35, item 6: a 12-megapixel photo, median
TARGET_MAX_CPU_S = 30.0  # issue 35, item 6: no photo over this
MEGAPIXELS = 12_000_000


def _resized(im, pixels: int = MEGAPIXELS):
    """A PIL image resized (Lanczos) to about ``pixels`` pixels at its aspect ratio."""
    from PIL import Image  # noqa: PLC0415

    f = (pixels / (im.width * im.height)) ** 0.5
    return im.resize((round(im.width * f), round(im.height * f)), Image.LANCZOS)


def _crop10(im):
    """The middle 80 % of each side (10 % off every edge)."""
    w, h = im.size
    return im.crop((w // 10, h // 10, w - w // 10, h - h // 10))


# name -> (make the image from the RGB original, JPEG quality: 95 as a camera writes, 80 a re-save)
TRANSFORMS = {
    "native": (lambda im: im, 95),
    "12mp": (_resized, 95),
    "12mp-q80": (_resized, 80),
    "12mp-gray": (lambda im: _resized(im).convert("L").convert("RGB"), 95),
    "12mp-mirror": (lambda im: _resized(im).transpose(0), 95),  # 0: Image.FLIP_LEFT_RIGHT
    "crop10": (lambda im: _resized(_crop10(im)), 95),
}


def sources(spb: Path | None = None) -> list[Path]:
    """The photos: the bundled curtain-wall ones, then the St Petersburg test photos (``spb``, else
    the first of :data:`SPB` that exists) when present."""
    spb = spb if spb is not None else next((d for d in SPB if d.is_dir()), None)
    return sorted(CURTAIN.glob("*.jpg")) + ([] if spb is None else sorted(spb.glob("*.jpg")))


def make_input(photo: Path, transform: str, folder: Path) -> Path:
    """``photo`` through ``transform`` (:data:`TRANSFORMS`), written into ``folder``; its path."""
    from PIL import Image  # noqa: PLC0415

    make, quality = TRANSFORMS[transform]
    with Image.open(photo) as im:
        out = make(im.convert("RGB"))
    path = folder / f"{photo.stem}-{transform}.jpg"
    out.save(path, quality=quality)
    return path


def run_one(path: Path, out: Path) -> dict:
    """Reconstruct ``path`` into ``out`` in a subprocess: CPU-s (user + sys), wall s, return code,
    and what windows.json says of the focal length and the windows."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "fenestra", "reconstruct", str(path), "--out", str(out)],
                       capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    row = {"cpu_s": round(cpu, 2), "wall_s": round(wall, 2), "rc": p.returncode}
    found = next(out.rglob("windows.json"), None)
    if found is not None:
        doc = json.loads(found.read_text())
        K = doc.get("K_source", {})
        row.update(k_source=K.get("source"), focal_px=K.get("focal_px"), windows=len(doc.get("windows", [])))
    if p.returncode:
        row["error"] = (p.stderr or p.stdout).strip().splitlines()[-1:] or [""]
    return row


def measure(transforms: list[str], photos: list[Path], keep: Path | None) -> list[dict]:
    """One row per (photo, transform): photo, transform, size [W, H], then :func:`run_one`'s."""
    from PIL import Image  # noqa: PLC0415

    rows = []
    with tempfile.TemporaryDirectory(prefix="photo-speed-") as tmp:
        work = Path(keep or tmp)
        work.mkdir(parents=True, exist_ok=True)
        for photo in photos:
            for t in transforms:
                path = make_input(photo, t, work)
                with Image.open(path) as im:
                    size = list(im.size)
                row = {"photo": photo.name, "transform": t, "size": size,
                       **run_one(path, work / f"out-{path.stem}")}
                print(json.dumps(row), flush=True)
                rows.append(row)
    return rows


def verdict(rows: list[dict]) -> dict:
    """The median CPU-s over the 12 MP inputs and the maximum over all, with the targets and
    whether each is met (and whether every run succeeded)."""
    import numpy as np  # noqa: PLC0415

    big = [r["cpu_s"] for r in rows if r["size"][0] * r["size"][1] >= 0.9 * MEGAPIXELS]
    med = float(np.median(big)) if big else None
    worst = max((r["cpu_s"] for r in rows), default=None)
    return {"median_12mp_cpu_s": med, "max_cpu_s": worst, "target_median_12mp_cpu_s": TARGET_MEDIAN_12MP_CPU_S,
            "target_max_cpu_s": TARGET_MAX_CPU_S, "median_met": med is not None and med <= TARGET_MEDIAN_12MP_CPU_S,
            "max_met": worst is not None and worst <= TARGET_MAX_CPU_S, "all_ran": all(r["rc"] == 0 for r in rows)}


def markdown(rows: list[dict], v: dict, command: str) -> str:
    """The generated block: the command, the verdict beside the targets, one row per photo."""
    load = " / ".join(f"{x:.1f}" for x in os.getloadavg())
    ok = lambda met: "met" if met else "**missed**"  # noqa: E731
    lines = [f"Generated by `{command}` ({os.cpu_count()} CPUs, load average {load} at the end: CPU seconds "
             "grow when other jobs share the cores). CPU-s: user + system time of one `fenestra reconstruct "
             "PHOTO --out DIR` process (no --K: the focal chain runs), threads included.", "",
             f"Median over the 12-megapixel inputs: **{v['median_12mp_cpu_s']:.1f} CPU-s** (target <= "
             f"{v['target_median_12mp_cpu_s']:g}: {ok(v['median_met'])}); slowest photo: **{v['max_cpu_s']:.1f} CPU-s** "
             f"(target <= {v['target_max_cpu_s']:g}: {ok(v['max_met'])}).", "",
             "| photo | transform | size | CPU-s | wall s | K source | focal px | windows |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        f = r.get("focal_px")
        lines.append(f"| {r['photo']} | {r['transform']} | {r['size'][0]}×{r['size'][1]} | {r['cpu_s']:.1f} | "
                     f"{r['wall_s']:.1f} | {r.get('k_source', 'failed')} | {'-' if f is None else f'{f:.0f}'} | "
                     f"{r.get('windows', '-')} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--transforms", default="native,12mp,12mp-q80", help=f"comma-separated, of {', '.join(TRANSFORMS)}")
    ap.add_argument("--limit", type=int, default=None, help="only the first N photos")
    ap.add_argument("--spb", type=Path, default=None, help="folder of the St Petersburg test photos (default: ../shared/real/spb_facades/images)")
    ap.add_argument("--only", default=None, help="comma-separated photo names (e.g. img042.jpg,img_185.jpg)")
    ap.add_argument("--keep", type=Path, default=None, help="write inputs and outputs here (default: a temporary folder)")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows and verdict (e.g. docs/results/photo_speed.json)")
    ap.add_argument("--doc", type=Path, default=None, help="write the table into this Markdown file's block")
    ap.add_argument("--block", default="photo-speed")
    a = ap.parse_args()
    transforms = a.transforms.split(",")
    unknown = sorted(set(transforms) - set(TRANSFORMS))
    if unknown:
        ap.error(f"unknown transform(s) {unknown}; known: {list(TRANSFORMS)}")
    photos = [p for p in sources(a.spb) if a.only is None or p.name in a.only.split(",")][:a.limit]
    if not photos:
        ap.error("no photos to measure")
    rows = measure(transforms, photos, a.keep)
    v = verdict(rows)
    command = f"python tools/photo_speed.py {' '.join(sys.argv[1:])}".strip()
    text = markdown(rows, v, command)
    print(text)
    if a.json is not None:
        from fenestra.files import write_json  # noqa: PLC0415

        write_json(a.json, {"command": command, "cpus": os.cpu_count(), "verdict": v, "rows": rows})
    if a.doc is not None:
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)
    sys.exit(0 if v["median_met"] and v["max_met"] and v["all_ran"] else 1)


if __name__ == "__main__":
    main()
