"""Timing of the reconstruction stages (without detection): median ms per window, per stage.

    .venv/bin/python tools/pipeline_timing.py [--windows 40] [--snapper harris linefit ...] [--json out.json]

Synthetic photos (renders.quad_image: exact antialiased quads + noise, 640 x 480) with exact masks;
one warm-up pass, then the median of each stage's time over all windows, and the whole (sum).
Target: < 5 ms per window for the whole reconstruction.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the exact quad images (tests/quad_image.py)

from fenestra.conventions import PAPER, make_K  # noqa: E402
from fenestra.pipeline.reconstruct import STAGES, ReconstructConfig, reconstruct  # noqa: E402
from fenestra.pipeline.snappers import SNAPPERS  # noqa: E402
from fenestra.pipeline.types import Detection  # noqa: E402
from quad_image import pixel_centre_mask, render_window_image, view_window  # noqa: E402

SHAPE = (480, 640)


def make_views(n: int, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray, Detection]]:
    """n (image RGB, K, detection) triples of one window each."""
    K = make_K(800.0, 800.0, 319.5, 239.5)
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        sw = view_window(K, rng.uniform(0.6, 1.8), rng.uniform(0.8, 1.8), rng.uniform(-45, 45),
                         rng.uniform(-25, 25), rng.uniform(-10, 10), rng.uniform(5, 9),
                         tuple(rng.uniform(-80, 80, 2)))
        img = render_window_image(sw.corners_px, SHAPE, noise_sigma=2.0, seed=i)
        m = pixel_centre_mask(sw.corners_px, SHAPE)
        out.append((img, K, Detection(mask=m, box=np.zeros(4), score=1.0)))
    return out


def time_config(views, cfg: ReconstructConfig) -> dict[str, float]:
    """Median ms per window for each stage and for their sum."""
    for img, K, det in views[:3]:  # warm-up
        reconstruct(img, K, [det], cfg)
    rows = [reconstruct(img, K, [det], cfg)[0].timings_ms for img, K, det in views]
    med = {s: float(np.median([r.get(s, np.nan) for r in rows])) for s in STAGES}
    med["total"] = float(np.median([sum(r.values()) for r in rows]))
    return med


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=40)
    ap.add_argument("--snapper", nargs="*", default=sorted(SNAPPERS))
    ap.add_argument("--pose", default=PAPER.pose)
    ap.add_argument("--json", default=None, help="also write the numbers as JSON")
    a = ap.parse_args(argv)
    views = make_views(a.windows)
    results = {s: time_config(views, ReconstructConfig(snapper=s, pose=a.pose)) for s in a.snapper}
    print(f"{'snapper':<9}" + "".join(f"{s:>9}" for s in (*STAGES, "total")) + "   (median ms/window)")
    for s, med in results.items():
        print(f"{s:<9}" + "".join(f"{med[k]:9.3f}" for k in (*STAGES, "total")))
    doc = {"metadata": {"windows": a.windows, "image": list(SHAPE[::-1]), "pose": a.pose,
                        "numpy": np.__version__, "opencv": cv2.__version__, "python": platform.python_version(),
                        "cpus": __import__("os").cpu_count()},
           "results_ms": results}
    if a.json:
        with open(a.json, "w") as f:
            json.dump(doc, f, indent=2)
    return doc


if __name__ == "__main__":
    main()
