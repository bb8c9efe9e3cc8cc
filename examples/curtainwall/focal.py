"""Focal length with K withheld on the curtain-wall photos, against the dataset's calibration.

    .venv/bin/python -m examples.curtainwall.focal SRC_DIR [--photos 017 020 042 056 086] [--scale 0.5]

SRC_DIR as for prepare.py (``masks/maskNNN.png``, already undistorted). The whole glass panes
(prepare.pane_instances) give mask quads (no snapping: the photos themselves still carry lens
distortion); pipeline.walls.fit_walls_focal estimates f with the principal point at the image
centre. Prints, per photo, the panes used, f +- sd and the error against the calibrated
sqrt(fx fy) (scaled), or why f was unobservable. The strategies with façade lines (``+lines``) are
left out: their segments would come from the photo, which still carries lens distortion (and
undistorting it needs the K that is withheld here).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from prepare import FX, FY, glass_mask, pane_instances  # noqa: E402

from fenestra.errors import PipelineError  # noqa: E402
from fenestra.pipeline.detectors.oracle import detections_from_instance_map  # noqa: E402
from fenestra.pipeline.reconstruct import fit_quads  # noqa: E402
from fenestra.pipeline.walls import WALL_STRATEGIES, fit_walls_focal  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("src", type=Path)
    ap.add_argument("--photos", nargs="+", default=["017", "020", "042", "056", "086"])
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--min-area-px", type=int, default=20000)
    a = ap.parse_args()
    f_true = float(np.sqrt(FX * FY)) * a.scale
    for n in a.photos:
        rgba = cv2.imread(str(a.src / "masks" / f"mask{n}.png"), cv2.IMREAD_UNCHANGED)
        inst = pane_instances(glass_mask(rgba), a.scale, a.min_area_px).astype(np.int32)
        fits = fit_quads(detections_from_instance_map(inst), image_shape=inst.shape)
        quads = np.array([f.result.quad for f in fits if f.result.quad is not None]).reshape(-1, 4, 2)
        for name, params in WALL_STRATEGIES.items():
            if params.lines:
                continue
            try:
                fit = fit_walls_focal(quads, inst.shape, 1.0, params)[2]
                sd = float(np.sqrt(fit.cov[-1, -1]))
                print(f"img{n} {name:8s} {len(quads)} panes  f = {fit.focal_px:7.1f} +- {sd:5.1f} px  "
                      f"(calibrated {f_true:.1f}: {100 * (fit.focal_px / f_true - 1):+.2f} %)")
            except PipelineError as e:
                print(f"img{n} {name:8s} {len(quads)} panes  no f: {e}")


if __name__ == "__main__":
    main()
