"""Overlay PNG: the pipeline's quads and the reprojected 3D window drawn on the photo.

Colours (RGB, like the image): mask-fit quad yellow, snapped quad magenta (corner labels TL TR BR BL), reprojected
3D window green (void outline at the facade and the frame's back outline, depth edges between),
window axes x red, y green, z blue (length half the window height). Failed windows get their
available quads and a red "failed" note.
"""
from __future__ import annotations

import cv2
import numpy as np

from fenestra.checks import check_image, check_K
from fenestra.conventions import CORNER_NAMES, project
from pipeline.export.geometry import place
from pipeline.types import WindowResult

COLOURS = {"mask": (255, 220, 0), "snapped": (255, 0, 255), "reprojected": (0, 230, 0),
           "x": (255, 0, 0), "y": (0, 200, 0), "z": (0, 80, 255), "failed": (255, 0, 0)}
_SHIFT = 4  # fractional bits for sub-pixel drawing


def _pts(px: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(px, dtype=np.float64) * (1 << _SHIFT)).astype(np.int32)


def _segment(img, a, b, colour, thick):
    if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
        cv2.line(img, tuple(_pts(a)), tuple(_pts(b)), colour, thick, cv2.LINE_AA, _SHIFT)


def _poly(img, quad, colour, thick):
    cv2.polylines(img, [_pts(quad)], True, colour, thick, cv2.LINE_AA, _SHIFT)


def _text(img, s, at, colour, scale):
    at = tuple(int(round(v)) for v in at)
    cv2.putText(img, s, at, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), max(2, int(3 * scale)), cv2.LINE_AA)
    cv2.putText(img, s, at, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, max(1, int(scale)), cv2.LINE_AA)


def _draw_3d(img, K, result, thick, depth_m: float = 0.07):
    """Reprojected window box (facade outline, back outline, depth edges) and axes."""
    pw = place(result)
    if isinstance(pw, str):  # no usable pose: nothing to reproject
        return
    front = pw.void_corners()
    back = front - [0.0, 0.0, depth_m]
    P = np.concatenate([front, back])
    ok = pw.to_camera(P)[:, 2] > 1e-6
    px = project(K, pw.R, pw.t, P)
    for i in range(4):
        j = (i + 1) % 4
        for a, b in ((i, j), (4 + i, 4 + j), (i, 4 + i)):
            if ok[a] and ok[b]:
                _segment(img, px[a], px[b], COLOURS["reprojected"], thick)
    L = 0.5 * pw.height_m
    axes = np.array([[0, 0, 0], [L, 0, 0], [0, L, 0], [0, 0, L]], dtype=np.float64)
    ok = pw.to_camera(axes)[:, 2] > 1e-6
    apx = project(K, pw.R, pw.t, axes)
    for k, name in enumerate("xyz", start=1):
        if ok[0] and ok[k]:
            _segment(img, apx[0], apx[k], COLOURS[name], thick + 1)


def draw_overlay(image: np.ndarray, K: np.ndarray, results: list[WindowResult]) -> np.ndarray:
    """(H, W, 3) uint8 RGB copy of the RGB ``image`` with every result drawn on it."""
    img = check_image(image).copy()
    K = check_K(K)
    H, W = img.shape[:2]
    thick = max(1, int(round(min(H, W) / 400)))
    scale = max(0.35, min(H, W) / 1200)
    for r in results:
        if r.quad_mask is not None:
            _poly(img, r.quad_mask, COLOURS["mask"], thick)
        if r.quad_snapped is not None:
            q = np.asarray(r.quad_snapped, dtype=np.float64)
            _poly(img, q, COLOURS["snapped"], thick)
            centre = q.mean(axis=0)
            for name, c in zip(CORNER_NAMES, q):
                d = c - centre
                d = d / (np.linalg.norm(d) + 1e-9)
                _text(img, name, c + d * 14 * scale * 2 - [10 * scale, -5 * scale], COLOURS["snapped"], scale)
        _draw_3d(img, K, r, thick)
        anchor = next((np.asarray(q, dtype=np.float64).min(axis=0) for q in (r.quad_snapped, r.quad_mask)
                       if q is not None), np.array([10.0, 30.0 + 20 * r.index]))
        placed = place(r)
        problem = f"failed: {r.failure}" if r.failure else (f"skipped: {placed}" if isinstance(placed, str) else None)
        label = f"#{r.index} " + (problem or f"w/h={r.aspect_ratio:.3f}")
        _text(img, label[:60], anchor - [0, 8 * scale], COLOURS["failed"] if problem else (255, 255, 255), scale)
    y = int(20 * scale * 2)
    for name in ("mask", "snapped", "reprojected"):
        _text(img, {"mask": "mask-fit quad", "snapped": "snapped quad", "reprojected": "3D window"}[name],
              (8, y), COLOURS[name], scale)
        y += int(22 * scale * 2)
    return img
