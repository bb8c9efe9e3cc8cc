"""What the quad head costs per photo beside the default detector (issue 46: <= 300 ms at 640 px, 2 threads).

    .venv/bin/python tools/quadnet_cost.py [--photos 30] [--repeats 3] [--threads 2] \
        [--doc fenestra/pipeline/models/README.md --block quadnet-cost]

The photos and their preparation are tools/detector_cost.py's (the first ``--photos`` validation
photos of spb_facades/train, never trained on, at a 640 px long side). Each photo is detected
``--repeats`` times by ``detect("default")`` and ``detect("quadnet")`` in turn, after a warm-up;
per detector the median over photos of each photo's median wall time, and the ratio of the two
medians (the machine is shared: the ratio is the steadier figure). Exit 1 when quadnet's median
misses the target; 2 without the photos.
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spb", type=Path, default=SPB)
    ap.add_argument("--photos", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="quadnet-cost")
    a = ap.parse_args()
    if not (a.spb / "train").is_dir():
        print(f"error: no spb photos at {a.spb / 'train'}")
        raise SystemExit(2)
    from fenestra.pipeline.detectors import detect, set_cpu_threads  # noqa: PLC0415
    from fenestra.training.dataset import real_box_photos  # noqa: PLC0415

    set_cpu_threads(a.threads)
    photos = [load_photo(p) for p in real_box_photos(a.spb / "train", "val")[:a.photos]]
    names = ("default", "quadnet")
    for n in names:
        detect(n, photos[0])  # warm-up: weights loaded, caches filled
    times: dict[str, list[float]] = {n: [] for n in names}
    for image in photos:
        for n in names:
            reps = []
            for _ in range(a.repeats):
                t = time.perf_counter()
                detect(n, image)
                reps.append(1e3 * (time.perf_counter() - t))
            times[n].append(statistics.median(reps))
    med = {n: statistics.median(v) for n, v in times.items()}
    text = (f"<!-- `python tools/quadnet_cost.py {' '.join(sys.argv[1:])}` -->\n"
            f"`detect(NAME, image)` on the first {len(photos)} spb validation photos at a 640 px long side, "
            f"{a.threads} torch threads, median over photos of each photo's median over {a.repeats} repeats: "
            f"`default` **{med['default']:.0f} ms**, `quadnet` **{med['quadnet']:.0f} ms** "
            f"(x{med['quadnet'] / med['default']:.2f}); slowest photo {max(times['quadnet']):.0f} ms. "
            f"Target <= {TARGET_DETECT_MS:.0f} ms: **{'met' if med['quadnet'] <= TARGET_DETECT_MS else 'missed'}**.\n")
    print(text)
    if a.doc is not None:
        from fenestra.reports.markdown import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)
    raise SystemExit(0 if med["quadnet"] <= TARGET_DETECT_MS else 1)


if __name__ == "__main__":
    main()
