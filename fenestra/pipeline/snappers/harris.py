"""``harris``: the paper's snapping: move each corner to the nearest Harris corner.

In a (2r+1)^2 window around each quad corner, compute the Harris response (``cv2.cornerHarris``),
keep its local maxima (3x3) above ``rel_threshold`` times the window's largest response, and move
the corner to the maximum nearest the window centre (the input corner); with no maximum the corner
stays. Integer pixel positions, as the paper. The paper notes it can snap to window sills: any
strong corner near the void's corner wins if it is nearer.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fenestra.pipeline.snappers.base import Snapper, check_inputs


@dataclass(frozen=True)
class HarrisParams:
    """half_window_px: r, the search window's half side; block_size, ksize, k: cv2.cornerHarris;
    rel_threshold: a maximum must exceed this fraction of the window's largest response."""

    half_window_px: int = 8
    block_size: int = 3
    ksize: int = 3
    k: float = 0.04
    rel_threshold: float = 0.1


def harris_corners(g: np.ndarray, centre: np.ndarray, p: HarrisParams) -> np.ndarray:
    """Harris local maxima (M, 2) px (x, y) within r of ``centre`` (2,) in float32 image g (H, W)."""
    H, W = g.shape
    r = p.half_window_px
    m = r + p.block_size + p.ksize  # margin so the response inside the window is unaffected by the crop
    cx, cy = int(round(centre[0])), int(round(centre[1]))
    x0, y0, x1, y1 = max(cx - m, 0), max(cy - m, 0), min(cx + m + 1, W), min(cy + m + 1, H)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return np.zeros((0, 2))
    resp = cv2.cornerHarris(np.ascontiguousarray(g[y0:y1, x0:x1]), p.block_size, p.ksize, p.k)
    ys, xs = np.mgrid[y0:y1, x0:x1]
    in_win = (np.abs(xs - cx) <= r) & (np.abs(ys - cy) <= r)
    if not in_win.any():  # the corner lies more than r outside the image: nothing to snap to
        return np.zeros((0, 2))
    peak = resp[in_win].max()
    if peak <= 0:
        return np.zeros((0, 2))
    is_max = (resp == cv2.dilate(resp, np.ones((3, 3), np.uint8))) & (resp > p.rel_threshold * peak) & in_win
    return np.stack([xs[is_max], ys[is_max]], axis=1).astype(np.float64)


def snap_harris(gray: np.ndarray, quad: np.ndarray, params: HarrisParams = HarrisParams()) -> tuple[np.ndarray, dict]:
    """Move each corner to the nearest thresholded Harris maximum in its window (else keep it)."""
    g, q = check_inputs(gray, quad)
    out, moved = q.copy(), []
    for i, c in enumerate(q):
        cand = harris_corners(g, c, params)
        if len(cand):
            out[i] = cand[np.argmin(np.linalg.norm(cand - c, axis=1))]
        moved.append(bool(len(cand)))
    return out, {"moved": moved}


HARRIS = Snapper("harris", snap_harris, HarrisParams, test_median_px=2.0,
                  description="nearest Harris corner, the paper's")
