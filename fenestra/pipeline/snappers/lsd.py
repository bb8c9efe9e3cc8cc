"""``lsd``: OpenCV's line segment detector near each side, a line fitted per side, intersections.

LSD (von Gioi et al. 2012; pipeline.segments.detect_segments, the pipeline's one segment detector)
runs once on a crop around the quad.
A segment supports a side when it is nearly parallel to it (``max_angle_deg``), both its ends lie
within ``band_px`` of the side's line, and it overlaps the side between its ends (trimmed by
``end_trim_px``, so the neighbouring sides' segments stay out). Each side's line is the total
least squares fit to its segments, each taken as a uniform density of points along its length
(so longer segments weigh more): the line through the length-weighted centroid along the principal
direction of the length-weighted scatter (a segment of length l and direction d adds l^3/12 d d^T
about its midpoint). Neighbouring lines intersect in the new corners; a side without support
keeps its input line, and a corner that would move further than ``max_move_px`` keeps its input.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.pipeline.segments import detect_segments
from fenestra.pipeline.snappers.base import Snapper, check_inputs, keep_if_far, quad_from_lines, side_lines


@dataclass(frozen=True)
class LsdParams:
    """band_px: largest distance of a segment's ends from the side's line; max_angle_deg: largest
    angle between segment and side; end_trim_px: the side's ends left out of the overlap test;
    min_length_px: shorter segments are ignored; margin_px: the crop around the quad that LSD sees;
    scale: LSD's image scale (1: full resolution, no sub-sampling bias); max_move_px: corners moving
    further keep their input position."""

    band_px: float = 3.0
    max_angle_deg: float = 5.0
    end_trim_px: float = 3.0
    min_length_px: float = 4.0
    margin_px: int = 8
    scale: float = 1.0
    max_move_px: float = 6.0


def segments_near(g: np.ndarray, quad: np.ndarray, p: LsdParams) -> np.ndarray:
    """LSD segments (M, 2, 2) px (pipeline.segments.detect_segments at ``p.scale``) in a crop of the
    float32 gray image g (H, W) around ``quad`` (4, 2), ``p.margin_px`` wide; (0, 2, 2) when the crop
    is empty."""
    H, W = g.shape
    lo = np.floor(quad.min(axis=0) - p.margin_px).astype(int)
    hi = np.ceil(quad.max(axis=0) + p.margin_px).astype(int) + 1
    x0, y0 = max(lo[0], 0), max(lo[1], 0)
    x1, y1 = min(hi[0], W), min(hi[1], H)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return np.zeros((0, 2, 2))
    return detect_segments(g, p.scale, (x0, y0, x1, y1))


def supporting(segs: np.ndarray, a: np.ndarray, b: np.ndarray, line: np.ndarray, p: LsdParams) -> np.ndarray:
    """Bool mask (M,) of the segments (M, 2, 2) px that support side a -> b with line (n_x, n_y, c)."""
    P, Q = segs[:, 0], segs[:, 1]
    d = Q - P
    length = np.linalg.norm(d, axis=1)
    u = (b - a) / np.linalg.norm(b - a)
    cos = np.abs(d @ u) / np.maximum(length, 1e-12)
    near = (np.abs(P @ line[:2] - line[2]) <= p.band_px) & (np.abs(Q @ line[:2] - line[2]) <= p.band_px)
    s0, s1 = (P - a) @ u, (Q - a) @ u  # positions along the side
    side_len = float(np.linalg.norm(b - a))
    overlaps = (np.maximum(s0, s1) > p.end_trim_px) & (np.minimum(s0, s1) < side_len - p.end_trim_px)
    return (length >= p.min_length_px) & (cos >= np.cos(np.radians(p.max_angle_deg))) & near & overlaps


def fit_line(segs: np.ndarray) -> np.ndarray:
    """Total least squares line (n_x, n_y, c), |n| = 1, of segments (M, 2, 2) px, each a uniform
    density of points along it (length-weighted centroid and scatter)."""
    P, Q = segs[:, 0], segs[:, 1]
    d = Q - P
    length = np.linalg.norm(d, axis=1)
    mid = (P + Q) / 2
    c = (length[:, None] * mid).sum(axis=0) / length.sum()
    r = mid - c
    S = (length[:, None, None] * (r[:, :, None] * r[:, None, :] + d[:, :, None] * d[:, None, :] / 12.0)).sum(axis=0)
    n = np.linalg.eigh(S)[1][:, 0]  # smallest eigenvalue: the normal
    return np.array([n[0], n[1], n @ c])


def snap_lsd(gray: np.ndarray, quad: np.ndarray, params: LsdParams = LsdParams()) -> tuple[np.ndarray, dict]:
    """Fit each side to the LSD segments along it (total least squares), intersect neighbours."""
    g, q = check_inputs(gray, quad)
    segs = segments_near(g, q, params)
    lines, found = side_lines(q), []
    for k in range(4):
        keep = supporting(segs, q[k], q[(k + 1) % 4], lines[k], params) if len(segs) else np.zeros(0, bool)
        found.append(bool(keep.any()))
        if keep.any():
            fit = fit_line(segs[keep])
            lines[k] = fit if fit[:2] @ lines[k][:2] > 0 else -fit  # keep the side's orientation
    out, ok = keep_if_far(q, quad_from_lines(lines), params.max_move_px)
    return out, {"moved": [bool(o and (found[i - 1] or found[i])) for i, o in enumerate(ok)], "side_found": found}


LSD = Snapper("lsd", snap_lsd, LsdParams, test_median_px=0.03,
              description="LSD line segments per side, total least squares lines, intersected")
