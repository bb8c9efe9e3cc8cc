"""Façade lines: the photo's straight line segments (wall edges, eaves, mullions, window frames)
near a wall's windows join its vanishing points and its joint fit (``+lines`` strategies,
WallParams.lines).

- :func:`photo_segments`: the photo's segments, from its pipeline.segments.SegmentCache (LSD at
  WALL_FIT.lsd_scale), at least WallParams.line_min_px long, as a :class:`FacadeSegments`: the
  per-photo cache of what the walls derive from them (per segment, and per wall), kept in the
  SegmentCache, so the bench's methods of one view do that work once.
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
from functools import cached_property
from itertools import combinations

import cv2
import numpy as np

from fenestra.checks import check_K
from fenestra.conventions import LIMITS
from fenestra.pipeline.segments import SegmentCache, longest_segments
from fenestra.pipeline.walls.fit import WallFit, left_jacobian
from fenestra.pipeline.walls.settings import WALL_FIT, WallParams
from fenestra.pipeline.walls.vanishing import (WallSides, WallVP, angles_to_vp, cross3, fit_vps, homog, plane_normals, rays,
                                      side_angles_to_vp, side_thresholds_deg, unit_normals)

MAX_HYPOTHESES = 2048  # per-segment vanishing-point hypotheses of one consensus (the longest segments')
CONSENSUS_CELLS = 4_000_000  # hypotheses x candidate segments scored at once (bounded memory)


def photo_segments(segment_cache: SegmentCache | None, params: WallParams,
                   image_shape: tuple[int, int]) -> "FacadeSegments | None":
    """The façade segments (M, 2, 2) px a strategy uses when params.lines (else None): those of
    the photo, from its segment cache (pipeline.segments.SegmentCache; LSD at WALL_FIT.lsd_scale),
    at least params.line_min_px long, the LIMITS.max_facade_segments longest of them (bounded
    consensus time), as the photo's :class:`FacadeSegments` (one per photo and
    length, kept by the cache: what the walls' line work derives from them is done once per
    photo). ValueError when they are needed and there is no cache, or the cache's photo is not
    (H, W) = image_shape."""
    if not params.lines:
        return None
    if segment_cache is None:
        raise ValueError("a per-wall strategy with façade lines (WallParams.lines) needs the photo's "
                         "segments (a pipeline.segments.SegmentCache of the gray image)")
    if tuple(segment_cache.shape) != tuple(image_shape):
        raise ValueError(f"the segment cache's photo is {tuple(segment_cache.shape)}, "
                         f"the windows' image {tuple(image_shape)}")
    key = ("facade", float(WALL_FIT.lsd_scale), float(params.line_min_px), LIMITS.max_facade_segments)
    return segment_cache.derived(key, lambda: FacadeSegments(longest_segments(
        segment_cache.segments(WALL_FIT.lsd_scale, params.line_min_px), LIMITS.max_facade_segments)))


class FacadeSegments:
    """A photo's façade segments (M, 2, 2) px and what the walls' line work derives from them, done
    once per photo: an explicit per-photo cache (make one per photo's segments, or let
    :func:`photo_segments` keep it in the photo's SegmentCache; no global state).

    Per segment: midpoint (M, 2) px, homogeneous midpoint (M, 3), direction end - start (M, 2) px
    and length (M,) px; per K (by its exact bytes) the interpretation-plane normals; per (noise,
    base) the inlier thresholds (vanishing.side_thresholds_deg); per sigma the weights
    (vanishing.segment_weights); per wall (:func:`wall_segments`, by the exact bytes of its quads,
    K and parameters) its result. Every per-segment value is the one the per-wall functions compute
    on a subset of the rows, bit for bit (they are row-wise: tests/pipeline/test_pipeline_facade.py).
    Arrays handed out are read-only.
    """

    def __init__(self, segments: np.ndarray) -> None:
        s = np.array(segments, dtype=np.float64).reshape(-1, 2, 2)
        self.segments = _frozen(s)
        self.mid = _frozen(0.5 * (s[:, 0] + s[:, 1]))
        self.mid_h = _frozen(homog(self.mid))
        self.e = _frozen(s[:, 1] - s[:, 0])
        self.length = _frozen(np.linalg.norm(self.e, axis=1))
        self._normals: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._thresholds: dict[tuple[float, float], np.ndarray] = {}
        self._weights: dict[float, np.ndarray] = {}
        self._walls: dict[tuple, tuple[WallLines, tuple[np.ndarray, np.ndarray]]] = {}

    def __len__(self) -> int:
        return len(self.segments)

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        """The segments (M, 2, 2) px (read-only unless copied)."""
        s = self.segments if dtype is None else self.segments.astype(dtype)
        return s.copy() if copy and s is self.segments else s

    def normals(self, K: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Unit interpretation-plane normals (len(idx), 3) of segments ``idx`` under K (3, 3,
        checked): vanishing.edge_normals of those segments (FacadeError when one is degenerate)."""
        key = K.tobytes()
        if key not in self._normals:
            n, norm = plane_normals(*rays(self.segments, np.linalg.inv(K)))
            self._normals[key] = (n, norm, np.divide(n, norm, out=np.zeros_like(n), where=norm >= 1e-15))
        n, norm, unit = self._normals[key]
        if np.any(norm[idx] < 1e-15):
            unit_normals(self.segments[idx], n[idx], norm[idx])  # raises, naming the segment
        return unit[idx]

    def thresholds(self, noise_px: float, base_deg: float) -> np.ndarray:
        """vanishing.side_thresholds_deg (M,) deg of every segment."""
        key = (float(noise_px), float(base_deg))
        if key not in self._thresholds:
            self._thresholds[key] = _frozen(side_thresholds_deg(self.segments, noise_px, base_deg))
        return self._thresholds[key]

    def weights(self, sigma_px: float) -> np.ndarray:
        """vanishing.segment_weights (M,) of every segment with end-point sigma ``sigma_px``."""
        key = float(sigma_px)
        if key not in self._weights:
            self._weights[key] = _frozen((self.length / key) ** 2)
        return self._weights[key]

    def wall(self, key: tuple, make: Callable[[], tuple]) -> tuple:
        """The result of :func:`wall_segments` for ``key`` (its inputs' exact bytes), made by
        ``make()`` on the first request."""
        if key not in self._walls:
            self._walls[key] = make()
        return self._walls[key]


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


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
    fs = FacadeSegments(segments)
    return _consensus(fs, np.arange(len(fs)), d0, check_K(K), gate_deg, tight_deg, noise_px, max_pairs_of)


def _consensus(fs: "FacadeSegments", idx: np.ndarray, d0: np.ndarray, K: np.ndarray, gate_deg: float,
               tight_deg: float, noise_px: float, max_pairs_of: int = 12) -> np.ndarray:
    """:func:`vp_consensus` of segments ``idx`` of ``fs`` under K (checked): (len(idx),) bool."""
    length, mid, e = fs.length[idx], fs.mid_h[idx], fs.e[idx]
    cand = np.flatnonzero(angles_to_vp(mid, e, length, K @ d0) <= fs.thresholds(noise_px, gate_deg)[idx])
    if not len(cand):
        return np.zeros(len(idx), dtype=bool)
    n = fs.normals(K, idx[cand])
    # one hypothesis per candidate (the prior pulled onto its line), of the MAX_HYPOTHESES longest
    # when there are more (a brick wall gives 10^5 segments), kept in candidate order
    own = np.arange(len(cand)) if len(cand) <= MAX_HYPOTHESES else np.sort(np.argsort(-length[cand])[:MAX_HYPOTHESES])
    hyps = [d0[None] - (n[own] @ d0)[:, None] * n[own]]
    top = np.argsort(-length[cand])[:max_pairs_of]
    if len(top) > 1:
        i, j = np.array(list(combinations(top, 2))).T
        hyps.append(cross3(n[i], n[j]))
    H = np.concatenate(hyps)
    H = H[np.linalg.norm(H, axis=1) > 1e-12]
    thr = fs.thresholds(noise_px, tight_deg)[idx[cand]]

    def inliers(h: np.ndarray) -> np.ndarray:  # (h, C) bool
        return angles_to_vp(mid[cand], e[cand], length[cand], h @ K.T) <= thr

    # scored in chunks: memory O(CHUNK x C), never (H x C)
    step = max(1, CONSENSUS_CELLS // max(len(cand), 1))
    score = np.concatenate([inliers(H[s:s + step]) @ length[cand] for s in range(0, len(H), step)])
    best = inliers(H[int(np.argmax(score))][None])[0]
    out = np.zeros(len(idx), dtype=bool)
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
    return _LineGeometry.of(segments).residuals(vp)


@dataclass(frozen=True)
class _LineGeometry:
    """What :func:`line_residuals` needs of segments besides their vanishing points, made once per
    set of segments: homogeneous midpoints m (M, 3), c = end x m (M, 3) (r ~ c . v: the end's
    offset from the line m x v) and the first two rows of [m]_x, as (M, 3) each."""

    m: np.ndarray
    c: np.ndarray
    mx0: np.ndarray
    mx1: np.ndarray

    @classmethod
    def of(cls, segments: np.ndarray) -> "_LineGeometry":
        s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
        m = homog(0.5 * (s[:, 0] + s[:, 1]))
        zero = np.zeros(len(m))
        return cls(m, cross3(homog(s[:, 1]), m), np.stack([zero, -m[:, 2], m[:, 1]], axis=1),
                   np.stack([m[:, 2], zero, -m[:, 0]], axis=1))

    def residuals(self, vp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`line_residuals` (r (M,), grad (M, 3)) against vanishing points vp (M, 3)."""
        v = np.asarray(vp, dtype=np.float64).reshape(-1, 3)
        c = self.c
        line = cross3(self.m, v)
        D = np.linalg.norm(line[:, :2], axis=1)
        cv = np.sum(c * v, axis=1)
        # d line / d v = [m]_x, so d D / d v = (l0 [m]_x[0] + l1 [m]_x[1]) / D
        dD = (line[:, :1] * self.mx0 + line[:, 1:2] * self.mx1) / D[:, None]
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

    What depends on the segments alone is made once per LineObs, and the residuals at the last
    (R, K) asked for are kept (the fit asks for residuals, then the Jacobian, at one point).
    """

    segments: np.ndarray
    group: np.ndarray
    Q: np.ndarray
    axis: np.ndarray
    weight: np.ndarray

    def __len__(self) -> int:
        return len(self.segments)

    @cached_property
    def _geometry(self) -> _LineGeometry:
        return _LineGeometry.of(self.segments)

    @cached_property
    def _last(self) -> dict:
        return {}

    def _at(self, R: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Directions d (M, 3) under R (G, 3, 3), and :func:`line_residuals` (r, grad) of the
        segments against K d (K (3, 3)); those of the last (R, K) asked for are kept."""
        R, K = np.asarray(R, dtype=np.float64), np.asarray(K, dtype=np.float64)
        key = (R.shape, R.tobytes(), K.shape, K.tobytes())
        if self._last.get("key") != key:
            d = self.directions(R)
            self._last.update(key=key, value=(d, *self._geometry.residuals(d @ K.T)))
        return self._last["value"]

    def directions(self, R: np.ndarray) -> np.ndarray:
        """Unit camera-frame directions (M, 3) of the segments under group rotations R (G, 3, 3)."""
        RQ = R[self.group] @ self.Q
        return RQ[np.arange(len(self.segments)), :, self.axis]

    def residuals(self, R: np.ndarray, K: np.ndarray) -> np.ndarray:
        """Weighted residuals (M,) px under rotations R (G, 3, 3) and intrinsics K (3, 3)."""
        return self.weight * self._at(R, K)[1]

    def angles_deg(self, R: np.ndarray, K: np.ndarray) -> np.ndarray:
        """Image angle (M,) deg between each segment and the line from its midpoint to its
        vanishing point under rotations R (G, 3, 3) and intrinsics K (3, 3)."""
        r = self._at(R, K)[1]
        half = 0.5 * np.linalg.norm(self.segments[:, 1] - self.segments[:, 0], axis=1)
        return np.degrees(np.arcsin(np.clip(np.abs(r) / (np.sqrt(2.0) * half), 0.0, 1.0)))

    def take(self, keep: np.ndarray) -> "LineObs":
        """The segments selected by ``keep`` (M,) bool or indices."""
        return LineObs(self.segments[keep], self.group[keep], self.Q[keep], self.axis[keep], self.weight[keep])

    def jacobian(self, x: np.ndarray, R: np.ndarray, K: np.ndarray, n_params: int, focal_free: bool) -> np.ndarray:
        """(M, P) derivative of :meth:`residuals` by the fit parameters x (P,) (refine_walls'
        layout: rotation vector per group first, f last if free)."""
        d, _, g = self._at(R, K)
        g = g * self.weight[:, None]
        J = np.zeros((len(d), n_params))
        Jl = np.array([left_jacobian(x[3 * k:3 * k + 3]) for k in range(len(R))])
        # d vp / d omega = K (-[d]_x J_l); (-[d]_x)^T (K^T g) = d x (K^T g)
        rot = np.einsum("mc,mcd->md", cross3(d, g @ K), Jl[self.group])
        J[np.arange(len(d))[:, None], 3 * self.group[:, None] + np.arange(3)] = rot
        if focal_free:
            J[:, -1] = g[:, 0] * d[:, 0] + g[:, 1] * d[:, 1]
        return J


def quad_sizes(quads: np.ndarray) -> np.ndarray:
    """Square root of the area (N,) px of quads (N, 4, 2) px."""
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    x, y = q[..., 0], q[..., 1]
    return np.sqrt(0.5 * np.abs(np.sum(x * np.roll(y, -1, 1) - y * np.roll(x, -1, 1), axis=1)))


WallLines = tuple[np.ndarray, np.ndarray]  # a wall's candidate façade segments (M, 2, 2) px, their family (M,)


def wall_segments(segments: "np.ndarray | FacadeSegments", quads: np.ndarray, members: list[int], K: np.ndarray,
                  params: WallParams, rounds: int = 2) -> tuple[WallLines, tuple[np.ndarray, np.ndarray]]:
    """The candidate façade segments of the wall of windows ``members`` of quads (N, 4, 2) px among
    the photo's ``segments`` (M, 2, 2) px, the vanishing direction each follows, and the wall's
    vanishing directions (d_h, d_v) (3,) under K from its sides and those segments.

    Candidates: see WallParams.lines (none: the sides' vanishing points). Assignment (0: d_h, 1:
    d_v, -1: neither): per direction, the segments that agree on one vanishing point near the
    sides' (vp_consensus, within line_gate_deg of it, line_refit_deg of each other);
    ``rounds`` times, each around the vanishing points refitted with the segments found.

    segments as the photo's :class:`FacadeSegments`: the result is kept there, keyed by the exact
    bytes of the wall's quads, K and the parameters it depends on, and its arrays are read-only.
    """
    fs = segments if isinstance(segments, FacadeSegments) else FacadeSegments(segments)
    K = check_K(K)
    q = np.asarray(quads, dtype=np.float64)
    members = list(members)
    # every input of _wall_segments: the wall's quads, K, and the parameters it reads
    key = (q[members].tobytes(), K.tobytes(), float(params.sigma_px), float(params.line_margin),
           float(params.line_gate_deg), float(params.line_refit_deg), float(params.line_sigma_px), int(rounds))
    return fs.wall(key, lambda: _wall_segments(fs, q, members, K, params, rounds))


def _wall_segments(fs: FacadeSegments, quads: np.ndarray, members: list[int], K: np.ndarray,
                   params: WallParams, rounds: int) -> tuple[WallLines, tuple[np.ndarray, np.ndarray]]:
    """:func:`wall_segments` (quads (N, 4, 2) float64, K checked), its arrays read-only."""
    sides = WallSides.of(quads, members, np.linalg.inv(K), params.sigma_px)
    vp = sides.vps()
    if not len(fs):
        return (fs.segments, _frozen(np.zeros(0, dtype=int))), tuple(_frozen(d) for d in vp)
    q = quads[members]
    idx = np.flatnonzero(hull_distance(fs.mid, q) >= -params.line_margin * float(np.median(quad_sizes(q))))
    weights = fs.weights(params.line_sigma_px)
    for _ in range(rounds):
        inl = [_consensus(fs, idx, d, K, params.line_gate_deg, params.line_refit_deg, params.line_sigma_px)
               for d in vp]
        fam = np.where(inl[0] & ~inl[1], 0, np.where(inl[1] & ~inl[0], 1, -1))
        lines = [idx[fam == f] for f in (0, 1)]
        vp = sides.vps(tuple((fs.normals(K, sel), weights[sel]) if len(sel) else None for sel in lines))
    return (_frozen(fs.segments[idx]), _frozen(fam)), tuple(_frozen(d) for d in vp)


def wall_vps(quads: np.ndarray, K: np.ndarray, walls: list[WallVP], params: WallParams,
             segments: "np.ndarray | FacadeSegments | None" = None
             ) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[WallLines] | None]:
    """Per wall: its vanishing directions (d_h, d_v) under K from its windows' sides and, given the
    photo's façade segments (M, 2, 2) px (an array, or the photo's :class:`FacadeSegments`, which
    keeps the work per wall), those that follow them (:func:`wall_segments`); and the segments per
    wall (None without)."""
    if segments is None:
        return [fit_vps(quads, list(w.members), K, params.sigma_px) for w in walls], None
    fs = segments if isinstance(segments, FacadeSegments) else FacadeSegments(segments)
    out = [wall_segments(fs, quads, list(w.members), K, params) for w in walls]
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
