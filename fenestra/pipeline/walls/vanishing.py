"""Vanishing points of a photo's windows: group the windows into walls, a wall's rotation.

Pure functions on image quads (4, 2) px, TL TR BR BL (pixel centres at integers):

- :func:`edge_normals`: each quad side as the unit normal of its interpretation plane (the plane
  through the camera centre and the side), in a camera frame K^-1 [u, v, 1].
- :func:`vanishing_direction`: the 3D direction (unit, camera frame) shared by many sides,
  weighted least squares (smallest eigenvector of sum w n n^T).
- :func:`group_walls`: RANSAC over windows: a hypothesis is the horizontal and vertical
  vanishing directions of one window or of a pair; its inliers are the windows whose four sides all
  point at those vanishing points (image angle within a length-dependent threshold,
  WALL_FIT.vp_angle_deg and WALL_FIT.corner_noise_px).
- :func:`focal_from_vanishing`: f from two orthogonal vanishing directions, square pixels and a
  known principal point: f^2 = -(v1 - p) . (v2 - p).
- :func:`initial_rotation`: wall rotation (window frame -> camera) from the two vanishing
  directions, signs from the quads' side directions, projected onto SO(3).
- :func:`tie_walls`: walls at right angles about a shared vertical tied into one rotation.

The window frame is pipeline.pose's: x along the wall (BL -> BR), y up (BL -> TL), z outward,
origin at the bottom-left corner, corners TL TR BR BL = (0,h,0), (w,h,0), (w,0,0), (0,0,0).
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

from fenestra.checks import check_K
from fenestra.conventions import rotation_error_deg
from fenestra.errors import PipelineError
from fenestra.pipeline.walls.settings import WALL_FIT


class FacadeError(PipelineError):
    """The wall geometry cannot be estimated (degenerate sides, focal length unobservable, ...)."""


# sides as (start, end) corner indices: horizontal (bottom BL->BR, top TL->TR), vertical
# (left BL->TL, right BR->TR); both point along +x resp. +y of the window frame
H_SIDES = ((3, 2), (0, 1))
V_SIDES = ((3, 0), (2, 1))


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (3) of broadcastable arrays: np.cross's products in np.cross's
    order (bit-identical), without its axis moves (the RANSAC hypotheses and the wall fit's Jacobian call it in their loops)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    sa, sb = np.shape(a), np.shape(b)
    out = np.empty(sa if sa == sb else np.broadcast_shapes(sa, sb), dtype=np.result_type(a0, b0))
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


def homog(p: np.ndarray) -> np.ndarray:
    """(N, 2) px -> (N, 3) homogeneous."""
    out = np.ones((len(p), 3))
    out[:, :2] = p
    return out


def side_segments(quads: np.ndarray, sides: tuple) -> np.ndarray:
    """(N, 4, 2) quads -> (2N, 2, 2) segments (start, end) px for the given side index pairs."""
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    return np.stack([np.stack([q[:, a], q[:, b]], axis=1) for a, b in sides], axis=1).reshape(-1, 2, 2)


def edge_normals(segments: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Unit interpretation-plane normals (N, 3) of segments (N, 2, 2) px under intrinsics K (3, 3).

    A camera-frame direction d lies along the segment's 3D line iff n . d = 0.
    """
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    return unit_normals(s, *plane_normals(*rays(s, np.linalg.inv(check_K(K)))))


def rays(segments: np.ndarray, Ki: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame rays K^-1 [u, v, 1] (N, 3) of the start and end points of segments (N, 2, 2)
    px, Ki = K^-1 (3, 3)."""
    return homog(segments[:, 0]) @ Ki.T, homog(segments[:, 1]) @ Ki.T


def plane_normals(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Interpretation-plane normals a x b (N, 3), not normalised, of segments with end rays a, b
    (N, 3) (:func:`rays`), and their lengths (N, 1) (see :func:`unit_normals`)."""
    n = cross3(a, b)
    return n, np.linalg.norm(n, axis=1, keepdims=True)


def unit_normals(segments: np.ndarray, n: np.ndarray, norm: np.ndarray) -> np.ndarray:
    """n / norm (:func:`plane_normals` of segments (N, 2, 2) px); FacadeError naming a degenerate
    segment (zero length) among them."""
    if np.any(norm < 1e-15):
        raise FacadeError(f"degenerate side (zero length): {segments[norm[:, 0] < 1e-15].tolist()}")
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
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    return _Orientation.of(*rays(s, np.linalg.inv(check_K(K)))).orient(d)


@dataclass(frozen=True)
class _Orientation:
    """What :func:`orient` needs of segments besides d: their end rays a, b (N, 3) (:func:`rays`)
    and the 2x2 normal equations' terms a.a, a.b, b.b and determinant (N,)."""

    a: np.ndarray
    b: np.ndarray
    aa: np.ndarray
    ab: np.ndarray
    bb: np.ndarray
    det: np.ndarray

    @classmethod
    def of(cls, a: np.ndarray, b: np.ndarray) -> "_Orientation":
        aa, ab, bb = np.sum(a * a, 1), np.sum(a * b, 1), np.sum(b * b, 1)
        return cls(a, b, aa, ab, bb, aa * bb - ab ** 2)

    def orient(self, d: np.ndarray) -> np.ndarray:
        # d = c0 a + c1 b (least squares, 2x2 normal equations per segment); d points start -> end
        # when the end's depth coefficient c1 exceeds the start's c0 (c1 > 0 > c0 exactly)
        ad, bd = self.a @ d, self.b @ d
        c0, c1 = (self.bb * ad - self.ab * bd) / self.det, (self.aa * bd - self.ab * ad) / self.det
        return d if np.sum(np.sign(c1 - c0)) >= 0 else -d


def side_angles_to_vp(segments: np.ndarray, vp: np.ndarray) -> np.ndarray:
    """Image angle (N,) deg between each segment (N, 2, 2) px and the line from its midpoint to the
    homogeneous vanishing point vp (3,) px (finite or at infinity); vp (H, 3): (H, N), per point."""
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    e = s[:, 1] - s[:, 0]
    return angles_to_vp(homog(0.5 * (s[:, 0] + s[:, 1])), e, np.linalg.norm(e, axis=1), vp)


def angles_to_vp(mid: np.ndarray, e: np.ndarray, e_len: np.ndarray, vp: np.ndarray) -> np.ndarray:
    """:func:`side_angles_to_vp` of segments given as their homogeneous midpoints mid (N, 3),
    directions e = end - start (N, 2) px and lengths e_len (N,) px."""
    lines = cross3(mid, np.asarray(vp, dtype=np.float64)[..., None, :])
    to_vp = np.stack([lines[..., 1], -lines[..., 0]], axis=-1)
    c = np.abs(np.sum(to_vp * e, axis=-1)) / (np.linalg.norm(to_vp, axis=-1) * e_len + 1e-300)
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def side_thresholds_deg(segments: np.ndarray, noise_px: float = WALL_FIT.corner_noise_px,
                        base_deg: float = WALL_FIT.vp_angle_deg) -> np.ndarray:
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
    Ki = np.linalg.inv(check_K(K))
    extra = None
    if lines is not None:
        segs = [np.asarray(seg, dtype=np.float64).reshape(-1, 2, 2) for seg in lines]
        extra = tuple((unit_normals(seg, *plane_normals(*rays(seg, Ki))), segment_weights(seg, line_sigma_px))
                      if len(seg) else None for seg in segs)
    return WallSides.of(quads, idx, Ki, sigma_px).vps(extra, oriented)


@dataclass(frozen=True)
class WallSides:
    """The horizontal and vertical sides of a wall's windows, as :func:`fit_vps` uses them: per
    family (0: horizontal, 1: vertical) their unit normals (S, 3), weights (S,) and orientation
    terms; made once per wall, used for every fit of its vanishing points."""

    normals: tuple[np.ndarray, np.ndarray]
    weights: tuple[np.ndarray, np.ndarray]
    orientation: tuple[_Orientation, _Orientation]

    @classmethod
    def of(cls, quads: np.ndarray, idx: list[int], Ki: np.ndarray, sigma_px: float) -> "WallSides":
        """The sides of windows ``idx`` of quads (N, 4, 2) px under Ki = K^-1 (3, 3) (K checked),
        weighted with corner sigma ``sigma_px``."""
        nrm, wts, ori = [], [], []
        q = quads[idx]
        for sides in (H_SIDES, V_SIDES):
            seg = side_segments(q, sides)
            a, b = rays(seg, Ki)
            nrm.append(unit_normals(seg, *plane_normals(a, b)))
            wts.append(segment_weights(seg, sigma_px))
            ori.append(_Orientation.of(a, b))
        return cls(tuple(nrm), tuple(wts), tuple(ori))

    def vps(self, lines: tuple | None = None, oriented: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(d_h, d_v) (3,) each: :func:`fit_vps` with these sides and, per family, the lines'
        (unit normals (M, 3), weights (M,)) or None (none, also for lines None)."""
        out = []
        for f in range(2):
            nrm, wts = self.normals[f], self.weights[f]
            if lines is not None and lines[f] is not None:
                nrm = np.concatenate([nrm, lines[f][0]])
                wts = np.concatenate([wts, lines[f][1]])
            d = vanishing_direction(nrm, wts)
            out.append(self.orientation[f].orient(d) if oriented else d)
        return out[0], out[1]


@dataclass(frozen=True)
class _Sides:
    """Per window and side family (0: horizontal, 1: vertical): segment midpoints (N, 2, 2, 3)
    homogeneous px, directions (N, 2, 2, 2) px and their lengths (1, N, 2, 2), weighted normal
    moments sum w n n^T (N, 2, 3, 3), inlier thresholds (N, 2, 2) deg; the sides' unit normals
    (N, 2, 2, 3), weights (N, 2, 2) and end rays a, b (N, 2, 2, 3) (:meth:`wall`)."""

    mid: np.ndarray
    dirs: np.ndarray
    dir_len: np.ndarray
    moments: np.ndarray
    thresh: np.ndarray
    nrm: np.ndarray
    wts: np.ndarray
    a: np.ndarray
    b: np.ndarray

    @classmethod
    def of(cls, q: np.ndarray, K: np.ndarray, sigma_px: float) -> "_Sides":
        n = len(q)
        seg = np.stack([side_segments(q, sides).reshape(n, 2, 2, 2) for sides in (H_SIDES, V_SIDES)], axis=1)
        flat = seg.reshape(-1, 2, 2)
        a, b = rays(flat, np.linalg.inv(K))
        nrm = unit_normals(flat, *plane_normals(a, b)).reshape(n, 2, 2, 3)
        wts = segment_weights(flat, sigma_px).reshape(n, 2, 2)
        moments = np.einsum("nfs,nfsi,nfsj->nfij", wts, nrm, nrm)
        mid = np.concatenate([0.5 * (seg[..., 0, :] + seg[..., 1, :]), np.ones((n, 2, 2, 1))], axis=-1)
        dirs = seg[..., 1, :] - seg[..., 0, :]
        return cls(mid, dirs, np.linalg.norm(dirs[None], axis=-1), moments,
                   side_thresholds_deg(flat).reshape(n, 2, 2), nrm, wts, a.reshape(n, 2, 2, 3), b.reshape(n, 2, 2, 3))

    def directions(self, hyps: np.ndarray) -> np.ndarray:
        """Unoriented (d_h, d_v) (H, 2, 3) of each hypothesis, a (H, N) bool window membership."""
        M = np.einsum("hn,nfij->hfij", hyps.astype(float), self.moments)
        return np.linalg.eigh(M)[1][..., 0]

    def inliers(self, K: np.ndarray, D: np.ndarray) -> np.ndarray:
        """(H, N) bool: windows whose four sides all point at the vanishing points K D[h, f]."""
        vp = D @ K.T  # (H, 2, 3)
        lines = cross3(self.mid[None], vp[:, None, :, None, :])  # (H, N, 2, 2, 3)
        to_vp = np.stack([lines[..., 1], -lines[..., 0]], axis=-1)
        e = self.dirs[None]
        c = np.abs(np.sum(to_vp * e, axis=-1)) / (np.linalg.norm(to_vp, axis=-1) * self.dir_len + 1e-300)
        ang = np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))
        return np.all(ang <= self.thresh[None], axis=(2, 3))

    def wall(self, idx: list[int]) -> WallSides:
        """The sides of windows ``idx`` as :func:`fit_vps` uses them (``WallSides.of(q, idx, ...)``,
        bit for bit: every per-side value is row-wise)."""
        return WallSides(tuple(self.nrm[idx, f].reshape(-1, 3) for f in range(2)),
                         tuple(self.wts[idx, f].reshape(-1) for f in range(2)),
                         tuple(_Orientation.of(self.a[idx, f].reshape(-1, 3), self.b[idx, f].reshape(-1, 3))
                               for f in range(2)))


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
        d_h, d_v = sd.wall(mem).vps()  # fit_vps(q, mem, K, sigma_px)
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
    M = np.stack([d_h, d_v, cross3(d_h, d_v)], axis=1)
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
    return R


def rot_y(deg: float) -> np.ndarray:
    """Rotation (3, 3) about the window frame's y axis (up) by ``deg``."""
    c, s_ = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, 0.0, s_], [0.0, 1.0, 0.0], [-s_, 0.0, c]])


def tie_walls(R0: np.ndarray, tol_deg: float = WALL_FIT.manhattan_deg) -> tuple[np.ndarray, np.ndarray]:
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
