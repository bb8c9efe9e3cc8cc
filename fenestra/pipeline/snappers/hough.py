"""``hough``: re-fit each side as the Hough line closest to it, intersect neighbours.

For each side, take Canny edges in a band of half-width ``band_px`` around it (ends trimmed by
``end_trim_px`` so the neighbouring sides' edges stay out), run ``cv2.HoughLines`` (standard
transform, fine angle steps) and choose the line closest to the side (angle difference in degrees
plus offset difference in px, each scaled by its tolerance); neighbouring lines intersect in the
new corners. A side with no acceptable line keeps its input line. The paper suggests Hough lines
because Harris corners snap to sills.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fenestra.pipeline.snappers.base import Snapper, check_inputs, keep_if_far, quad_from_lines, side_lines


@dataclass(frozen=True)
class HoughParams:
    """band_px: half-width of the search band around each side; end_trim_px: side ends left out;
    canny_low/high: Canny thresholds (on uint8 intensities); rho_px, theta_deg: Hough resolution;
    min_votes_frac: a line needs this fraction of the side's length in votes; max_angle_deg:
    largest accepted angle to the side; max_move_px: corners moving further keep their input."""

    band_px: float = 4.0
    end_trim_px: float = 4.0
    canny_low: float = 30.0
    canny_high: float = 90.0
    rho_px: float = 0.5
    theta_deg: float = 0.25
    min_votes_frac: float = 0.3
    max_angle_deg: float = 5.0
    max_move_px: float = 8.0


def band_mask(shape: tuple[int, int], a: np.ndarray, b: np.ndarray, half_width: float, trim: float) -> np.ndarray:
    """(H, W) uint8 mask of the band of half-width ``half_width`` around segment a-b, ends trimmed."""
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([-d[1], d[0]])
    a2, b2 = a + trim * d, b - trim * d
    poly = np.array([a2 + half_width * n, b2 + half_width * n, b2 - half_width * n, a2 - half_width * n])
    m = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(m, np.round(poly * 16).astype(np.int32), 1, lineType=cv2.LINE_8, shift=4)
    return m


def best_line(edges: np.ndarray, side: np.ndarray, length: float, p: HoughParams) -> np.ndarray | None:
    """The Hough line (n_x, n_y, c) in edge image (H, W) closest to ``side``, or None."""
    votes = max(3, int(p.min_votes_frac * length))
    # only angles near the side's: theta of the normal, folded into [0, pi) as HoughLines uses
    theta0 = np.arctan2(side[1], side[0]) % np.pi
    span = np.radians(p.max_angle_deg)
    lo, hi = theta0 - span, theta0 + span
    if lo < 0 or hi > np.pi:  # the window wraps around 0 = pi: search both ends
        lines = cv2.HoughLines(edges, p.rho_px, np.radians(p.theta_deg), votes)
    else:
        lines = cv2.HoughLines(edges, p.rho_px, np.radians(p.theta_deg), votes, min_theta=lo, max_theta=hi)
    if lines is None:
        return None
    rho, theta = lines[:, 0, 0].astype(np.float64), lines[:, 0, 1].astype(np.float64)
    cand = np.stack([np.cos(theta), np.sin(theta), rho], axis=1)  # x cos + y sin = rho
    cand[cand[:, :2] @ side[:2] < 0] *= -1.0  # same orientation as the side
    ang = np.degrees(np.arccos(np.clip(cand[:, :2] @ side[:2], -1.0, 1.0)))
    off = np.abs(cand[:, 2] - side[2])
    ok = ang <= p.max_angle_deg
    if not ok.any():
        return None
    score = np.where(ok, ang / p.max_angle_deg + off / p.band_px, np.inf)
    return cand[int(np.argmin(score))]


def snap_hough(gray: np.ndarray, quad: np.ndarray, params: HoughParams = HoughParams()) -> tuple[np.ndarray, dict]:
    """Replace each side by its closest Hough line within the band, intersect neighbours."""
    g, q = check_inputs(gray, quad)
    H, W = g.shape
    sides = side_lines(q)
    new_lines, found = sides.copy(), []
    pad = params.band_px + 2
    for k in range(4):
        a, b = q[k], q[(k + 1) % 4]
        x0, y0 = np.floor(np.minimum(a, b) - pad).astype(int)
        x1, y1 = np.ceil(np.maximum(a, b) + pad + 1).astype(int)
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
        line = None
        if x1 - x0 >= 3 and y1 - y0 >= 3:
            crop = np.clip(g[y0:y1, x0:x1], 0, 255).astype(np.uint8)  # the side's crop only, not the photo
            edges = cv2.Canny(crop, params.canny_low, params.canny_high)
            origin = np.array([x0, y0], dtype=np.float64)
            edges *= band_mask(edges.shape, a - origin, b - origin, params.band_px, params.end_trim_px)
            local = sides[k].copy()
            local[2] -= local[:2] @ origin
            line = best_line(edges, local, float(np.linalg.norm(b - a)), params)
            if line is not None:
                line = np.array([line[0], line[1], line[2] + line[:2] @ origin])
        found.append(line is not None)
        if line is not None:
            new_lines[k] = line
    out, ok = keep_if_far(q, quad_from_lines(new_lines), params.max_move_px)
    return out, {"moved": ok, "side_found": found}


HOUGH = Snapper("hough", snap_hough, HoughParams, test_median_px=0.6,
                 description="Hough line per side, intersected, the paper's suggestion")
