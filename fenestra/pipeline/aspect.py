"""Aspect ratio of a rectangle from its perspective image: Zhang & He (2007).

Z. Zhang, L.-W. He, "Whiteboard scanning and image enhancement", Digital Signal Processing 17(2),
2007, section 2. The rectangle's corners M1 = (0, 0), M2 = (w, 0), M3 = (0, h), M4 = (w, h) image
to m1..m4 (homogeneous pixels). With

    k2 = ((m1 x m4) . m3) / ((m2 x m4) . m3),   k3 = ((m1 x m4) . m2) / ((m3 x m4) . m2),
    n2 = k2 m2 - m1 (proportional to w K r1),  n3 = k3 m3 - m1 (proportional to h K r2),

the aspect ratio is (w/h)^2 = (n2^T B n2) / (n3^T B n3) with B = K^-T K^-1, valid for any K (also
when image sides are parallel). Without K (square pixels, principal point (u0, v0) assumed known,
here the image centre) the focal length follows from r1 . r2 = 0:

    f^2 = -[(n21 n31 - (n21 n33 + n23 n31) u0 + n23 n33 u0^2)
            + (n22 n32 - (n22 n33 + n23 n32) v0 + n23 n33 v0^2)] / (n23 n33),

undefined when n23 n33 = 0, i.e. when a pair of opposite image sides is parallel. When both pairs
are parallel (fronto-parallel view) the ratio is the affine one, |n2| / |n3| (n2, n3 then have a zero
third coordinate, and any focal length gives the same ratio).

Our quads are TL, TR, BR, BL; with the window frame's origin at the bottom-left corner,
m1 = BL, m2 = BR, m3 = TL, m4 = TR, so w runs along the bottom side and h up the left side.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.checks import check_K, check_quad
from fenestra.tolerances import TOL
from fenestra.errors import PipelineError
from fenestra.pipeline.types import AspectCase

# the cases by the number of parallel opposite side pairs (0, 1, 2); AspectCase.ILL_CONDITIONED is a per-wall verdict
CASES = (AspectCase.GENERAL, AspectCase.ONE_PAIR_PARALLEL, AspectCase.FRONTO_PARALLEL)


class AspectError(PipelineError):
    """The aspect ratio cannot be computed from this quad (degenerate, or focal length undefined)."""


@dataclass(frozen=True)
class AspectResult:
    """Aspect ratio w / h of the imaged rectangle.

    ratio: w / h (w along the quad's bottom side BL -> BR, h along BL -> TL).
    case: "general" | "one_pair_parallel" | "fronto_parallel" (which opposite image sides are
        parallel within ``TOL.parallel_sides_deg``).
    focal_px: focal length used (px): K's (geometric mean of fx, fy) when K is given, else the
        estimate from the quad, else the fallback; None for a fronto-parallel quad without K.
    focal_source: "K" | "estimated" | "fallback" | "none".
    """

    ratio: float
    case: str
    focal_px: float | None
    focal_source: str


def _check_quad(quad: np.ndarray) -> np.ndarray:
    q = check_quad(quad)
    sides = np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)
    if sides.min() < 1e-9:
        raise AspectError(f"degenerate quad (two corners coincide, side lengths "
                          f"{np.round(sides, 3).tolist()} px): {q.tolist()}")
    return q


def side_angles_deg(quad: np.ndarray) -> tuple[float, float]:
    """Angles (deg) between opposite sides: (top vs bottom, left vs right) of a TL TR BR BL quad."""
    q = _check_quad(quad)

    def angle(a: np.ndarray, b: np.ndarray) -> float:
        c = abs(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b))
        return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))

    return angle(q[1] - q[0], q[2] - q[3]), angle(q[3] - q[0], q[2] - q[1])


def classify(quad: np.ndarray, tol_deg: float = TOL.parallel_sides_deg) -> AspectCase:
    """"general", "one_pair_parallel" or "fronto_parallel" from the opposite sides' angles."""
    n_par = sum(a < tol_deg for a in side_angles_deg(quad))
    return CASES[n_par]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of two 3-vectors: np.cross's products and differences in its order (bit for bit),
    without its general-axis overhead."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def zhang_vectors(quad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """n2, n3 (3,) of Zhang & He for a TL TR BR BL quad (4, 2) px; raises AspectError if degenerate."""
    q = _check_quad(quad)
    m1, m2, m3, m4 = (np.append(q[i], 1.0) for i in (3, 2, 0, 1))  # BL, BR, TL, TR
    d2 = _cross(m2, m4) @ m3
    d3 = _cross(m3, m4) @ m2
    if abs(d2) < 1e-12 or abs(d3) < 1e-12:
        raise AspectError(f"degenerate quad (three collinear corners): {q.tolist()}")
    c14 = _cross(m1, m4)
    k2 = (c14 @ m3) / d2
    k3 = (c14 @ m2) / d3
    if k2 <= 0 or k3 <= 0:
        raise AspectError(f"quad is not the image of a rectangle in front of the camera "
                          f"(k2={k2:.3g}, k3={k3:.3g}): {q.tolist()}")
    return k2 * m2 - m1, k3 * m3 - m1


def focal_from_quad(quad: np.ndarray, principal_point: tuple[float, float]) -> float | None:
    """Focal length (px) from the quad, square pixels, principal point (u0, v0) px.

    None when undefined: a pair of opposite sides parallel (n23 n33 = 0) or f^2 <= 0 (noise).
    """
    n2, n3 = zhang_vectors(quad)
    u0, v0 = principal_point
    den = n2[2] * n3[2]
    scale = np.linalg.norm(n2) * np.linalg.norm(n3)
    if abs(den) <= 1e-12 * scale:
        return None
    num = (n2[0] * n3[0] - (n2[0] * n3[2] + n2[2] * n3[0]) * u0 + n2[2] * n3[2] * u0 ** 2
           + n2[1] * n3[1] - (n2[1] * n3[2] + n2[2] * n3[1]) * v0 + n2[2] * n3[2] * v0 ** 2)
    f2 = -num / den
    return float(np.sqrt(f2)) if f2 > 0 else None


def ratio_with_K(quad: np.ndarray, K: np.ndarray) -> float:
    """w / h from the quad (4, 2) px and intrinsics K (3, 3)."""
    n2, n3 = zhang_vectors(quad)
    Ki = np.linalg.inv(check_K(K))
    a, b = Ki @ n2, Ki @ n3
    return float(np.sqrt((a @ a) / (b @ b)))


def aspect_ratio(quad: np.ndarray, K: np.ndarray | None = None,
                 principal_point: tuple[float, float] | None = None,
                 fallback_focal_px: float | None = None,
                 tol_deg: float = TOL.parallel_sides_deg) -> AspectResult:
    """Aspect ratio w / h of the rectangle imaged as ``quad`` (4, 2) px, TL TR BR BL.

    With K: exact for any view (Zhang & He eq. for (w/h)^2). Without K: ``principal_point`` (u0, v0)
    px is required (usually the image centre); the focal length is estimated from the quad, or
    ``fallback_focal_px`` is used when the quad cannot give it (one pair of sides parallel, or
    f^2 <= 0 from noise). A fronto-parallel quad needs no focal length (affine ratio).
    Raises AspectError when no ratio can be computed, ValueError for malformed input.
    """
    q = _check_quad(quad)
    case = classify(q, tol_deg)
    if K is not None:
        K = check_K(K)
        return AspectResult(ratio_with_K(q, K), case, float(np.sqrt(K[0, 0] * K[1, 1])), "K")
    if principal_point is None:
        raise ValueError("aspect_ratio without K needs principal_point=(u0, v0) px (e.g. the image centre)")
    if case == "fronto_parallel":
        n2, n3 = zhang_vectors(q)
        return AspectResult(float(np.linalg.norm(n2[:2]) / np.linalg.norm(n3[:2])), case, None, "none")
    f = focal_from_quad(q, principal_point) if case == "general" else None
    source = "estimated"
    if f is None:
        if fallback_focal_px is None:
            raise AspectError(f"focal length undefined from this quad (case {case}) and no K or "
                              f"fallback_focal_px given: {q.tolist()}")
        f, source = float(fallback_focal_px), "fallback"
    u0, v0 = principal_point
    K = np.array([[f, 0.0, u0], [0.0, f, v0], [0.0, 0.0, 1.0]])
    return AspectResult(ratio_with_K(q, K), case, f, source)
