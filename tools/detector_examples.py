"""Small example overlays for the model card: the worst held-out views of a detector.

    .venv/bin/python tools/detector_examples.py --data out/detector-data/heldout-pyrender --out DIR [-n 3] [--weights W]

Per view: each ground-truth window's best mask IoU with any detection (score >= 0.5); the views
with the lowest worst-window IoU are drawn (ground truth green, detections red), 320 px wide.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from fenestra.pipeline.detectors import detect  # noqa: E402
from fenestra.images import read_image, read_instances  # noqa: E402
from fenestra.training.dataset import find_datasets, list_views  # noqa: E402


def view_scores(name: str, data: Path, **opts) -> list[tuple[float, int, int, Path, Path]]:
    """(worst GT IoU, n_gt, n_det, image path, instances path) per view, worst first."""
    rows = []
    for d in find_datasets([data]):
        for v in list_views(d):
            img, inst = read_image(v.image), read_instances(v.instances)
            dets = detect(name, img, **opts)
            ious = []
            for k in np.unique(inst):
                if k == 0:
                    continue
                g = inst == k
                ious.append(max([(g & x.mask).sum() / (g | x.mask).sum() for x in dets], default=0.0))
            rows.append((min(ious, default=1.0), len(ious), len(dets), v.image, v.instances))
    return sorted(rows, key=lambda r: r[0])


def draw(name: str, image_path: Path, inst_path: Path, out: Path, width: int = 320, **opts) -> None:
    """Overlay: ground-truth outlines green, detected mask outlines red."""
    img, inst = read_image(image_path), read_instances(inst_path)
    vis = img.copy()
    for k in np.unique(inst):
        if k:
            c, _ = cv2.findContours((inst == k).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
            cv2.drawContours(vis, c, -1, (0, 255, 0), 2)
    for d in detect(name, img, **opts):
        c, _ = cv2.findContours(d.mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(vis, c, -1, (255, 0, 0), 1)
    s = width / vis.shape[1]
    vis = cv2.resize(vis, (width, round(vis.shape[0] * s)), interpolation=cv2.INTER_AREA)
    out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out), cv2.cvtColor(vis, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 80])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--detector", default="default")
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("-n", type=int, default=3)
    ap.add_argument("--weights", type=Path, help="weights file (default: the detector's shipped one)")
    a = ap.parse_args()
    opts = {"weights": a.weights} if a.weights else {}
    rows = view_scores(a.detector, a.data, **opts)
    ious = np.array([r[0] for r in rows])
    print(f"{len(rows)} views; worst-window IoU per view: median {np.median(ious):.3f}, "
          f"views with a window under IoU 0.5: {(ious < 0.5).sum()}, "
          f"views with >= 2 more detections than windows: {sum(r[2] >= r[1] + 2 for r in rows)}")
    for i, (iou, ngt, ndet, ip, sp) in enumerate(rows[:a.n]):
        out = a.out / f"worst{i + 1}_{ip.parent.parent.parent.name[:20]}_{ip.parent.name}.jpg"
        draw(a.detector, ip, sp, out, **opts)
        print(f"{out}: worst IoU {iou:.2f}, {ngt} windows, {ndet} detections")


if __name__ == "__main__":
    main()
