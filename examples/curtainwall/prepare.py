"""Re-create this example from the Glass Curtain Wall Installation Dataset (CC BY 4.0, see README.md).

    python examples/curtainwall/prepare.py SRC_DIR [--photos 017 086] [--scale 0.5] [--min-area-px 20000]

SRC_DIR holds the dataset's ``images/imgNNN.png`` (distorted, as taken) and ``masks/maskNNN.png``
(RGBA, already undistorted; glass = pure blue, alpha >= 128). Writes beside this file:

- ``imgNNN.jpg``: the photo as taken (lens distortion still in it), resized by ``scale``
  (cv2.INTER_AREA), JPEG quality 92.
- ``panesNNN.png``: 16-bit instance map in the *undistorted* frame at the same size: one id per
  4-connected component of the glass mask (resized with INTER_AREA, then thresholded at 0.5),
  numbered left-to-right then top-to-bottom; components that touch the image border (panes cut
  by the frame) or cover fewer than ``min_area_px`` full-resolution pixels are dropped.
- ``K.json``: the dataset's calibration scaled to the photo size. Pixel centres at integers, so
  fx' = s fx, fy' = s fy, c' = (c + 0.5) s - 0.5; the distortion coefficients act on normalised
  coordinates and do not change with the image size.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

# Calibration from the dataset's user guide (1536 x 2048 px, OpenCV, pixel centres at integers).
FX, FY, CX, CY = 1821.04993399032, 1817.92066001349, 740.82871031754, 1018.94855509992
DISTORTION = [-0.1552775701035, 0.0472686081157939, 0.0, 0.0, 0.0]


def scaled_K(s: float) -> list[list[float]]:
    """3x3 K for the photo resized by s (pixel-centre convention)."""
    return [[FX * s, 0.0, (CX + 0.5) * s - 0.5], [0.0, FY * s, (CY + 0.5) * s - 0.5], [0.0, 0.0, 1.0]]


def glass_mask(rgba: np.ndarray) -> np.ndarray:
    """(H, W) bool: the dataset's glass label (BGRA (255, 0, 0, alpha >= 128) as cv2 reads it)."""
    b, g, r, a = (rgba[..., i] for i in range(4))
    return (b == 255) & (g == 0) & (r == 0) & (a >= 128)


def pane_instances(glass: np.ndarray, scale: float, min_area_px: int) -> np.ndarray:
    """(H', W') uint16 instance map of the whole panes, at ``scale`` (see the module docstring)."""
    H, W = glass.shape
    size = (round(W * scale), round(H * scale))
    g = glass.astype(np.float32)
    if scale != 1.0:
        g = cv2.resize(g, size, interpolation=cv2.INTER_AREA)
    g = (g >= 0.5).astype(np.uint8)
    n, lab, st, cen = cv2.connectedComponentsWithStats(g, connectivity=4)
    h, w = g.shape
    keep = [i for i in range(1, n)
            if st[i, 0] > 0 and st[i, 1] > 0 and st[i, 0] + st[i, 2] < w and st[i, 1] + st[i, 3] < h
            and st[i, 4] >= min_area_px * scale**2]
    # Reading order: rows of panes top to bottom (pane height >> row jitter), then left to right.
    row_h = 0.5 * np.median([st[i, 3] for i in keep]) if keep else 1.0
    keep.sort(key=lambda i: (round(cen[i, 1] / row_h), cen[i, 0]))
    out = np.zeros((h, w), np.uint16)
    for k, i in enumerate(keep, 1):
        out[lab == i] = k
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("src", type=Path)
    ap.add_argument("--photos", nargs="+", default=["017", "086"])
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--min-area-px", type=int, default=20000)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    for n in a.photos:
        img = cv2.imread(str(a.src / "images" / f"img{n}.png"), cv2.IMREAD_COLOR)
        rgba = cv2.imread(str(a.src / "masks" / f"mask{n}.png"), cv2.IMREAD_UNCHANGED)
        if img is None or rgba is None or rgba.ndim != 3 or rgba.shape[2] != 4:
            raise SystemExit(f"cannot read photo/mask {n} under {a.src}")
        if a.scale != 1.0:
            img = cv2.resize(img, (round(img.shape[1] * a.scale), round(img.shape[0] * a.scale)),
                             interpolation=cv2.INTER_AREA)
        cv2.imwrite(str(a.out / f"img{n}.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 92])
        inst = pane_instances(glass_mask(rgba), a.scale, a.min_area_px)
        cv2.imwrite(str(a.out / f"panes{n}.png"), inst)
        print(f"img{n}.jpg {img.shape[1]}x{img.shape[0]}, panes{n}.png: {int(inst.max())} panes")
    rows = ",\n        ".join(json.dumps(r) for r in scaled_K(a.scale))
    note = ("Glass Curtain Wall Installation Dataset user guide calibration (1536x2048 px), "
            f"scaled by {a.scale:g}: f' = s f, c' = (c + 0.5) s - 0.5")
    (a.out / "K.json").write_text(
        f'{{\n  "K": [{rows}],\n  "distortion": {json.dumps(DISTORTION)},\n'
        f'  "width": {round(1536 * a.scale)},\n  "height": {round(2048 * a.scale)},\n'
        f'  "source": {json.dumps(note)}\n}}\n')


if __name__ == "__main__":
    main()
