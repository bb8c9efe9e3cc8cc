"""Sim-to-real check of a detector on the real photos in /work/shared/real (see its README).

    python -m pipeline.detectors.realcheck [--detector default] [--real /work/shared/real] [--out out/real]

curtainwall/: photos are undistorted with their calibration, then compared with the glass masks
(panes = connected glass regions): pixel IoU of the union, and pane recall/precision at IoU 0.5.
spb_facades/: COCO bbox AP/AP50 against the YOLO window boxes (classes window=0 and win_ad=4).
Overlays go to --out (never into the repository: the spb photos' licence is unverified).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from pipeline.detectors import detect
from pipeline.detectors.dataset import read_image
from pipeline.detectors.evaluate import coco_stats

CURTAIN_K = np.array([[1821.04993399032, 0, 740.82871031754], [0, 1817.92066001349, 1018.94855509992], [0, 0, 1]])
CURTAIN_DIST = np.array([-0.1552775701035, 0.0472686081157939, 0, 0, 0])


def detect_resized(name: str, image: np.ndarray, long_side: int = 640, score_threshold: float = 0.5, **opts):
    """Run a detector on a copy resized to ``long_side`` px; masks/boxes back at full size."""
    H, W = image.shape[:2]
    s = long_side / max(H, W)
    small = cv2.resize(image, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA)
    out = []
    for d in detect(name, small, score_threshold=score_threshold, **opts):
        m = cv2.resize(d.mask.astype(np.uint8), (W, H), interpolation=cv2.INTER_NEAREST).astype(bool)
        if m.any():
            out.append((m, d.score))
    return out


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    u = (a | b).sum()
    return float((a & b).sum() / u) if u else 0.0


def _overlay(image: np.ndarray, masks: list[np.ndarray], path: Path, width: int = 480) -> None:
    vis = image.copy()
    for m in masks:
        vis[m] = (0.5 * vis[m] + 0.5 * np.array([255, 40, 40])).astype(np.uint8)
        cnts, _ = cv2.findContours(m.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(vis, cnts, -1, (255, 255, 0), max(1, image.shape[1] // 400))
    s = width / vis.shape[1]
    vis = cv2.resize(vis, (width, round(vis.shape[0] * s)), interpolation=cv2.INTER_AREA)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), cv2.cvtColor(vis, cv2.COLOR_RGB2BGR))


def curtainwall_check(folder: Path, detector: str = "default", out: Path | None = None, **opts) -> dict:
    """Pane recall/precision (IoU >= 0.5) and union IoU on the undistorted curtain-wall photos."""
    rows = []
    for img_path in sorted((folder / "images").glob("img*.png")):
        mask_path = folder / "masks" / img_path.name.replace("img", "mask")
        image = cv2.undistort(read_image(img_path), CURTAIN_K, CURTAIN_DIST)
        rgba = cv2.imread(str(mask_path), cv2.IMREAD_UNCHANGED)
        glass = (rgba[..., 0] == 255) & (rgba[..., 3] > 127)  # BGRA: blue = glass
        n, lab = cv2.connectedComponents(glass.astype(np.uint8), connectivity=4)
        panes = [lab == k for k in range(1, n) if (lab == k).sum() > 2000]
        dets = detect_resized(detector, image, **opts)
        masks = [m for m, _ in dets]
        found = sum(any(_iou(p, m) >= 0.5 for m in masks) for p in panes)
        correct = sum(any(_iou(p, m) >= 0.5 for p in panes) for m in masks)
        union = np.zeros_like(glass)
        for m in masks:
            union |= m
        rows.append({"image": img_path.name, "panes": len(panes), "detections": len(masks),
                     "pane_recall": found / max(1, len(panes)), "precision": correct / max(1, len(masks)),
                     "union_iou": _iou(union, glass)})
        if out is not None:
            _overlay(image, masks, out / f"curtainwall_{img_path.stem}.jpg")
    return {"per_image": rows, **{k: float(np.mean([r[k] for r in rows])) for k in
                                  ("pane_recall", "precision", "union_iou")}}


def spb_check(folder: Path, detector: str = "default", out: Path | None = None, **opts) -> dict:
    """COCO bbox AP/AP50 of detections against the YOLO window boxes (window, win_ad)."""
    images, anns, results = [], [], []
    for i, img_path in enumerate(sorted((folder / "images").glob("*.jpg"))):
        image = read_image(img_path)
        H, W = image.shape[:2]
        images.append({"id": i + 1, "width": W, "height": H, "file_name": img_path.name})
        for line in (folder / "labels" / (img_path.stem + ".txt")).read_text().split("\n"):
            if not line.strip():
                continue
            c, cx, cy, w, h = (float(v) for v in line.split())
            if int(c) in (0, 4):
                anns.append({"id": len(anns) + 1, "image_id": i + 1, "category_id": 1, "iscrowd": 0,
                             "bbox": [(cx - w / 2) * W, (cy - h / 2) * H, w * W, h * H], "area": w * W * h * H})
        dets = detect_resized(detector, image, score_threshold=0.05, **opts)
        for m, score in dets:
            ys, xs = np.nonzero(m)
            results.append({"image_id": i + 1, "category_id": 1, "score": score,
                            "bbox": [float(xs.min()), float(ys.min()), float(xs.max() - xs.min() + 1),
                                     float(ys.max() - ys.min() + 1)]})
        if out is not None:
            _overlay(image, [m for m, s in dets if s >= 0.5], out / f"spb_{img_path.stem}.jpg")
    gt = {"images": images, "annotations": anns, "categories": [{"id": 1, "name": "window"}]}
    stats = coco_stats(gt, results, "bbox")
    return {"n_images": len(images), "n_windows": len(anns), "n_det": len(results), "bbox": stats}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--detector", default="default")
    ap.add_argument("--weights", default=None)
    ap.add_argument("--real", type=Path, default=Path("/work/shared/real"))
    ap.add_argument("--out", type=Path, default=Path("out/real"))
    a = ap.parse_args()
    opts = {"weights": a.weights} if a.weights else {}
    res = {"curtainwall": curtainwall_check(a.real / "curtainwall", a.detector, a.out, **opts),
           "spb_facades": spb_check(a.real / "spb_facades", a.detector, a.out, **opts)}
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "realcheck.json").write_text(json.dumps(res, indent=2))
    print(json.dumps({"curtainwall": {k: v for k, v in res["curtainwall"].items() if k != "per_image"},
                      "spb_facades": res["spb_facades"]}, indent=2))


if __name__ == "__main__":
    main()
