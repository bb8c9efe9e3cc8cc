"""``linefit``: sub-pixel edge points along each side, robust weighted line fits, intersections.

For each side, scan across it: rows for a steep side, columns for a flat one. On each scanline the
edge position is the centroid of the signed central-difference gradient within ``band_px`` of the
side; on an antialiased step edge (pixels = area coverage) this equals the exact edge crossing
(the centroid telescopes to the area-based estimate R - 1/2 - sum of coverage). A weighted
least-squares line (weight = the scanline's contrast) with a few IRLS (Huber) iterations through
those points replaces the side; scanlines within ``end_trim_px`` of a corner are left out so the
neighbouring sides do not pull. Neighbouring lines intersect in the new corners. The whole fit
is repeated ``iterations`` times, each from the previous quad.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.pipeline.snappers.base import Snapper, check_inputs, keep_if_far, quad_from_lines, side_lines


@dataclass(frozen=True)
class LinefitParams:
    """band_px: half-width (px, integer) of each scanline's window around the side; end_trim_px:
    scanlines this close to a corner are skipped; irls_iters: Huber reweighting iterations;
    huber_k: Huber threshold in robust standard deviations; min_points: fewer scanlines keep the
    input side; iterations: repeats of the whole fit; max_move_px: corners moving further keep
    their input position."""

    band_px: int = 4
    end_trim_px: float = 6.0
    irls_iters: int = 3
    huber_k: float = 1.5
    min_points: int = 5
    iterations: int = 2
    max_move_px: float = 6.0


def edge_points_rows(g: np.ndarray, a: np.ndarray, b: np.ndarray, p: LinefitParams) -> tuple[np.ndarray, np.ndarray]:
    """Edge crossings of a steep side a -> b (x, y px) on each image row; returns (M, 2) points, (M,) weights.

    g: (H, W) float32. Each row v between the trimmed ends gives the gradient centroid over the
    2*band_px+1 pixels centred on the side's x at v.
    """
    H, W = g.shape
    length = np.linalg.norm(b - a)
    d = (b - a) / length
    trim = p.end_trim_px * abs(d[1])  # along y
    v_lo, v_hi = min(a[1], b[1]) + trim, max(a[1], b[1]) - trim
    v = np.arange(int(np.ceil(max(v_lo, 0))), int(np.floor(min(v_hi, H - 1))) + 1)
    if len(v) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    x_side = a[0] + (v - a[1]) * d[0] / d[1]
    offs = np.arange(-p.band_px, p.band_px + 1)
    U = np.round(x_side).astype(int)[:, None] + offs[None, :]
    ok = (U[:, 0] >= 1) & (U[:, -1] <= W - 2)
    v, U = v[ok], U[ok]
    if len(v) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    gx = g[v[:, None], U + 1] - g[v[:, None], U - 1]
    total = gx.sum(axis=1)
    good = np.abs(total) > 1e-6
    x_edge = (gx[good] * U[good]).sum(axis=1) / total[good]
    return np.stack([x_edge, v[good].astype(np.float64)], axis=1), np.abs(total[good])


def huber_line(P: np.ndarray, w: np.ndarray, p: LinefitParams) -> np.ndarray:
    """Weighted IRLS (Huber) fit of x = alpha + beta * y through P (M, 2); returns line (n_x, n_y, c)."""
    x, y = P[:, 0], P[:, 1]
    rw = np.ones_like(w)
    for _ in range(p.irls_iters + 1):
        ww = w * rw
        sw, sy, sx = ww.sum(), ww @ y, ww @ x
        syy, sxy = ww @ (y * y), ww @ (x * y)
        det = sw * syy - sy * sy
        if abs(det) < 1e-12:
            break
        coef = ((syy * sx - sy * sxy) / det, (sw * sxy - sy * sx) / det)  # 2x2 normal equations
        r = x - coef[0] - coef[1] * y
        s = 1.4826 * np.median(np.abs(r)) + 1e-9
        rw = np.minimum(1.0, p.huber_k * s / np.maximum(np.abs(r), 1e-12))
    alpha, beta = coef
    n = np.array([1.0, -beta]) / np.hypot(1.0, beta)  # x - beta y = alpha
    return np.array([n[0], n[1], alpha / np.hypot(1.0, beta)])


def fit_side(g: np.ndarray, a: np.ndarray, b: np.ndarray, p: LinefitParams) -> np.ndarray | None:
    """Refit the side a -> b; (n_x, n_y, c) or None when too few edge points were found."""
    d = b - a
    if abs(d[1]) >= abs(d[0]):  # steep: scan rows
        P, w = edge_points_rows(g, a, b, p)
        return huber_line(P, w, p) if len(P) >= p.min_points else None
    # flat: scan columns = rows of the transposed image with x and y swapped
    P, w = edge_points_rows(g.T, a[::-1], b[::-1], p)
    if len(P) < p.min_points:
        return None
    line = huber_line(P, w, p)
    return np.array([line[1], line[0], line[2]])


def snap_linefit(gray: np.ndarray, quad: np.ndarray, params: LinefitParams = LinefitParams()) -> tuple[np.ndarray, dict]:
    """Sub-pixel side lines from gradient centroids, robust line fits, intersections."""
    g, q = check_inputs(gray, quad)
    cur, found = q.copy(), [False] * 4
    for _ in range(params.iterations):
        lines = side_lines(cur)
        for k in range(4):
            line = fit_side(g, cur[k], cur[(k + 1) % 4], params)
            found[k] = line is not None
            if line is not None:
                lines[k] = line
        cur, _ = keep_if_far(q, quad_from_lines(lines), params.max_move_px)
    out, ok = keep_if_far(q, cur, params.max_move_px)
    return out, {"moved": ok, "side_found": found}


LINEFIT = Snapper("linefit", snap_linefit, LinefitParams, test_median_px=0.05,
                   description="sub-pixel edge points per side, robust line fits, intersected")
