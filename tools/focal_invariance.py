"""Is the vanishing-point focal length the same for the same photo? The focal chain of
``fenestra reconstruct`` (no intrinsics, the default method) on real photos as they are and as users
re-save them: a JPEG at quality 80, a copy at half the size, a mirror image.

    nice .venv/bin/python tools/focal_invariance.py --doc docs/experiments.md --block focal-invariance

Photos: the St Petersburg test photos (../shared/real/spb_facades/images, not shipped; left out with
a note when absent) and the bundled curtain-wall photos (data/real/curtainwall/images). Per photo
and copy: the vanishing points' answer (f px and its 90 % interval, or why there is none) and the
focal length the chain chose. A copy's focal length is compared at the original's scale (the half
size copy's doubled). Per copy of a photo whose original the vanishing points answer, the outcome:
``inside`` (the copy's vanishing points answer inside the original's interval), ``outside`` (they
answer outside it), ``refused`` (no answer on the copy); and for a photo whose original they do not
answer, ``answers`` where a copy gets one. Stable means every copy ``inside``, or no answer on the
original nor any copy.
"""
from __future__ import annotations

import argparse
import io
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SPB = ROOT.parent / "shared" / "real" / "spb_facades" / "images"
CURTAIN = ROOT / "data" / "real" / "curtainwall" / "images"
COPIES = ("jpeg q80", "half size", "mirror")  # how users re-save a photo
SCALE = {"jpeg q80": 1.0, "half size": 0.5, "mirror": 1.0}  # the copy's size over the original's


@dataclass(frozen=True)
class FocalRun:
    """One photo or copy through the chain: ``vp`` (f, lo, hi) px at the original's scale, or None
    with ``why``; ``chosen``: the chain's source and (f, lo, hi) px at the original's scale;
    warnings: the chain's (sources that disagree); cpu_s: CPU seconds."""

    photo: str
    copy: str
    vp: tuple[float, float, float] | None
    why: str
    chosen: tuple[str, float, float, float]
    warnings: tuple[str, ...]
    cpu_s: float


def copy_of(image: np.ndarray, copy: str) -> np.ndarray:
    """An (H, W, 3) uint8 RGB photo as a user's copy: re-saved as JPEG quality 80 (PIL), halved in
    each dimension (area averaging, OpenCV INTER_AREA), or mirrored left to right; "original": itself."""
    import cv2  # noqa: PLC0415
    from PIL import Image  # noqa: PLC0415

    if copy == "original":
        return image
    if copy == "jpeg q80":
        buf = io.BytesIO()
        Image.fromarray(image).save(buf, format="JPEG", quality=80)
        return np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB"))
    if copy == "half size":
        H, W = image.shape[:2]
        return cv2.resize(image, (round(W / 2), round(H / 2)), interpolation=cv2.INTER_AREA)
    if copy == "mirror":
        return np.ascontiguousarray(image[:, ::-1])
    raise ValueError(f"unknown copy {copy!r}; choose from {('original', *COPIES)}")


def focal_run(photo: Path, copy: str) -> FocalRun:
    """The focal chain of the CLI's default method on ``copy`` of ``photo`` (no EXIF: the copies
    have none, and the question is the vanishing points')."""
    from fenestra.images import read_image  # noqa: PLC0415
    from fenestra.pipeline.photo import PhotoOptions, method_of  # noqa: PLC0415
    from fenestra.pipeline.session import PhotoSession  # noqa: PLC0415

    t0 = time.process_time()
    image = copy_of(read_image(photo, "photo"), copy)
    r = PhotoSession(image).resolve(method_of(PhotoOptions(), False))
    back = 1.0 / SCALE.get(copy, 1.0)
    vp = next((e for e in r.estimates if e.source == "vanishing points"), None)
    def scaled(e):
        return (e.focal_px * back, e.interval_px[0] * back, e.interval_px[1] * back)

    return FocalRun(photo.name, copy, None if vp is None else scaled(vp), r.unavailable.get("vanishing points", ""),
                    (r.source, *scaled(r.chosen)), r.warnings, time.process_time() - t0)


def outcome(original: FocalRun, run: FocalRun) -> str:
    """A copy's vanishing-point answer against its original's: inside | outside | refused (the
    original answers); answers | none (it does not)."""
    if original.vp is None:
        return "none" if run.vp is None else "answers"
    if run.vp is None:
        return "refused"
    return "inside" if original.vp[1] <= run.vp[0] <= original.vp[2] else "outside"


def stable(outcomes: list[str]) -> bool:
    """Whether a photo's copies agree with it: all inside, or no answer anywhere."""
    return all(o == "inside" for o in outcomes) or all(o == "none" for o in outcomes)


def _vp_words(run: FocalRun) -> str:
    if run.vp is None:
        return "-"
    return f"{run.vp[0]:.0f} [{run.vp[1]:.0f}, {run.vp[2]:.0f}]"


def report(runs: dict[str, list[FocalRun]]) -> list[str]:
    """Markdown: one table row per photo (each copy's vanishing-point f px at the original's scale
    and its outcome; "warned": the chain warned that its sources disagree), then the counts of
    outcomes per copy and of stable photos."""
    lines = ["| photo | original: f px [90 %] | " + " | ".join(COPIES) + " | stable |",
             "|---|---|" + "---|" * len(COPIES) + "---|"]
    counts = {c: {} for c in COPIES}
    n_stable = 0
    for name, rs in runs.items():
        orig, copies = rs[0], rs[1:]
        outs = [outcome(orig, r) for r in copies]
        for c, o in zip(COPIES, outs):
            counts[c][o] = counts[c].get(o, 0) + 1
        n_stable += stable(outs)
        cells = [f"{_vp_words(r)} ({o}{', warned' if r.warnings else ''})" if r.vp is not None else o
                 for r, o in zip(copies, outs)]
        lines.append(f"| {name} | {_vp_words(orig) if orig.vp else 'none (' + orig.chosen[0] + ')'} | "
                     + " | ".join(cells) + f" | {'yes' if stable(outs) else 'no'} |")
    answered = sum(rs[0].vp is not None for rs in runs.values())
    lines += ["", f"{len(runs)} photos; the vanishing points answer on {answered} originals; stable: {n_stable} of "
              f"{len(runs)}. Per copy: " + "; ".join(
                  f"{c}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts[c].items())) for c in COPIES) + ".",
              f"CPU: {sum(r.cpu_s for rs in runs.values() for r in rs):.0f} s for {sum(len(rs) for rs in runs.values())} "
              "chains (detection included)."]
    return lines


def photos(spb: Path, curtain: Path) -> tuple[list[Path], list[str]]:
    """The photos to measure and notes on the folders left out."""
    out, notes = [], []
    for folder in (spb, curtain):
        found = sorted(p for p in folder.glob("*") if p.suffix.lower() in (".jpg", ".jpeg", ".png")) if folder.is_dir() else []
        if not found:
            notes.append(f"no photos in {folder}: left out")
        out += found
    return out, notes


def main(argv: list[str] | None = None) -> list[str]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spb", type=Path, default=SPB, help="the street photos' folder")
    ap.add_argument("--curtain", type=Path, default=CURTAIN, help="the curtain-wall photos' folder")
    ap.add_argument("--doc", type=Path, default=None, help="write the report into this Markdown file's block")
    ap.add_argument("--block", default="focal-invariance", help="the block's name (<!-- NAME:begin --> ... <!-- NAME:end -->)")
    a = ap.parse_args(argv)
    import torch  # noqa: PLC0415

    torch.set_num_threads(1)
    found, notes = photos(a.spb, a.curtain)
    if not found:
        raise SystemExit("error: no photos found: " + "; ".join(notes))
    runs = {}
    for p in found:
        name = f"{p.parent.parent.name}/{p.name}"
        runs[name] = [focal_run(p, c) for c in ("original", *COPIES)]
        print(f"{name}: " + "; ".join(f"{r.copy} {_vp_words(r)} {r.why}" for r in runs[name]), file=sys.stderr)
    args = " ".join(sys.argv[1:] if argv is None else argv)
    lines = [f"`python tools/{Path(__file__).name}{' ' + args if args else ''}` (the default method's focal chain, "
             "no EXIF; vanishing-point f px "
             "and 90 % interval at the original's scale; outcome against the original's interval)", "",
             *report(runs), *notes]
    text = "\n".join(lines) + "\n"
    print(text)
    if a.doc is not None:
        from fenestra.reports.markdown import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)
    return lines


if __name__ == "__main__":
    sys.exit(main() and 0)
