"""Façade-level geometry: windows of one wall share a plane, so estimate it once.

Pure functions on image quads (4, 2) px, TL TR BR BL (pixel centres at integers):

- :func:`edge_normals`: each quad side as the unit normal of its interpretation plane (the plane
  through the camera centre and the side), in a camera frame K^-1 [u, v, 1].
- :func:`vanishing_direction`: the 3D direction (unit, camera frame) shared by many sides,
  weighted least squares (smallest eigenvector of sum w n n^T).
- :func:`group_walls`: RANSAC over windows: a hypothesis is the horizontal and vertical
  vanishing directions of one window or of a pair; its inliers are the windows whose four sides all
  point at those vanishing points (image angle within a length-dependent threshold).
- :func:`focal_from_vanishing`: f from two orthogonal vanishing directions, square pixels and a
  known principal point: f^2 = -(v1 - p) . (v2 - p).
- :func:`initial_rotation`: wall rotation (window frame -> camera) from the two vanishing
  directions, signs from the quads' side directions, projected onto SO(3).
- :func:`refine_walls`: Levenberg-Marquardt over all corners of one or more walls: one rotation
  per wall, per window a translation and a width (height fixed: the scale gauge), optionally one
  focal length shared by all, and optionally façade line segments (:class:`LineObs`) as extra
  residuals on the rotations (and f). Returns the estimate and its first-order covariance
  (sigma^2 (J^T J)^-1, or the sandwich form with per-window corner sigmas).
- Façade lines: :func:`detect_segments` (LSD, or Hough on Canny edges) finds straight segments;
  :func:`vp_consensus` picks those that share one vanishing point near a wall's; :func:`line_residuals`
  measures a segment against a vanishing point in pixels.

The window frame is pipeline.pose's: x along the wall (BL -> BR), y up (BL -> TL), z outward,
origin at the bottom-left corner, corners TL TR BR BL = (0,h,0), (w,h,0), (w,0,0), (0,0,0).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from itertools import combinations

import cv2
import numpy as np
from scipy.optimize import least_squares

from fenestra.conventions import TOL, check_K, check_quad, rotation_error_deg
from fenestra.errors import PipelineError


class FacadeError(PipelineError):
    """The wall geometry cannot be estimated (degenerate sides, focal length unobservable, ...)."""


# sides as (start, end) corner indices: horizontal (bottom BL->BR, top TL->TR), vertical
# (left BL->TL, right BR->TR); both point along +x resp. +y of the window frame
H_SIDES = ((3, 2), (0, 1))
V_SIDES = ((3, 0), (2, 1))


def _homog(p: np.ndarray) -> np.ndarray:
    """(N, 2) px -> (N, 3) homogeneous."""
    return np.hstack([p, np.ones((len(p), 1))])


def side_segments(quads: np.ndarray, sides: tuple) -> np.ndarray:
    """(N, 4, 2) quads -> (2N, 2, 2) segments (start, end) px for the given side index pairs."""
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    return np.stack([np.stack([q[:, a], q[:, b]], axis=1) for a, b in sides], axis=1).reshape(-1, 2, 2)


def edge_normals(segments: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Unit interpretation-plane normals (N, 3) of segments (N, 2, 2) px under intrinsics K (3, 3).

    A camera-frame direction d lies along the segment's 3D line iff n . d = 0.
    """
    Ki = np.linalg.inv(check_K(K))
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    a, b = _homog(s[:, 0]) @ Ki.T, _homog(s[:, 1]) @ Ki.T
    n = np.cross(a, b)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(norm < 1e-15):
        raise FacadeError(f"degenerate side (zero length): {s[norm[:, 0] < 1e-15].tolist()}")
    return n / norm


def segment_weights(segments: np.ndarray, sigma_px: float) -> np.ndarray:
    """Reliability (N,) of segments (N, 2, 2) px: (length / sigma)^2, the inverse variance of the
    side's direction when its end points carry isotropic noise sigma_px."""
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    return (np.linalg.norm(s[:, 1] - s[:, 0], axis=1) / float(sigma_px)) ** 2


def vanishing_direction(normals: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Unit direction d (3,) minimising sum_i w_i (n_i . d)^2 over interpretation-plane normals (N, 3).

    Needs at least two non-parallel normals; the sign of d is arbitrary (see :func:`orient`).
    """
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    w = np.ones(len(n)) if weights is None else np.asarray(weights, dtype=np.float64)
    if len(n) < 2:
        raise FacadeError(f"a vanishing direction needs >= 2 sides, got {len(n)}")
    M = (n * w[:, None]).T @ n
    vals, vecs = np.linalg.eigh(M)
    return vecs[:, 0]


def orient(d: np.ndarray, segments: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Sign of direction d (3,) such that it points from each segment's start to its end in 3D
    (majority over segments (N, 2, 2) px); returns +-d."""
    Ki = np.linalg.inv(check_K(K))
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    a, b = _homog(s[:, 0]) @ Ki.T, _homog(s[:, 1]) @ Ki.T
    # d = c0 a + c1 b (least squares, 2x2 normal equations per segment); d points start -> end
    # when the end's depth coefficient c1 exceeds the start's c0 (c1 > 0 > c0 exactly)
    aa, ab, bb = np.sum(a * a, 1), np.sum(a * b, 1), np.sum(b * b, 1)
    ad, bd = a @ d, b @ d
    det = aa * bb - ab ** 2
    c0, c1 = (bb * ad - ab * bd) / det, (aa * bd - ab * ad) / det
    return d if np.sum(np.sign(c1 - c0)) >= 0 else -d


def side_angles_to_vp(segments: np.ndarray, vp: np.ndarray) -> np.ndarray:
    """Image angle (N,) deg between each segment (N, 2, 2) px and the line from its midpoint to the
    homogeneous vanishing point vp (3,) px (finite or at infinity); vp (H, 3): (H, N), per point."""
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    m = _homog(0.5 * (s[:, 0] + s[:, 1]))
    lines = np.cross(m, np.asarray(vp, dtype=np.float64)[..., None, :])
    to_vp = np.stack([lines[..., 1], -lines[..., 0]], axis=-1)
    e = s[:, 1] - s[:, 0]
    c = np.abs(np.sum(to_vp * e, axis=-1)) / (np.linalg.norm(to_vp, axis=-1) * np.linalg.norm(e, axis=1) + 1e-300)
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def side_thresholds_deg(segments: np.ndarray, noise_px: float = TOL.wall_corner_noise_px,
                        base_deg: float = TOL.wall_vp_angle_deg) -> np.ndarray:
    """Inlier threshold (N,) deg per segment: base_deg plus the angle 2 noise_px / length."""
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    length = np.linalg.norm(s[:, 1] - s[:, 0], axis=1)
    return base_deg + np.degrees(np.arctan2(2.0 * noise_px, length))


@dataclass(frozen=True)
class WallVP:
    """Vanishing directions of one wall: d_h (3,) along +x, d_v (3,) along +y of the window frame
    (camera frame, unit, not yet orthogonal); members: indices into the quads given."""

    d_h: np.ndarray
    d_v: np.ndarray
    members: tuple[int, ...]


def fit_vps(quads: np.ndarray, idx: list[int], K: np.ndarray, sigma_px: float = 1.0,
            oriented: bool = True, lines: tuple[np.ndarray, np.ndarray] | None = None,
            line_sigma_px: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(d_h, d_v) (3,) each of windows ``idx`` of quads (N, 4, 2) px: weighted least squares over
    their horizontal resp. vertical sides, oriented along +x / +y of the window frame unless not
    ``oriented`` (sign arbitrary then). lines: façade segments (M_h, 2, 2), (M_v, 2, 2) px along
    the horizontal resp. vertical direction, weighted like the sides with end-point sigma
    ``line_sigma_px`` (the sign still comes from the sides)."""
    out = []
    for f, sides in enumerate((H_SIDES, V_SIDES)):
        seg = side_segments(quads[idx], sides)
        nrm, wts = edge_normals(seg, K), segment_weights(seg, sigma_px)
        if lines is not None and len(lines[f]):
            nrm = np.concatenate([nrm, edge_normals(lines[f], K)])
            wts = np.concatenate([wts, segment_weights(lines[f], line_sigma_px)])
        d = vanishing_direction(nrm, wts)
        out.append(orient(d, seg, K) if oriented else d)
    return out[0], out[1]


@dataclass(frozen=True)
class _Sides:
    """Per window and side family (0: horizontal, 1: vertical): segment midpoints (N, 2, 2, 3)
    homogeneous px, directions (N, 2, 2, 2) px, weighted normal moments sum w n n^T (N, 2, 3, 3),
    inlier thresholds (N, 2, 2) deg."""

    mid: np.ndarray
    dirs: np.ndarray
    moments: np.ndarray
    thresh: np.ndarray

    @classmethod
    def of(cls, q: np.ndarray, K: np.ndarray, sigma_px: float) -> "_Sides":
        n = len(q)
        seg = np.stack([side_segments(q, sides).reshape(n, 2, 2, 2) for sides in (H_SIDES, V_SIDES)], axis=1)
        flat = seg.reshape(-1, 2, 2)
        nrm = edge_normals(flat, K).reshape(n, 2, 2, 3)
        wts = segment_weights(flat, sigma_px).reshape(n, 2, 2)
        moments = np.einsum("nfs,nfsi,nfsj->nfij", wts, nrm, nrm)
        mid = np.concatenate([0.5 * (seg[..., 0, :] + seg[..., 1, :]), np.ones((n, 2, 2, 1))], axis=-1)
        return cls(mid, seg[..., 1, :] - seg[..., 0, :], moments, side_thresholds_deg(flat).reshape(n, 2, 2))

    def directions(self, hyps: np.ndarray) -> np.ndarray:
        """Unoriented (d_h, d_v) (H, 2, 3) of each hypothesis, a (H, N) bool window membership."""
        M = np.einsum("hn,nfij->hfij", hyps.astype(float), self.moments)
        return np.linalg.eigh(M)[1][..., 0]

    def inliers(self, K: np.ndarray, D: np.ndarray) -> np.ndarray:
        """(H, N) bool: windows whose four sides all point at the vanishing points K D[h, f]."""
        vp = D @ K.T  # (H, 2, 3)
        lines = np.cross(self.mid[None], vp[:, None, :, None, :])  # (H, N, 2, 2, 3)
        to_vp = np.stack([lines[..., 1], -lines[..., 0]], axis=-1)
        e = self.dirs[None]
        c = np.abs(np.sum(to_vp * e, axis=-1)) / (np.linalg.norm(to_vp, axis=-1) * np.linalg.norm(e, axis=-1) + 1e-300)
        ang = np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))
        return np.all(ang <= self.thresh[None], axis=(2, 3))


def group_walls(quads: np.ndarray, K: np.ndarray, sigma_px: float = 1.0,
                max_pair_windows: int = 8) -> list[WallVP]:
    """Group window quads (N, 4, 2) px into walls by their vanishing directions (RANSAC).

    K (3, 3): intrinsics, or any pseudo-K with the right principal point when the focal length is
    unknown (inlier tests are image angles, so its focal length barely matters). Hypotheses: every
    window alone and every pair of the ``max_pair_windows`` largest; the one with most inliers
    (ties: the fewest windows in the hypothesis) wins, is refitted on its inliers, removed, and the
    rest is grouped again. Every window ends in exactly one group; a window agreeing with no other
    is a wall of its own. Largest walls first.
    """
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    K = check_K(K)
    n = len(q)
    sd = _Sides.of(q, K, sigma_px)
    left = np.ones(n, dtype=bool)
    areas = 0.5 * np.abs(np.sum(q[:, :, 0] * np.roll(q[:, :, 1], -1, 1) - q[:, :, 1] * np.roll(q[:, :, 0], -1, 1), 1))
    walls: list[WallVP] = []
    while left.any():
        idx = np.flatnonzero(left)
        big = idx[np.argsort(-areas[idx])][:max_pair_windows]
        hyps = [np.eye(n, dtype=bool)[idx]]
        if len(big) > 1:
            pairs = np.array(list(combinations(big, 2)))
            h2 = np.zeros((len(pairs), n), dtype=bool)
            h2[np.arange(len(pairs))[:, None], pairs] = True
            hyps.append(h2)
        hyps = np.concatenate(hyps)
        inl = sd.inliers(K, sd.directions(hyps)) & left
        valid = ~np.any(hyps & ~inl, axis=1)  # a hypothesis must agree with its own windows
        score = np.where(valid, inl.sum(axis=1) * 4 - hyps.sum(axis=1), -1)
        members = inl[int(np.argmax(score))] if valid.any() else np.eye(n, dtype=bool)[idx[0]]
        for _ in range(2):  # refit on the inliers, re-collect
            new = sd.inliers(K, sd.directions(members[None]))[0] & left
            if not new.any() or np.array_equal(new, members):
                break
            members = new
        mem = np.flatnonzero(members).tolist()
        d_h, d_v = fit_vps(q, mem, K, sigma_px)
        walls.append(WallVP(d_h, d_v, tuple(mem)))
        left &= ~members
    return sorted(walls, key=lambda w: -len(w.members))


def focal_from_vanishing(d_h: np.ndarray, d_v: np.ndarray, K0: np.ndarray) -> float | None:
    """Focal length (px) from two orthogonal vanishing directions d_h, d_v (3,) found under a
    pseudo-K0 (3, 3) (square pixels, principal point p = K0[:2, 2]): f^2 = -(v1 - p).(v2 - p).

    None when undefined: a vanishing point at infinity (its side pair parallel in the image) or
    f^2 <= 0 (the two directions are not seen as orthogonal).
    """
    v1, v2 = check_K(K0) @ d_h, K0 @ d_v
    p = K0[:2, 2]
    if min(abs(v1[2]), abs(v2[2])) < 1e-9 * max(np.linalg.norm(v1), np.linalg.norm(v2)):
        return None
    f2 = -float((v1[:2] / v1[2] - p) @ (v2[:2] / v2[2] - p))
    return float(np.sqrt(f2)) if f2 > 0 else None


def initial_rotation(d_h: np.ndarray, d_v: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) window frame -> camera: the closest one to columns [d_h, d_v, d_h x d_v]."""
    M = np.stack([d_h, d_v, np.cross(d_h, d_v)], axis=1)
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
    return R


def window_init(quad: np.ndarray, K: np.ndarray, R: np.ndarray, height: float) -> tuple[np.ndarray, float]:
    """Translation t (3,) and width w (m) of a window of height ``height`` with rotation R, from its
    quad (4, 2) px by linear least squares on the ray depths (BL = t, TL = t + h r2, BR = t + w r1)."""
    a = _homog(check_quad(quad)) @ np.linalg.inv(K).T  # rays TL TR BR BL
    r1, r2 = R[:, 0], R[:, 1]
    # lam_TL a_TL - lam_BL a_BL = h r2
    lam = np.linalg.lstsq(np.stack([a[0], -a[3]], axis=1), height * r2, rcond=None)[0]
    t = lam[1] * a[3]
    # lam_BR a_BR - w r1 = t ; and TR: lam_TR a_TR - w r1 = t + h r2
    A = np.zeros((6, 3))
    A[:3, 0], A[:3, 2] = a[2], -r1
    A[3:, 1], A[3:, 2] = a[1], -r1
    x = np.linalg.lstsq(A, np.concatenate([t, t + height * r2]), rcond=None)[0]
    return t, float(max(x[2], 1e-3 * height))


@dataclass(frozen=True)
class WallFit:
    """Joint estimate of G walls with N windows.

    R (G, 3, 3): each rotation group's frame -> camera rotation (a group: one wall, or walls tied
    at right angles, see :func:`tie_walls`); wall_of (N,): each window's group; Q (N, 3, 3): each
    window's fixed rotation within its group (identity for a plain wall), so its rotation is
    R[wall_of[i]] @ Q[i] (:meth:`window_R`);
    t (N, 3) m and width (N,) m per window (height fixed at ``height``); focal_px: the focal length
    used (estimated when ``focal_free``); reprojected (N, 4, 2) px; rms_px: reprojection RMS;
    sigma_px: the corner sigma used for the covariance; cov (P, P): first-order covariance of the
    parameters [omega (3, rad) per wall, (t_i (3), w_i) per window, f if free]; dof: residuals
    minus parameters; n_lines: façade line segments in the fit (:class:`LineObs`).
    """

    R: np.ndarray
    wall_of: np.ndarray
    Q: np.ndarray
    t: np.ndarray
    width: np.ndarray
    height: float
    focal_px: float
    focal_free: bool
    reprojected: np.ndarray
    rms_px: float
    sigma_px: float
    cov: np.ndarray
    dof: int
    n_lines: int = 0

    def window_R(self, i: int) -> np.ndarray:
        """Window i's rotation (3, 3), window frame -> camera."""
        return self.R[int(self.wall_of[i])] @ self.Q[i]

    def rot_block(self, i: int) -> slice:
        """Covariance index range of window i's wall rotation vector."""
        g = int(self.wall_of[i])
        return slice(3 * g, 3 * g + 3)

    def window_block(self, i: int) -> slice:
        """Covariance index range of window i's (t (3), width)."""
        k = 3 * len(self.R) + 4 * i
        return slice(k, k + 4)


def _unpack(x: np.ndarray, n_walls: int, n: int, R0: np.ndarray, K: np.ndarray, focal_free: bool):
    R = np.array([cv2.Rodrigues(x[3 * g:3 * g + 3])[0] @ R0[g] for g in range(n_walls)])
    per = x[3 * n_walls:3 * n_walls + 4 * n].reshape(n, 4)
    Kx = K.copy()
    if focal_free:
        Kx[0, 0] = Kx[1, 1] = x[-1]
    return R, per[:, :3], per[:, 3], Kx


def project_wall(R: np.ndarray, t: np.ndarray, width: np.ndarray, height: float, K: np.ndarray) -> np.ndarray:
    """Corners (N, 4, 2) px of N windows (widths (N,), common height) with rotation R (3, 3) shared
    or (N, 3, 3) per window, translations t (N, 3), intrinsics K (3, 3)."""
    w = np.asarray(width, dtype=np.float64).reshape(-1, 1)
    Rn = np.broadcast_to(np.asarray(R, dtype=np.float64), (len(w), 3, 3))
    obj_x = w * np.array([0.0, 1.0, 1.0, 0.0])  # (N, 4) window-frame x; y = height * (1, 1, 0, 0)
    obj_y = np.broadcast_to(height * np.array([1.0, 1.0, 0.0, 0.0]), obj_x.shape)
    X = (obj_x[..., None] * Rn[:, None, :, 0] + obj_y[..., None] * Rn[:, None, :, 1]
         + np.asarray(t).reshape(-1, 1, 3))
    x = X @ K.T
    return x[..., :2] / x[..., 2:3]


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def left_jacobian(omega: np.ndarray) -> np.ndarray:
    """SO(3) left Jacobian (3, 3) of a rotation vector omega (3,) rad: d(exp(omega) v) / d omega
    = -[exp(omega) v]_x J_l(omega)."""
    th = float(np.linalg.norm(omega))
    W = _skew(omega)
    if th < 1e-8:
        return np.eye(3) + 0.5 * W
    return np.eye(3) + (1.0 - np.cos(th)) / th ** 2 * W + (th - np.sin(th)) / th ** 3 * (W @ W)


def wall_jacobian(x: np.ndarray, n_walls: int, wall_of: np.ndarray, R0: np.ndarray, K: np.ndarray,
                  height: float, focal_free: bool, Q: np.ndarray | None = None) -> np.ndarray:
    """Analytic Jacobian (8N, P) of :func:`refine_walls`' residuals (corners TL TR BR BL, u then v)
    with respect to its parameters x (P,) [omega per group, (t, w) per window, f if free]; Q (N, 3, 3)
    the windows' fixed rotations within their groups (None: identity)."""
    n = len(wall_of)
    R, t, w, Kx = _unpack(x, n_walls, n, R0, K, focal_free)
    Rn = R[wall_of] if Q is None else R[wall_of] @ Q  # (n, 3, 3)
    cx_ = np.array([0.0, 1.0, 1.0, 0.0])
    cy_ = height * np.array([1.0, 1.0, 0.0, 0.0])
    v = (w[:, None, None] * cx_[None, :, None] * Rn[:, None, :, 0]
         + cy_[None, :, None] * Rn[:, None, :, 1])  # (n, 4, 3) rotated object points
    X = v + t[:, None, :]
    Z = X[..., 2]
    dpi = np.zeros((n, 4, 2, 3))  # d(u, v) / dX
    dpi[..., 0, 0], dpi[..., 0, 2] = Kx[0, 0] / Z, -Kx[0, 0] * X[..., 0] / Z ** 2
    dpi[..., 1, 1], dpi[..., 1, 2] = Kx[1, 1] / Z, -Kx[1, 1] * X[..., 1] / Z ** 2
    Jl = np.array([left_jacobian(x[3 * g:3 * g + 3]) for g in range(n_walls)])
    # d/d omega: dpi @ (-[v]_x J_l) = (v x dpi_row) @ J_l
    rot = np.einsum("njkc,ncd->njkd", np.cross(v[:, :, None, :], dpi), Jl[wall_of])
    J_rot = np.zeros((n, 4, 2, n_walls, 3))
    J_rot[np.arange(n), :, :, wall_of, :] = rot
    block = np.concatenate([dpi, (dpi @ Rn[:, None, :, 0][..., None]) * cx_[None, :, None, None]], axis=3)
    J_win = np.zeros((n, 4, 2, n, 4))
    J_win[np.arange(n), :, :, np.arange(n), :] = block
    parts = [J_rot.reshape(8 * n, 3 * n_walls), J_win.reshape(8 * n, 4 * n)]
    if focal_free:
        parts.append((X[..., :2] / Z[..., None]).reshape(8 * n, 1))
    return np.hstack(parts)


def _inverse(A: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive semi-definite (P, P) matrix (pseudo-inverse if singular)."""
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A)


def refine_walls(quads: np.ndarray, K: np.ndarray, R0: np.ndarray, wall_of: np.ndarray | None = None,
                 height: float = 1.0, focal_free: bool = False, sigma_px: float = 1.0,
                 prior_dof: float = 0.0, Q: np.ndarray | None = None, lines: "LineObs | None" = None,
                 corner_sigma: np.ndarray | None = None) -> WallFit:
    """Joint LM over all corners of the windows of one or more walls (quads (N, 4, 2) px).

    R0: (3, 3) for one wall, or (G, 3, 3) with wall_of (N,) giving each window's wall. Parameters:
    per wall a rotation (a rotation vector applied to R0[g]), per window t (3,) m and width (m) at
    the fixed ``height`` (the gauge: single-image scale is unknown per window), and one focal length
    when ``focal_free`` (square pixels, K's principal point). Covariance sigma^2 (J^T J)^-1 with
    sigma^2 the residuals' variance pooled with ``prior_dof`` pseudo-observations of ``sigma_px``
    (prior_dof = inf: the fixed sigma_px). Q (N, 3, 3): a fixed rotation of each window within its
    group (walls at right angles sharing one rotation: window i's is R[wall_of[i]] @ Q[i]); None:
    identity. lines: façade line segments along the groups' axes, an extra residual each on the
    rotations (and f); None: corners only. corner_sigma (N,) px: each window's own corner sigma
    for the covariance (at least the pooled one; the estimate stays unweighted, so the covariance
    is the sandwich (J^T J)^-1 J^T V J (J^T J)^-1 with V the residuals' variances); None: the
    pooled sigma for all. Raises FacadeError if the fit fails.
    """
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    n = len(q)
    Q = np.broadcast_to(np.eye(3), (n, 3, 3)) if Q is None else np.asarray(Q, dtype=np.float64).reshape(n, 3, 3)
    K = check_K(K)
    R0 = np.asarray(R0, dtype=np.float64).reshape(-1, 3, 3)
    G = len(R0)
    wall_of = np.zeros(n, dtype=int) if wall_of is None else np.asarray(wall_of, dtype=int)
    if wall_of.shape != (n,) or wall_of.min() < 0 or wall_of.max() >= G:
        raise ValueError(f"wall_of must be (N,) = ({n},) indices into {G} wall(s), got {wall_of.tolist()}")
    x0 = [np.zeros(3 * G)]
    for quad, g, Qi in zip(q, wall_of, Q):
        t, w = window_init(quad, K, R0[g] @ Qi, height)
        x0.append(np.append(t, w))
    if focal_free:
        x0.append([np.sqrt(K[0, 0] * K[1, 1])])
    x0 = np.concatenate(x0)

    def residuals(x: np.ndarray) -> np.ndarray:
        R, t, w, Kx = _unpack(x, G, n, R0, K, focal_free)
        r = (project_wall(R[wall_of] @ Q, t, w, height, Kx) - q).ravel()
        return r if lines is None else np.concatenate([r, lines.residuals(R, Kx)])

    def jacobian(x: np.ndarray) -> np.ndarray:
        J = wall_jacobian(x, G, wall_of, R0, K, height, focal_free, Q)
        if lines is None:
            return J
        R, _, _, Kx = _unpack(x, G, n, R0, K, focal_free)
        return np.vstack([J, lines.jacobian(x, R, Kx, len(x), focal_free)])

    sol = least_squares(residuals, x0, jac=jacobian, method="lm", x_scale="jac")
    if not np.all(np.isfinite(sol.x)):
        raise FacadeError(f"wall refinement diverged ({sol.message})")
    R, t, w, Kx = _unpack(sol.x, G, n, R0, K, focal_free)
    if np.any(w <= 0) or np.any(t[:, 2] <= 0) or Kx[0, 0] <= 0:
        raise FacadeError(f"wall refinement gives a window behind the camera, a width <= 0 or f <= 0 "
                          f"(widths {np.round(w, 4).tolist()}, f {Kx[0, 0]:.1f})")
    r = sol.fun
    dof = len(r) - len(sol.x)
    rss = float(r @ r)
    if np.isinf(prior_dof):
        s2 = sigma_px ** 2
    else:
        s2 = (rss + prior_dof * sigma_px ** 2) / max(dof + prior_dof, 1e-9)
    J = sol.jac
    cov = _inverse(J.T @ J) * s2
    if corner_sigma is not None:
        v = np.full(len(r), s2)
        v[:8 * n] = np.maximum(s2, np.repeat(np.asarray(corner_sigma, dtype=np.float64) ** 2, 8))
        A = cov / s2
        cov = A @ ((J.T * v) @ J) @ A
    return WallFit(R=R, wall_of=wall_of, Q=np.array(Q), t=t, width=w, height=float(height), focal_px=float(Kx[0, 0]),
                   focal_free=focal_free, reprojected=project_wall(R[wall_of] @ Q, t, w, height, Kx),
                   rms_px=float(np.sqrt(rss / len(r))), sigma_px=float(np.sqrt(s2)), cov=cov, dof=dof,
                   n_lines=0 if lines is None else len(lines))


def rot_y(deg: float) -> np.ndarray:
    """Rotation (3, 3) about the window frame's y axis (up) by ``deg``."""
    c, s_ = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, 0.0, s_], [0.0, 1.0, 0.0], [-s_, 0.0, c]])


def tie_walls(R0: np.ndarray, tol_deg: float = TOL.manhattan_deg) -> tuple[np.ndarray, np.ndarray]:
    """Tie walls at right angles (one vertical, headings k x 90 deg apart: a rectilinear building).

    R0 (G, 3, 3): the walls' rotations, largest wall first. Each wall joins the first group whose
    reference wall it matches as R_ref @ rot_y(k 90) within ``tol_deg`` (geodesic), else starts its
    own group. Returns group (G,) int and Q (G, 3, 3): wall g's rotation is R_group @ Q[g].
    """
    R0 = np.asarray(R0, dtype=np.float64).reshape(-1, 3, 3)
    refs: list[int] = []
    group = np.zeros(len(R0), dtype=int)
    Q = np.repeat(np.eye(3)[None], len(R0), axis=0)
    for g, Rg in enumerate(R0):
        for k, r in enumerate(refs):
            cands = [rot_y(90.0 * m) for m in range(4)]
            errs = [rotation_error_deg(R0[r] @ c, Rg) for c in cands]
            m = int(np.argmin(errs))
            if errs[m] <= tol_deg:
                group[g], Q[g] = k, cands[m]
                break
        else:
            group[g] = len(refs)
            refs.append(g)
    return group, Q



# ------------------------------------------------------------------ façade lines

def _lsd(gray: np.ndarray, min_length_px: float) -> np.ndarray | None:
    return cv2.createLineSegmentDetector().detect(gray)[0]


def _hough(gray: np.ndarray, min_length_px: float) -> np.ndarray | None:
    edges = cv2.Canny(gray, 50, 150)
    return cv2.HoughLinesP(edges, 1.0, np.pi / 720.0, threshold=int(min_length_px),
                           minLineLength=min_length_px, maxLineGap=2.0)


SEGMENT_DETECTORS = {"lsd": _lsd, "hough": _hough}  # LSD: OpenCV's line segment detector (sub-pixel)


def detect_segments(gray: np.ndarray, min_length_px: float, method: str = "lsd") -> np.ndarray:
    """Straight line segments (M, 2, 2) px (start, end; pixel centres at integers) at least
    ``min_length_px`` long in a gray image (H, W), uint8 or float in [0, 255] (rounded to uint8):
    ``lsd`` (OpenCV's line segment detector, sub-pixel, within about 0.15 px of a step edge) or
    ``hough`` (probabilistic Hough on Canny edges).

    The last result is kept, keyed on the uint8 image's content (a digest), the method and the
    length: one photo's segments are found once, though ``fenestra reconstruct`` asks for them
    twice (the focal fit without K, then the wall fit); LSD on a 6000x4000 photo takes ~3 s and
    ~0.5 GB. A copy is returned.
    """
    g = np.asarray(gray)
    if g.ndim != 2 or not (g.dtype == np.uint8 or np.issubdtype(g.dtype, np.floating)):
        raise ValueError(f"gray must be an (H, W) uint8 or float image, got shape {g.shape} dtype {g.dtype}")
    if g.dtype != np.uint8:
        r = np.round(g)
        g = np.clip(r, 0, 255, out=r).astype(np.uint8)
        del r
    if method not in SEGMENT_DETECTORS:
        raise ValueError(f"unknown segment detector {method!r}; known: {sorted(SEGMENT_DETECTORS)}")
    g = np.ascontiguousarray(g)
    key = (g.shape, hashlib.blake2b(g.data, digest_size=16).digest(), method, float(min_length_px))
    last = _LAST_SEGMENTS[0]
    if last is None or last[0] != key:
        found = SEGMENT_DETECTORS[method](g, float(min_length_px))
        seg = np.zeros((0, 2, 2)) if found is None else np.asarray(found, dtype=np.float64).reshape(-1, 2, 2)
        last = _LAST_SEGMENTS[0] = (key, seg[np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) >= min_length_px])
    return last[1].copy()


_LAST_SEGMENTS: list = [None]  # detect_segments' last (key, segments), replaced as one object


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
    m = _homog(0.5 * (s[:, 0] + s[:, 1]))
    c = np.cross(_homog(s[:, 1]), m)  # r ~ c . v: the end's offset from the line m x v
    line = np.cross(m, v)
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
        rot = np.einsum("mc,mcd->md", np.cross(d, g @ K), Jl[self.group])
        for k in range(len(R)):
            sel = self.group == k
            J[sel, 3 * k:3 * k + 3] = rot[sel]
        if focal_free:
            J[:, -1] = g[:, 0] * d[:, 0] + g[:, 1] * d[:, 1]
        return J
