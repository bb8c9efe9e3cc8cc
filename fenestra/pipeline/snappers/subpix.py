"""``subpix``: OpenCV's ``cv2.cornerSubPix`` at each corner.

Iteratively moves each corner to the point where the image gradients in a window around it are
orthogonal to the vectors from the point (the least-squares corner of the local gradient field).
Good on sharp, isolated corners; pulled off by nearby texture (frames, sills) within the window.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fenestra.pipeline.snappers.base import Snapper, check_inputs, keep_if_far


@dataclass(frozen=True)
class SubpixParams:
    """half_window_px: cornerSubPix winSize (half side); max_iter, eps: stop criteria;
    max_move_px: a corner moving further than this keeps its input position."""

    half_window_px: int = 5
    max_iter: int = 40
    eps: float = 0.001
    max_move_px: float = 6.0


def snap_subpix(gray: np.ndarray, quad: np.ndarray, params: SubpixParams = SubpixParams()) -> tuple[np.ndarray, dict]:
    """Refine each corner with cv2.cornerSubPix (pixel centres at integers, as OpenCV)."""
    g, q = check_inputs(gray, quad)
    H, W = g.shape
    inside = (q[:, 0] >= 0) & (q[:, 0] <= W - 1) & (q[:, 1] >= 0) & (q[:, 1] <= H - 1)
    if not inside.any():
        return q.copy(), {"moved": [False] * 4}
    pts = q[inside].astype(np.float32).reshape(-1, 1, 2).copy()
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, params.max_iter, params.eps)
    r = params.half_window_px
    cv2.cornerSubPix(g, pts, (r, r), (-1, -1), crit)
    new = q.copy()
    new[inside] = pts.reshape(-1, 2)
    out, ok = keep_if_far(q, new, params.max_move_px)
    return out, {"moved": [bool(o and i) for o, i in zip(ok, inside)]}


SUBPIX = Snapper("subpix", snap_subpix, SubpixParams, test_median_px=0.5,
                  description="cv2.cornerSubPix at each corner")
