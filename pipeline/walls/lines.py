"""Façade lines: the photo's straight line segments (wall edges, eaves, mullions, window frames)
near a wall's windows join its vanishing points and its joint fit (``+lines`` strategies,
WallParams.lines).

- :func:`photo_segments`: the photo's segments, from its pipeline.segments.SegmentCache (LSD at
  WALL_FIT.lsd_scale), at least WallParams.line_min_px long.
- :func:`wall_segments`: a wall's candidate segments (near its windows) and the vanishing
  direction each follows (:func:`vp_consensus`: those that share one vanishing point near the
  sides').
- :func:`line_residuals`, :class:`LineObs`: a segment against its vanishing point in pixels, as
  residuals (and their Jacobian) of the joint fit (pipeline.walls.fit.refine_walls);
  :func:`refit_lines`: the fit, each segment assigned again to the fitted vanishing points, and
  the fit again.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from itertools import combinations

import cv2
import numpy as np

from fenestra.checks import check_K
from pipeline.segments import SegmentCache
from pipeline.walls.fit import WallFit, left_jacobian
from pipeline.walls.settings import WALL_FIT, WallParams
from pipeline.walls.vanishing import WallVP, cross3, edge_normals, fit_vps, homog, side_angles_to_vp, side_thresholds_deg


def photo_segments(segment_cache: SegmentCache | None, params: WallParams,
                   image_shape: tuple[int, int]) -> np.ndarray | None:
    """The façade segments (M, 2, 2) px a strategy uses when params.lines (else None): those of
    the photo, from its segment cache (pipeline.segments.SegmentCache; LSD at WALL_FIT.lsd_scale),
    at least params.line_min_px long. ValueError when they are needed and there is no cache, or
    the cache's photo is not (H, W) = image_shape."""
    if not params.lines:
        return None
    if segment_cache is None:
        raise ValueError("a per-wall strategy with façade lines (WallParams.lines) needs the photo's "
                         "segments (a pipeline.segments.SegmentCache of the gray image)")
    if tuple(segment_cache.shape) != tuple(image_shape):
        raise ValueError(f"the segment cache's photo is {tuple(segment_cache.shape)}, "
                         f"the windows' image {tuple(image_shape)}")
    return segment_cache.segments(WALL_FIT.lsd_scale, params.line_min_px)


def segment_families(segments: np.ndarray, d_h: np.ndarray, d_v: np.ndarray, K: np.ndarray,
                     base_deg: float, noise_px: float) -> np.ndarray:
    """Which vanishing direction each segment (M, 2, 2) px follows: 0 the wall's horizontal d_h,
    1 its vertical d_v (camera frame (3,) under K (3, 3)), -1 neither: the closer of the two in
    image angle (:func:`side_angles_to_vp`), if within base_deg + atan(2 noise_px / length)."""
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    K = check_K(K)
    ang = np.stack([side_angles_to_vp(s, K @ d) for d in (d_h, d_v)], axis=1)
    fam = np.argmin(ang, axis=1)
    ok = ang[np.arange(len(s)), fam] <= side_thresholds_deg(s, noise_px, base_deg)
    return np.where(ok, fam, -1)


def vp_consensus(segments: np.ndarray, d0: np.ndarray, K: np.ndarray, gate_deg: float, tight_deg: float,
                 noise_px: float, max_pairs_of: int = 12) -> np.ndarray:
    """Which of the segments (M, 2, 2) px share one vanishing point near K d0 (d0 (3,) camera frame
    under K (3, 3)): (M,) bool.

    Candidates: the segments pointing at K d0 within gate_deg (+ atan(2 noise_px / length)).
    Hypotheses: the direction in each candidate's interpretation plane closest to d0, and the
    intersection of every pair among the ``max_pairs_of`` longest candidates. The hypothesis whose
    segments within tight_deg (+ the same) have the greatest total length wins; those segments are
    returned (none without candidates).
    """
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    K = check_K(K)
    length = np.linalg.norm(s[:, 1] - s[:, 0], axis=1)
    cand = np.flatnonzero(side_angles_to_vp(s, K @ d0) <= side_thresholds_deg(s, noise_px, gate_deg))
    if not len(cand):
        return np.zeros(len(s), dtype=bool)
    n = edge_normals(s[cand], K)
    hyps = [d0[None] - (n @ d0)[:, None] * n]
    top = np.argsort(-length[cand])[:max_pairs_of]
    if len(top) > 1:
        i, j = np.array(list(combinations(top, 2))).T
        hyps.append(np.cross(n[i], n[j]))
    H = np.concatenate(hyps)
    H = H[np.linalg.norm(H, axis=1) > 1e-12]
    thr = side_thresholds_deg(s[cand], noise_px, tight_deg)
    inl = side_angles_to_vp(s[cand], H @ K.T) <= thr  # (H, C)
    best = inl[int(np.argmax(inl @ length[cand]))]
    out = np.zeros(len(s), dtype=bool)
    out[cand[best]] = True
    return out


def hull_distance(points: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Signed distance (M,) px of points (M, 2) px to the convex hull of quads' (N, 4, 2) corners:
    positive inside, negative outside."""
    hull = cv2.convexHull(np.asarray(quads, dtype=np.float32).reshape(-1, 2))
    return np.array([cv2.pointPolygonTest(hull, (float(x), float(y)), True)
                     for x, y in np.asarray(points, dtype=np.float64).reshape(-1, 2)])


def line_residuals(segments: np.ndarray, vp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Residual (M,) px of segments (M, 2, 2) px against their vanishing points vp (M, 3)
    (homogeneous px), and its gradient d r / d vp (M, 3).

    r = sqrt(2) x the signed distance of the segment's end from the line through its midpoint and
    its vanishing point: with isotropic end-point noise sigma, r has standard deviation sigma.
    """
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    v = np.asarray(vp, dtype=np.float64).reshape(-1, 3)
    m = homog(0.5 * (s[:, 0] + s[:, 1]))
    c = cross3(homog(s[:, 1]), m)  # r ~ c . v: the end's offset from the line m x v
    line = cross3(m, v)
    D = np.linalg.norm(line[:, :2], axis=1)
    cv = np.sum(c * v, axis=1)
    # d line / d v = [m]_x, so d D / d v = (l0 [m]_x[0] + l1 [m]_x[1]) / D
    mx = np.stack([np.zeros(len(m)), -m[:, 2], m[:, 1]], axis=1), np.stack([m[:, 2], np.zeros(len(m)), -m[:, 0]], axis=1)
    dD = (line[:, :1] * mx[0] + line[:, 1:2] * mx[1]) / D[:, None]
    r = np.sqrt(2.0) * cv / D
    grad = np.sqrt(2.0) * (c / D[:, None] - (cv / D ** 2)[:, None] * dD)
    return r, grad


@dataclass(frozen=True)
class LineObs:
    """Façade line segments in a joint wall fit.

    segments (M, 2, 2) px; group (M,): the rotation group (index into the fit's R0) of each
    segment's wall; Q (M, 3, 3): that wall's fixed rotation within its group; axis (M,): 0 the
    segment runs along the window frame's x (horizontal), 1 along its y (vertical); weight (M,):
    the factor on its residual (:func:`line_residuals`), corner sigma / line sigma, so that a line
    counts like one corner coordinate of its precision.
    """

    segments: np.ndarray
    group: np.ndarray
    Q: np.ndarray
    axis: np.ndarray
    weight: np.ndarray

    def __len__(self) -> int:
        return len(self.segments)

    def directions(self, R: np.ndarray) -> np.ndarray:
        """Unit camera-frame directions (M, 3) of the segments under group rotations R (G, 3, 3)."""
        RQ = R[self.group] @ self.Q
        return RQ[np.arange(len(self.segments)), :, self.axis]

    def residuals(self, R: np.ndarray, K: np.ndarray) -> np.ndarray:
        """Weighted residuals (M,) px under rotations R (G, 3, 3) and intrinsics K (3, 3)."""
        return self.weight * line_residuals(self.segments, self.directions(R) @ K.T)[0]

    def angles_deg(self, R: np.ndarray, K: np.ndarray) -> np.ndarray:
        """Image angle (M,) deg between each segment and the line from its midpoint to its
        vanishing point under rotations R (G, 3, 3) and intrinsics K (3, 3)."""
        r = line_residuals(self.segments, self.directions(R) @ K.T)[0]
        half = 0.5 * np.linalg.norm(self.segments[:, 1] - self.segments[:, 0], axis=1)
        return np.degrees(np.arcsin(np.clip(np.abs(r) / (np.sqrt(2.0) * half), 0.0, 1.0)))

    def take(self, keep: np.ndarray) -> "LineObs":
        """The segments selected by ``keep`` (M,) bool or indices."""
        return LineObs(self.segments[keep], self.group[keep], self.Q[keep], self.axis[keep], self.weight[keep])

    def jacobian(self, x: np.ndarray, R: np.ndarray, K: np.ndarray, n_params: int, focal_free: bool) -> np.ndarray:
        """(M, P) derivative of :meth:`residuals` by the fit parameters x (P,) (refine_walls'
        layout: rotation vector per group first, f last if free)."""
        d = self.directions(R)
        _, g = line_residuals(self.segments, d @ K.T)
        g = g * self.weight[:, None]
        J = np.zeros((len(d), n_params))
        Jl = np.array([left_jacobian(x[3 * k:3 * k + 3]) for k in range(len(R))])
        # d vp / d omega = K (-[d]_x J_l); (-[d]_x)^T (K^T g) = d x (K^T g)
        rot = np.einsum("mc,mcd->md", cross3(d, g @ K), Jl[self.group])
        for k in range(len(R)):
            sel = self.group == k
            J[sel, 3 * k:3 * k + 3] = rot[sel]
        if focal_free:
            J[:, -1] = g[:, 0] * d[:, 0] + g[:, 1] * d[:, 1]
        return J


def quad_sizes(quads: np.ndarray) -> np.ndarray:
    """Square root of the area (N,) px of quads (N, 4, 2) px."""
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    x, y = q[..., 0], q[..., 1]
    return np.sqrt(0.5 * np.abs(np.sum(x * np.roll(y, -1, 1) - y * np.roll(x, -1, 1), axis=1)))


WallLines = tuple[np.ndarray, np.ndarray]  # a wall's candidate façade segments (M, 2, 2) px, their family (M,)


def wall_segments(segments: np.ndarray, quads: np.ndarray, members: list[int], K: np.ndarray,
                  params: WallParams, rounds: int = 2) -> tuple[WallLines, tuple[np.ndarray, np.ndarray]]:
    """The candidate façade segments of the wall of windows ``members`` of quads (N, 4, 2) px among
    the photo's ``segments`` (M, 2, 2) px, the vanishing direction each follows, and the wall's
    vanishing directions (d_h, d_v) (3,) under K from its sides and those segments.

    Candidates: see WallParams.lines (none: the sides' vanishing points). Assignment (0: d_h, 1:
    d_v, -1: neither): per direction, the segments that agree on one vanishing point near the
    sides' (vp_consensus, within line_gate_deg of it, line_refit_deg of each other);
    ``rounds`` times, each around the vanishing points refitted with the segments found.
    """
    vp = fit_vps(quads, list(members), K, params.sigma_px)
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    if not len(s):
        return (s, np.zeros(0, dtype=int)), vp
    q = quads[list(members)]
    mid = 0.5 * (s[:, 0] + s[:, 1])
    s = s[hull_distance(mid, q) >= -params.line_margin * float(np.median(quad_sizes(q)))]
    for _ in range(rounds):
        inl = [vp_consensus(s, d, K, params.line_gate_deg, params.line_refit_deg, params.line_sigma_px)
               for d in vp]
        fam = np.where(inl[0] & ~inl[1], 0, np.where(inl[1] & ~inl[0], 1, -1))
        vp = fit_vps(quads, list(members), K, params.sigma_px, lines=(s[fam == 0], s[fam == 1]),
                     line_sigma_px=params.line_sigma_px)
    return (s, fam), vp


def wall_vps(quads: np.ndarray, K: np.ndarray, walls: list[WallVP], params: WallParams,
             segments: np.ndarray | None = None) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[WallLines] | None]:
    """Per wall: its vanishing directions (d_h, d_v) under K from its windows' sides and, given the
    photo's façade segments (M, 2, 2) px, those that follow them (:func:`wall_segments`); and the
    segments per wall (None without)."""
    if segments is None:
        return [fit_vps(quads, list(w.members), K, params.sigma_px) for w in walls], None
    out = [wall_segments(segments, quads, list(w.members), K, params) for w in walls]
    return [vp for _, vp in out], [wl for wl, _ in out]


def line_obs(lines: list[WallLines], sel: list[int], set_of_wall: dict[int, int], Q: np.ndarray,
             weight: float) -> tuple[LineObs, np.ndarray]:
    """The candidate segments of walls ``sel`` as one LineObs, each twice (axis 0 then 1; rotation
    group set_of_wall[g] of wall g), and (2M,) bool: the entries of their initial families."""
    seg, grp, Qs, keep = [np.zeros((0, 2, 2))], [np.zeros(0, int)], [np.zeros((0, 3, 3))], [np.zeros(0, bool)]
    for g in sel:
        s, fam = lines[g]
        seg.append(np.repeat(s, 2, axis=0))
        grp.append(np.full(2 * len(s), set_of_wall[g]))
        Qs.append(np.repeat(Q[g][None], 2 * len(s), axis=0))
        keep.append((np.tile([0, 1], len(s)) == np.repeat(fam, 2)))
    seg = np.concatenate(seg)
    obs = LineObs(seg, np.concatenate(grp), np.concatenate(Qs), np.tile([0, 1], len(seg) // 2),
                  np.full(len(seg), weight))
    return obs, np.concatenate(keep)


def refit_lines(fit: Callable[[LineObs | None], WallFit], quads: np.ndarray, K: np.ndarray,
                params: WallParams, obs: LineObs, keep: np.ndarray) -> WallFit:
    """Joint fit (``fit``, of the windows' quads (N, 4, 2) px under K) with the façade segments
    ``obs.take(keep)``; then each candidate segment is assigned again, to the fitted vanishing
    point it points at within line_refit_deg (+ the angle of 2 line_sigma_px on its length),
    weighted by the fit's corner RMS (at least the prior sigma) over line_sigma_px, and the walls
    fitted again."""
    first = fit(obs.take(keep))
    Kx = K.copy()
    Kx[0, 0] = Kx[1, 1] = first.focal_px
    length = np.linalg.norm(obs.segments[::2, 1] - obs.segments[::2, 0], axis=1)
    ang = obs.angles_deg(first.R, Kx).reshape(-1, 2)
    best = np.argmin(ang, axis=1)
    ok = ang[np.arange(len(ang)), best] <= params.line_refit_deg + np.degrees(np.arctan2(2.0 * params.line_sigma_px, length))
    again = np.zeros(len(obs), dtype=bool)
    again[2 * np.flatnonzero(ok) + best[ok]] = True
    corner_rms = float(np.sqrt(np.mean((first.reprojected - quads) ** 2)))
    w = max(params.sigma_px, corner_rms) / params.line_sigma_px
    return fit(replace(obs.take(again), weight=np.full(int(again.sum()), w)))
