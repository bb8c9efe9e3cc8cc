"""The joint fit of one or more walls: Levenberg-Marquardt over all their windows' corners, its
covariance, and each window's uncertainty intervals.

- :func:`refine_walls`: LM over all corners of one or more walls: one rotation per wall (or per
  group of walls tied at right angles), per window a translation and a width (height fixed: the
  scale gauge), optionally one focal length shared by all, and optionally façade line segments
  (pipeline.walls.lines.LineObs) as extra residuals on the rotations (and f). Analytic Jacobian
  (:func:`wall_jacobian`). Returns the estimate (:class:`WallFit`) and its first-order covariance
  (sigma^2 (J^T J)^-1, or the sandwich form with per-window corner sigmas).
- :func:`window_uncertainty`: a window's intervals from that covariance (aspect, rotation,
  translation) at WALL_FIT.interval_level, and whether it is ill-conditioned.

The window frame is pipeline.pose's: x along the wall (BL -> BR), y up (BL -> TL), z outward,
origin at the bottom-left corner, corners TL TR BR BL = (0,h,0), (w,h,0), (w,0,0), (0,0,0).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np
from scipy import special
from scipy.optimize import least_squares

from fenestra.checks import check_K, check_quad
from fenestra.pipeline.types import Uncertainty
from fenestra.pipeline.walls.settings import WALL_FIT
from fenestra.pipeline.walls.vanishing import FacadeError, cross3, homog

if TYPE_CHECKING:  # annotations only: lines imports this module
    from fenestra.pipeline.walls.lines import LineObs


def window_init(quad: np.ndarray, K: np.ndarray, R: np.ndarray, height: float,
                Ki: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Translation t (3,) and width w (m) of a window of height ``height`` with rotation R, from its
    quad (4, 2) px by linear least squares on the ray depths (BL = t, TL = t + h r2, BR = t + w r1).
    Ki: np.linalg.inv(K) when the caller has it (None: computed here)."""
    a = homog(check_quad(quad)) @ (np.linalg.inv(K) if Ki is None else Ki).T  # rays TL TR BR BL
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


# the corners TL TR BR BL in the window frame: x = width * CORNER_X, y = height * CORNER_Y
CORNER_X = np.array([0.0, 1.0, 1.0, 0.0])
CORNER_Y = np.array([1.0, 1.0, 0.0, 0.0])


def _corners_cam(Rn: np.ndarray, t: np.ndarray, w: np.ndarray, height: float) -> tuple[np.ndarray, np.ndarray]:
    """The rotated corner offsets v (N, 4, 3) and camera-frame corners X = v + t (N, 4, 3) of N
    windows: rotations Rn (N, 3, 3), translations t (N, 3), widths w (N,)."""
    v = (w[:, None, None] * CORNER_X[None, :, None] * Rn[:, None, :, 0]
         + (height * CORNER_Y)[None, :, None] * Rn[:, None, :, 1])
    return v, v + t[:, None, :]


def project_wall(R: np.ndarray, t: np.ndarray, width: np.ndarray, height: float, K: np.ndarray) -> np.ndarray:
    """Corners (N, 4, 2) px of N windows (widths (N,), common height) with rotation R (3, 3) shared
    or (N, 3, 3) per window, translations t (N, 3), intrinsics K (3, 3)."""
    w = np.asarray(width, dtype=np.float64).reshape(-1)
    Rn = np.broadcast_to(np.asarray(R, dtype=np.float64), (len(w), 3, 3))
    return _project(_corners_cam(Rn, np.asarray(t, dtype=np.float64).reshape(-1, 3), w, height)[1], K)


def _project(X: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Pixels (..., 2) of camera-frame points X (..., 3) under K (3, 3)."""
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
    wall_of = np.asarray(wall_of)
    R, t, w, Kx = _unpack(x, n_walls, len(wall_of), R0, K, focal_free)
    Rn = R[wall_of] if Q is None else R[wall_of] @ Q  # (n, 3, 3)
    return _jacobian(x, n_walls, wall_of, Rn, t, w, Kx, height, focal_free)


def _jacobian(x: np.ndarray, n_walls: int, wall_of: np.ndarray, Rn: np.ndarray, t: np.ndarray, w: np.ndarray,
              Kx: np.ndarray, height: float, focal_free: bool) -> np.ndarray:
    """:func:`wall_jacobian` at x (P,) unpacked: the windows' rotations Rn (n, 3, 3), translations t
    (n, 3), widths w (n,), intrinsics Kx (3, 3). Written into one (8n, P) array: the rows of window
    i are zero outside its group's rotation, its own (t, w) and f."""
    n = len(wall_of)
    v, X = _corners_cam(Rn, t, w, height)  # (n, 4, 3) rotated object points, camera-frame corners
    Z = X[..., 2]
    dpi = np.zeros((n, 4, 2, 3))  # d(u, v) / dX
    dpi[..., 0, 0], dpi[..., 0, 2] = Kx[0, 0] / Z, -Kx[0, 0] * X[..., 0] / Z ** 2
    dpi[..., 1, 1], dpi[..., 1, 2] = Kx[1, 1] / Z, -Kx[1, 1] * X[..., 1] / Z ** 2
    Jl = np.array([left_jacobian(x[3 * g:3 * g + 3]) for g in range(n_walls)])
    J = np.zeros((n, 4, 2, len(x)))
    rows = np.arange(n)[:, None]
    # d/d omega: dpi @ (-[v]_x J_l) = (v x dpi_row) @ J_l; (n, 4, 2, 3) into columns 3 g .. 3 g + 2
    rot = np.einsum("njkc,ncd->njkd", cross3(v[:, :, None, :], dpi), Jl[wall_of])
    J[rows, :, :, 3 * wall_of[:, None] + np.arange(3)] = rot.transpose(0, 3, 1, 2)
    # d/d (t, w): dpi, and dpi @ r1 x the corner's x; (n, 4, 2, 4) into columns 3 G + 4 i .. + 3
    dw = (dpi @ Rn[:, None, :, 0][..., None]) * CORNER_X[None, :, None, None]
    J[rows, :, :, 3 * n_walls + 4 * rows + np.arange(3)] = dpi.transpose(0, 3, 1, 2)
    J[np.arange(n), :, :, 3 * n_walls + 4 * np.arange(n) + 3] = dw[..., 0]
    if focal_free:
        J[..., -1] = X[..., :2] / Z[..., None]
    return J.reshape(8 * n, len(x))


class _Unpacked:
    """The parameters x of :func:`refine_walls` unpacked (:func:`_unpack`) with the windows'
    rotations Rn = R[wall_of] @ Q, for the residuals and the Jacobian: the last x's kept, since the
    solver asks for the Jacobian where it last evaluated the residuals (one fit's state, not shared)."""

    def __init__(self, n_walls: int, wall_of: np.ndarray, R0: np.ndarray, K: np.ndarray, Q: np.ndarray,
                 focal_free: bool) -> None:
        self.args = (n_walls, len(wall_of), R0, K, focal_free)
        self.wall_of, self.Q = wall_of, Q
        self.last: tuple[bytes, tuple] | None = None

    def __call__(self, x: np.ndarray) -> tuple:
        k = x.tobytes()
        if self.last is None or self.last[0] != k:
            R, t, w, Kx = _unpack(x, *self.args)
            self.last = (k, (R, t, w, Kx, R[self.wall_of] @ self.Q))
        return self.last[1]


class _Runaway(Exception):
    """A free focal length left refine_walls' focal_bounds (args[0]: its value, px)."""


def _inverse(A: np.ndarray) -> np.ndarray:
    """Inverse of a symmetric positive semi-definite (P, P) matrix (pseudo-inverse if singular)."""
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A)


def refine_walls(quads: np.ndarray, K: np.ndarray, R0: np.ndarray, wall_of: np.ndarray | None = None,
                 height: float = 1.0, focal_free: bool = False, sigma_px: float = 1.0,
                 prior_dof: float = 0.0, Q: np.ndarray | None = None, lines: "LineObs | None" = None,
                 corner_sigma: np.ndarray | None = None, max_nfev: int | None = WALL_FIT.max_nfev,
                 focal_bounds: tuple[float, float] | None = None) -> WallFit:
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
    pooled sigma for all. max_nfev: at most this many residual evaluations (None: scipy's default,
    100 x (P + 1)); with ``focal_free`` not converging within them raises, with K fixed the last
    estimate is kept. focal_bounds (lo, hi) px: with ``focal_free``, the fit stops (FacadeError) as
    soon as f leaves them (a runaway focal length; None: no bound). Raises FacadeError if the fit fails.
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
    Ki = np.linalg.inv(K)
    for quad, g, Qi in zip(q, wall_of, Q):
        t, w = window_init(quad, K, R0[g] @ Qi, height, Ki)
        x0.append(np.append(t, w))
    if focal_free:
        x0.append([np.sqrt(K[0, 0] * K[1, 1])])
    x0 = np.concatenate(x0)
    at = _Unpacked(G, wall_of, R0, K, Q, focal_free)

    def residuals(x: np.ndarray) -> np.ndarray:
        if focal_free and focal_bounds is not None and not focal_bounds[0] <= x[-1] <= focal_bounds[1]:
            raise _Runaway(float(x[-1]))
        R, t, w, Kx, Rn = at(x)
        r = (_project(_corners_cam(Rn, t, w, height)[1], Kx) - q).ravel()
        return r if lines is None else np.concatenate([r, lines.residuals(R, Kx)])

    def jacobian(x: np.ndarray) -> np.ndarray:
        R, t, w, Kx, Rn = at(x)
        J = _jacobian(x, G, wall_of, Rn, t, w, Kx, height, focal_free)
        if lines is None:
            return J
        return np.vstack([J, lines.jacobian(x, R, Kx, len(x), focal_free)])

    try:
        sol = least_squares(residuals, x0, jac=jacobian, method="lm", x_scale="jac", max_nfev=max_nfev)
    except _Runaway as e:
        raise FacadeError(f"focal length unobservable: f ran away to {e.args[0]:.0f} px, outside "
                          f"[{focal_bounds[0]:.0f}, {focal_bounds[1]:.0f}] px, during the joint fit") from None
    if focal_free and sol.status == 0:
        raise FacadeError(f"focal length unobservable: the joint fit did not converge in {sol.nfev} evaluations "
                          f"(f = {sol.x[-1]:.0f} px)")
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


def norm_quantile(cov: np.ndarray, level: float = WALL_FIT.interval_level) -> float:
    """``level`` quantile of |x| for x ~ N(0, cov (3, 3)): Satterthwaite's scaled chi-square,
    |x|^2 ~ c chi2(nu) with c = tr(S^2) / tr(S), nu = tr(S)^2 / tr(S^2) (exact when isotropic)."""
    S = 0.5 * (cov + cov.T)
    tr, tr2 = float(np.trace(S)), float(np.sum(S * S))
    if not tr > 0:
        return 0.0
    return float(np.sqrt(tr2 / tr * chi2_ppf(level, tr * tr / tr2)))


def chi2_ppf(level: float, dof: float) -> float:
    """scipy.stats.chi2.ppf(level, dof) for 0 < level < 1 and dof > 0, without its argument
    handling (the same special function: 2 gammaincinv(dof / 2, level), bit for bit)."""
    return float(2 * special.gammaincinv(dof / 2, level))


def norm_ppf(level: float) -> float:
    """scipy.stats.norm.ppf(level) for 0 < level < 1 (special.ndtri, bit for bit)."""
    return float(special.ndtri(level))


def window_uncertainty(fit: WallFit, i: int, level: float = WALL_FIT.interval_level) -> Uncertainty:
    """90 % intervals of window i of a wall fit: aspect (lo, hi), rotation (deg), |dt| / |t|
    (pipeline.types.Uncertainty)."""
    z = norm_ppf(0.5 + level / 2.0)
    wb, rb = fit.window_block(i), fit.rot_block(i)
    cw = fit.cov[wb, wb]
    a = fit.width[i] / fit.height
    a_sd = float(np.sqrt(max(cw[3, 3], 0.0))) / fit.height
    rot = np.degrees(norm_quantile(fit.cov[rb, rb], level))
    trans = norm_quantile(cw[:3, :3], level) / float(np.linalg.norm(fit.t[i]))
    ill = bool(z * a_sd / a > WALL_FIT.ill_conditioned_aspect_rel or rot > WALL_FIT.ill_conditioned_rot_deg)
    return Uncertainty(level=level, sigma_px=fit.sigma_px, aspect_sd=a_sd, aspect_lo=a - z * a_sd,
                       aspect_hi=a + z * a_sd, rot_deg=float(rot), trans_rel=float(trans), ill_conditioned=ill)
