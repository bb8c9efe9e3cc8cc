"""What detectors cost per photo side by side: the same photos, the same threads, in turn.

    .venv/bin/python tools/cost_side_by_side.py [--detectors default,quadnet] [--gate quadnet] \
        [--photos 30] [--repeats 3] [--threads 2] [--doc fenestra/pipeline/models/README.md --block quadnet-cost]

The photos and their preparation are tools/detector_cost.py's (the first ``--photos`` validation
photos of spb_facades/train, never trained on, at a 640 px long side). Each photo is detected
``--repeats`` times by ``detect(NAME)`` of each detector in turn, after a warm-up; per detector the
median over photos of each photo's median wall time, and its ratio to the first detector's (the
machine is shared: the ratio is the steadier figure). ``--gate NAME``: exit 1 when that detector's
median misses tools/detector_cost.TARGET_DETECT_MS; 2 without the photos.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tools.detector_cost import SPB, TARGET_DETECT_MS, load_photo  # noqa: E402


def side_by_side(photos: list, names: list[str], repeats: int) -> dict[str, list[float]]:
    """{detector: [each photo's median wall time over ``repeats``, ms]}, the detectors run in turn
    on each photo after one warm-up each."""
    from fenestra.pipeline.detectors import detect  # noqa: PLC0415

    for n in names:
        detect(n, photos[0])  # warm-up: weights loaded, caches filled
    times: dict[str, list[float]] = {n: [] for n in names}
    for image in photos:
        for n in names:
            reps = []
            for _ in range(repeats):
                t = time.perf_counter()
                detect(n, image)
                reps.append(1e3 * (time.perf_counter() - t))
            times[n].append(statistics.median(reps))
    return times


def markdown(times: dict[str, list[float]], n_photos: int, threads: int, repeats: int, gate: str | None) -> str:
    """The block's text: each detector's median (and ratio to the first), the slowest photo, the gate's verdict."""
    med = {n: statistics.median(v) for n, v in times.items()}
    first = next(iter(med))
    parts = [f"`{n}` **{m:.0f} ms**" + ("" if n == first else f" (x{m / med[first]:.2f})") for n, m in med.items()]
    text = (f"<!-- `python tools/cost_side_by_side.py {' '.join(sys.argv[1:])}` -->\n"
            f"`detect(NAME, image)` on the first {n_photos} spb validation photos at a 640 px long side, "
            f"{threads} torch threads, median over photos of each photo's median over {repeats} repeats: "
            + ", ".join(parts) + ".")
    if gate is not None:
        text += (f" Slowest photo of `{gate}`: {max(times[gate]):.0f} ms. Target <= {TARGET_DETECT_MS:.0f} ms: "
                 f"**{'met' if med[gate] <= TARGET_DETECT_MS else 'missed'}**.")
    return text + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--detectors", default="default,quadnet", help="comma-separated registry names, the first the reference")
    ap.add_argument("--gate", default=None, help="the detector held to the cost target (exit 1 when missed)")
    ap.add_argument("--spb", type=Path, default=SPB)
    ap.add_argument("--photos", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="quadnet-cost")
    a = ap.parse_args()
    names = [n.strip() for n in a.detectors.split(",") if n.strip()]
    if not (a.spb / "train").is_dir():
        print(f"error: no spb photos at {a.spb / 'train'}")
        raise SystemExit(2)
    if a.gate is not None and a.gate not in names:
        print(f"error: --gate {a.gate!r} is not one of --detectors {names}")
        raise SystemExit(2)
    from fenestra.pipeline.detectors import set_cpu_threads  # noqa: PLC0415
    from fenestra.training.dataset import real_box_photos  # noqa: PLC0415

    set_cpu_threads(a.threads)
    photos = [load_photo(p) for p in real_box_photos(a.spb / "train", "val")[:a.photos]]
    times = side_by_side(photos, names, a.repeats)
    text = markdown(times, len(photos), a.threads, a.repeats, a.gate)
    print(text)
    if a.doc is not None:
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)
    raise SystemExit(1 if a.gate is not None and statistics.median(times[a.gate]) > TARGET_DETECT_MS else 0)


if __name__ == "__main__":
    main()
