"""Mask -> quadrilateral, as in the paper: local line fits on the outline, keep the four best.

Steps (:func:`mask_to_quad`):

1. Check the mask (empty, tiny, touching the image border, several blobs): each gives an explicit
   ``failure`` reason instead of a crash.
2. Take the outer contour (``cv2.findContours``, ``CHAIN_APPROX_NONE``): the centres of the mask's
   border pixels, in order around the blob.
3. At every outline point fit a line (principal component) through its ~``window_pts`` neighbours
   along the outline (fewer for small masks: at most a sixth of the outline). For a thin blob, whose
   short side holds fewer outline points than that fit spans, add the candidates of a second,
   shorter fit (``short_fit_frac`` x the short side of the blob's minimum-area rectangle), so the
   short sides get a line of their own.
4. Greedily keep the four candidate lines that explain most outline points (distance below
   ``inlier_px``), removing the points each chosen line explains and refusing a candidate whose
   support overlaps a chosen line's (so one long edge is never chosen twice).
5. Refit each line to the outline points nearest to it, order the four lines around the contour,
   shift each one outward by the half-pixel that separates a border pixel's centre from the mask's
   true edge (see :func:`edge_offset_px`), intersect neighbours -> quad, corners TL, TR, BR, BL.
6. Check the quad explains the outline (a disc or a triangle fails with ``not_quadrilateral``).
   Each side must explain ``min_side_frac`` of the whole outline, or, for a side short against
   the outline (a thin window's top and bottom), ``min_side_own`` of its own expected outline
   (its length in outline points) while being at least ``min_opposite_ratio`` x as long as the
   opposite side: a triangle with a clipped corner (a short side facing a long one) still fails.
7. Quad source ``mask+lines``, for a detection with predicted corners: if that fails with
   ``not_quadrilateral`` (a learned mask with one corner notched, where a shadowed reveal was left
   out, or a bulge into a shadow beside the window, made the greedy choice take the notch's or
   bulge's edge as a side), :func:`best_subset_quad` tries every four of the ``subset_lines``
   best distinct lines. A quad passes if the mask fills at least ``subset_min_fill`` of it, at
   most ``subset_max_outside`` of the mask lies outside it and every side is covered along
   ``subset_min_cover`` of its length (a disc, a triangle or an L fails). The passing quad
   nearest to the predicted corners is kept if it lies within a mean ``subset_hint_px`` of them:
   the mask's lines give the geometry, the corner head confirms which lines are the window's.

Pixel convention (``fenestra.conventions``): the centre of pixel (u, v) is at (u, v). A rasterised
mask contains the pixels whose centres lie inside the polygon, so on a straight edge the border
pixels' centres lie on average ``0.5 * max(|n_x|, |n_y|)`` px inside the true edge (n: the edge's
unit normal): the outline is one pixel per column (rows for steep edges) and the edge cuts each
column at a uniformly distributed fraction of a pixel above that pixel's centre.
"""
from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import cv2
import numpy as np

from fenestra.conventions import DEFAULTS
from fenestra.pipeline.types import Failure


QUAD_SOURCES = ("mask", "corners", "mask+corners", "mask+lines", "network")


@dataclass(frozen=True)
class QuadParams:
    """Parameters of :func:`mask_to_quad` (pixels unless stated).

    window_pts: outline points in each local line fit (the paper: ~100); capped at a sixth of the
        outline so small masks still get one fit per side.
    inlier_px: an outline point within this distance of a line is explained by it; for large
        masks the distance grows to ``inlier_rel`` x sqrt(mask area) (a network's mask boundary
        wobbles in proportion to the window size).
    max_candidates: local fits considered as candidate lines (every k-th outline point).
    max_overlap: a candidate sharing more than this fraction of its inliers with a chosen line is
        a copy of that line and is refused; for a thin blob (see ``short_fit_frac``) only if it
        also runs within ``copy_angle_deg`` of that line's direction (a short side of a few
        pixels shares a good part of its inliers with the long sides at its ends).
    min_area_px: masks smaller than this fail with ``too_small``.
    min_explained: the four lines must explain at least this fraction of the outline.
    min_side_frac: each line must explain at least this fraction of the outline.
    short_fit_frac: for a thin blob (its short side, in outline points, shorter than the local
        fit), a second set of candidate lines from local fits over this fraction of the short
        side (at least 5 points). Only for a blob that fills at least ``thin_min_fill`` of its
        minimum-area rectangle (a thin quadrilateral, even under perspective; a sliver of a
        triangle fills half and keeps the single fit).
    min_side_own, min_opposite_ratio: a side below ``min_side_frac`` is still accepted when the
        outline points it explains are at least ``min_side_own`` x its expected outline points
        (the side's Chebyshev length: the contour has one point per pixel step) and its length is
        at least ``min_opposite_ratio`` x the opposite side's (thin tall windows, whose
        short sides are a few per cent of the outline, more so with rounded corners).
    side_trim: a side shorter than the local fit is refitted to the outline points near it whose
        projection lies between ``side_trim`` and ``1 - side_trim`` of the way between its corners
        (its neighbours' lines fix those): a rounded corner's arc would otherwise tilt it.
    speck_px, speck_rel: extra connected components up to max(speck_px, speck_rel x the largest
        component) are ignored (noise specks, as a network's masks have); larger ones make the
        mask fail with ``multiple_blobs`` (e.g. two windows in one mask).
    allow_border: if False, a mask touching the image border fails with ``touches_border``
        (the window is cut by the image, its true corners are unknown); if True it is fitted like
        any mask, the image edge one of its sides (the quad of the window's *visible* part), and
        the edges it reaches are its result's ``cut`` (the session's partial windows).
    subset_lines, subset_min_fill, subset_max_outside, subset_min_cover: the fallback of step 7
        (:func:`best_subset_quad`, source ``mask+lines``): lines considered, the least share of the
        quad the mask must fill, the most share of the mask outside the quad, and the least share
        of each side's length that outline points within ``inlier_px`` of it must cover;
        subset_hint_px: with predicted corners (``hint``), the quad is kept only when its corners
        lie within this mean distance of them (two cues that agree; a notch or bulge edge taken
        as a side does not).
    source: where the quad comes from: ``"mask"`` (:func:`mask_to_quad`), or ``"corners"``: the
        corners a detector with a corner head predicts (``Detection.corners``,
        :func:`corners_to_quad`), falling back to the mask fit for a detection without usable
        corners; or ``"mask+corners"``: the mask fit, and the predicted corners (where they
        describe the mask) for a mask the fit finds no quadrilateral in; or ``"mask+lines"``: the
        mask fit, and where it finds no quadrilateral the best four of more lines on the same
        outline (step 7); or ``"network"``: the detection's own corners as they are, unchecked against
        its mask (a detector with a quad head, ``quadnet``, whose mask is that quad: one instance per
        window centre), a quad reaching past the image failing ``touches_border`` (the session then
        fits its visible part), the mask fit for a detection without corners. QUAD_SOURCES lists the choices;
        the default is the CLI's, fenestra.conventions.DEFAULTS.quad_source.
    """

    window_pts: int = 100
    inlier_px: float = 1.5
    inlier_rel: float = 0.015
    max_candidates: int = 256
    max_overlap: float = 0.3
    min_area_px: int = 64
    min_explained: float = 0.6
    min_side_frac: float = 0.04
    short_fit_frac: float = 0.5
    thin_min_fill: float = 0.75
    min_side_own: float = 0.35
    min_opposite_ratio: float = 0.4
    copy_angle_deg: float = 30.0
    side_trim: float = 0.2
    speck_px: int = 4
    speck_rel: float = 0.05
    allow_border: bool = False
    source: str = DEFAULTS.quad_source
    subset_lines: int = 7
    subset_min_fill: float = 0.85
    subset_max_outside: float = 0.08
    subset_min_cover: float = 0.5
    subset_hint_px: float = 3.0

    def __post_init__(self) -> None:
        if self.source not in QUAD_SOURCES:
            raise ValueError(f"quad source must be one of {QUAD_SOURCES}, got {self.source!r}")
        if self.subset_lines < 4:
            raise ValueError(f"subset_lines must be at least 4, got {self.subset_lines}")


@dataclass(frozen=True)
class QuadResult:
    """Result of :func:`mask_to_quad`.

    quad: (4, 2) float64 px, TL TR BR BL (clockwise on screen), or None on failure.
    lines: (4, 3) float64, each row (n_x, n_y, c) of the side line n . p = c with |n| = 1 and n
        pointing out of the mask, in order top, right, bottom, left; None on failure.
    explained: fraction of outline points within ``inlier_px`` of a chosen line (0 if not fitted).
    failure: None, or a pipeline.types.Failure of stage ``quad`` whose code is one of empty_mask,
        too_small, touches_border, multiple_blobs, not_quadrilateral, no_corners (its ``detail``
        the numbers; ``str``: ``"quad: <code>: <detail>"``, the form windows.json holds).
    cut: the image edges the mask's blob reaches (of pipeline.types.CUT_SIDES, in that order; a
        fit with ``allow_border`` only, else ()): the quad is then the *visible* part of the
        window, its sides along those edges the image's edges.
    """

    quad: np.ndarray | None
    lines: np.ndarray | None
    explained: float
    failure: Failure | None
    cut: tuple[str, ...] = ()


def _fail(code: str, detail: str, explained: float = 0.0) -> QuadResult:
    return QuadResult(quad=None, lines=None, explained=explained, failure=Failure("quad", code, detail))


def edge_offset_px(normal: np.ndarray) -> float:
    """Mean distance (px) from border-pixel centres to the true edge with unit ``normal`` (2,)."""
    return 0.5 * float(max(abs(normal[0]), abs(normal[1])))


def check_mask(mask: np.ndarray, params: QuadParams = QuadParams()
               ) -> tuple[np.ndarray | None, tuple[int, int], Failure | None]:
    """Validate a (H, W) mask; return (blob crop as uint8 0/1, crop origin (x0, y0), failure).

    On success the failure is None and the crop holds the single blob with a one-pixel background
    margin where the image allows; on failure the crop is None. Raises ValueError for a mask that
    is not 2-D (a programming error, not a bad detection).
    """
    m, origin, _, failure = _check_mask(mask, params)
    return m, origin, failure


def _check_mask(mask: np.ndarray, params: QuadParams) -> tuple[np.ndarray | None, tuple[int, int], tuple[str, ...],
                                                              Failure | None]:
    """:func:`check_mask`, with the image edges the blob reaches (pipeline.types.CUT_SIDES order)
    as the third item."""
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"mask must be 2-D (H, W), got shape {mask.shape}")
    full = np.ascontiguousarray(mask).view(np.uint8) if mask.dtype == bool else (mask != 0).astype(np.uint8)  # bool: 0/1 already, no copy
    x, y, w, h = cv2.boundingRect(full)
    if w == 0 or h == 0:
        return None, (0, 0), (), Failure("quad", "empty_mask", "no foreground pixel")
    H, W = full.shape
    x0, y0 = max(x - 1, 0), max(y - 1, 0)
    m = full[y0:min(y + h + 1, H), x0:min(x + w + 1, W)]
    labels, stats = _components(m)
    sizes = stats[1:, cv2.CC_STAT_AREA]
    speck = max(params.speck_px, params.speck_rel * float(sizes.max()))
    big = np.flatnonzero(sizes > speck)
    if len(big) > 1:
        top = sorted(sizes[big].tolist(), reverse=True)[:4]
        return None, (x0, y0), (), Failure("quad", "multiple_blobs", f"{len(big)} components larger than "
                                           f"{speck:.0f} px (largest: {top} px)")
    keep = 1 + int(np.argmax(sizes))
    area = int(sizes[keep - 1])
    if area < params.min_area_px:
        return None, (x0, y0), (), Failure("quad", "too_small", f"{area} px < min_area_px={params.min_area_px}")
    if len(sizes) > 1:
        m = (labels == keep).astype(np.uint8)
    bx, by, bw, bh = stats[keep, :4]
    bx, by = bx + x0, by + y0
    sides = [name for name, touch in (("top", by == 0), ("bottom", by + bh == H), ("left", bx == 0),
                                      ("right", bx + bw == W)) if touch]
    if sides and not params.allow_border:
        return None, (x0, y0), tuple(sides), Failure("quad", "touches_border",
                                                     f"mask reaches the image {', '.join(sides)} edge")
    return m, (x0, y0), tuple(sides), None


def _components(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(labels (h, w), stats (n + 1, 5)) of the 8-connected blobs of a 0/1 uint8 mask: labels
    uint16 (half the memory of int32: a full-width blob of a 150 Mpx photo) unless the mask has
    more than 65535 blobs."""
    try:
        _, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8, ltype=cv2.CV_16U)
    except cv2.error:  # OpenCV refuses a label count that overflows uint16
        _, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8, ltype=cv2.CV_32S)
    return labels, stats


def outline(m: np.ndarray) -> np.ndarray:
    """Ordered outer contour of a single-blob uint8 mask: (N, 2) float64 pixel centres (x, y)."""
    contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=len)
    return c.reshape(-1, 2).astype(np.float64)


def local_lines(P: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Principal-component line through each point's ``window`` circular neighbours.

    P: (N, 2) ordered outline. Returns normals (N, 2) unit and offsets (N,) with n . p = c.
    Uses running sums, O(N).
    """
    N = len(P)
    h = max(1, window // 2)
    Pp = np.concatenate([P[N - h:], P, P[:h]]) if h < N else np.tile(P, (3, 1))[N - h:2 * N + h]
    x, y = Pp[:, 0], Pp[:, 1]
    S = np.zeros((len(Pp) + 1, 5))
    S[1:] = np.cumsum(np.stack([x, y, x * x, x * y, y * y], axis=1), axis=0)
    n = 2 * h + 1
    W = (S[n:n + N] - S[:N]) / n
    mx, my = W[:, 0], W[:, 1]
    cxx, cxy, cyy = W[:, 2] - mx * mx, W[:, 3] - mx * my, W[:, 4] - my * my
    theta = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)  # principal direction angle
    normals = np.stack([-np.sin(theta), np.cos(theta)], axis=1)
    return normals, normals[:, 0] * mx + normals[:, 1] * my


def fit_line(P: np.ndarray) -> np.ndarray:
    """Total-least-squares line (n_x, n_y, c) through points P (N, 2), N >= 2."""
    m = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - m, full_matrices=False)
    n = vt[-1]
    return np.array([n[0], n[1], n @ m])


def intersect(l1: np.ndarray, l2: np.ndarray) -> np.ndarray:
    """Intersection (2,) of lines (n_x, n_y, c); inf if parallel."""
    A = np.array([l1[:2], l2[:2]])
    det = np.linalg.det(A)
    if abs(det) < 1e-12:
        return np.array([np.inf, np.inf])
    return np.linalg.solve(A, np.array([l1[2], l2[2]]))


def order_corners(quad: np.ndarray) -> np.ndarray:
    """Reorder a convex quad's corners (4, 2) as TL, TR, BR, BL (clockwise on screen, y down).

    TL starts the top side: the side whose midpoint is highest in the image.
    """
    q = np.asarray(quad, dtype=np.float64)
    x, y = q[:, 0], q[:, 1]
    area2 = np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)  # > 0: clockwise on screen
    if area2 < 0:
        q = q[::-1]
    mid_y = (q[:, 1] + np.roll(q, -1, axis=0)[:, 1]) / 2.0
    return np.roll(q, -int(np.argmin(mid_y)), axis=0)


def short_side_pts(P: np.ndarray) -> tuple[float, float]:
    """(short side in outline points, fill) of the outline's minimum-area rectangle: its short
    side's Chebyshev length (an 8-connected contour has one point per pixel step along the longer
    axis) and the share of the rectangle the outline polygon covers (a rectangle ~1, a triangle 1/2)."""
    (_, _), (w, h), angle = cv2.minAreaRect(P.astype(np.float32))
    a = np.radians(angle if w <= h else angle + 90.0)  # direction of the short side
    fill = abs(cv2.contourArea(P.astype(np.float32))) / max(float(w * h), 1e-9)
    return float(min(w, h)) * max(abs(np.cos(a)), abs(np.sin(a))), fill


def _fit_windows(P: np.ndarray, params: QuadParams) -> list[int]:
    """Outline points of the local fits whose lines are the candidates: the main fit, and for a
    thin, four-sided blob (short side in outline points below the main fit's span, filling at
    least ``thin_min_fill`` of its minimum-area rectangle) a shorter one."""
    N = len(P)
    window = int(min(params.window_pts, max(5, N // 6)))
    short, fill = short_side_pts(P)
    if window <= short or fill < params.thin_min_fill:
        return [window]
    return [window, int(max(5, min(window - 1, round(params.short_fit_frac * short))))]


def _choose_lines(P: np.ndarray, params: QuadParams, inlier_px: float, n: int = 4) -> np.ndarray | None:
    """Greedy choice of ``n`` distinct candidate lines, best first; returns (k, 3) lines with
    4 <= k <= n (fewer than n where no other line explains a remaining point), or None if fewer
    than four are found."""
    N = len(P)
    step = max(1, N // params.max_candidates)
    cand = np.arange(0, N, step)
    windows = _fit_windows(P, params)
    fits = [local_lines(P, w) for w in windows]
    normals = np.concatenate([n[cand] for n, _ in fits])
    offsets = np.concatenate([c[cand] for _, c in fits])
    # (N, C) inlier table as 0/1 floats: counting inliers becomes a matrix-vector product
    D = (np.abs(P @ normals.T - offsets) < inlier_px).astype(np.float32)
    remaining = np.ones(N, dtype=np.float32)
    allowed = np.ones(len(normals), dtype=bool)
    support = np.maximum(D.sum(axis=0), 1.0)
    chosen = []
    for _ in range(n):
        counts = np.where(allowed, remaining @ D, -1.0)
        best = int(np.argmax(counts))
        if counts[best] <= 0:
            return np.array(chosen) if len(chosen) >= 4 else None
        inl = D[:, best]
        chosen.append(np.array([*normals[best], offsets[best]]))
        remaining *= 1.0 - inl
        copy = (inl @ D) / support > params.max_overlap
        if len(windows) > 1:  # thin blob: a short side shares its end points with the long sides
            copy &= np.abs(normals @ normals[best]) > np.cos(np.radians(params.copy_angle_deg))
        allowed &= ~copy
        allowed[best] = False
    return np.array(chosen)


def _refit(P: np.ndarray, lines: np.ndarray, radius: float, iters: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Refit each line to the outline points nearest to it (within ``radius``).

    Returns lines (4, 3) and the assignment (N,) of each point to a line index, -1 for none.
    """
    assign = np.full(len(P), -1)
    for _ in range(iters):
        d = np.abs(P @ lines[:, :2].T - lines[:, 2])  # (N, 4)
        nearest = np.argmin(d, axis=1)
        assign = np.where(d[np.arange(len(P)), nearest] < radius, nearest, -1)
        new = lines.copy()
        for k in range(4):
            pts = P[assign == k]
            if len(pts) >= 3:
                new[k] = fit_line(pts)
        lines = new
    return lines, assign


def mask_to_quad(mask: np.ndarray, params: QuadParams = QuadParams(), hint: np.ndarray | None = None) -> QuadResult:
    """Fit the window quadrilateral to a binary mask (H, W) (bool or 0/non-zero).

    hint: (4, 2) px in the mask's coordinates, the detector's predicted corners, or None: step 7
    (source ``mask+lines``) keeps the passing quad nearest to them, and only if they agree; it
    runs only with a hint (a detector without a corner head keeps the greedy fit's failure).

    Returns a :class:`QuadResult`; failures are reported in ``failure``, never raised (except a
    mask that is not 2-D: ValueError).
    """
    m, origin, cut, failure = _check_mask(mask, params)
    if failure is not None:
        return QuadResult(quad=None, lines=None, explained=0.0, failure=failure)
    P = outline(m) + np.asarray(origin, dtype=np.float64)
    inlier_px = max(params.inlier_px, params.inlier_rel * float(np.sqrt(np.count_nonzero(m))))
    qr = _greedy_quad(P, m, params, inlier_px)
    if params.source == "mask+lines" and hint is not None and getattr(qr.failure, "code", None) == "not_quadrilateral":
        sub = best_subset_quad(P, m, np.asarray(origin, dtype=np.float64), params, inlier_px, hint)
        if sub is not None:
            return dataclasses.replace(sub, cut=cut)
    return dataclasses.replace(qr, cut=cut)  # a failure of a visible part keeps its cut, too


def _greedy_quad(P: np.ndarray, m: np.ndarray, params: QuadParams, inlier_px: float) -> QuadResult:
    """Steps 3-6 of :func:`mask_to_quad` on the outline P (N, 2) px of the blob crop m (uint8 0/1)."""
    N = len(P)
    lines = _choose_lines(P, params, inlier_px)
    if lines is None:
        return _fail("not_quadrilateral", "fewer than four distinct lines on the outline")
    lines, assign = _refit(P, lines, radius=inlier_px)
    counts = np.bincount(assign[assign >= 0], minlength=4)
    explained = float(counts.sum()) / N
    if explained < params.min_explained:
        return _fail("not_quadrilateral", f"four lines explain {explained:.0%} of the outline "
                    f"< min_explained={params.min_explained:.0%}", explained)
    if counts.min() < 3:  # no line to speak of, whatever its length
        return _fail("not_quadrilateral", f"a side explains only {counts.min() / N:.1%} of the outline "
                    f"< min_side_frac={params.min_side_frac:.0%}", explained)
    # order the lines around the contour: circular mean of the outline index of their points
    ang = 2.0 * np.pi * np.arange(N) / N
    pos = [np.angle(np.exp(1j * ang[assign == k]).mean()) for k in range(4)]
    order = np.argsort(pos)
    lines, counts = lines[order], counts[order]
    # orient normals outward (away from the blob's centroid) and shift by the half-pixel offset
    centre = P.mean(axis=0)
    for k in range(4):
        if lines[k, :2] @ centre > lines[k, 2]:
            lines[k] = -lines[k]
        lines[k, 2] += edge_offset_px(lines[k, :2])
    corners = np.array([intersect(lines[k], lines[(k + 1) % 4]) for k in range(4)])
    if not np.all(np.isfinite(corners)):
        return _fail("not_quadrilateral", "two neighbouring sides are parallel", explained)
    lines, corners = _refit_short_sides(P, lines, corners, _fit_windows(P, params)[0], inlier_px, params)
    reason = _side_support(corners, counts, N, params)
    if reason is not None:
        return _fail("not_quadrilateral", reason, explained)
    # each corner must lie near the outline (a triangle's fourth 'side' puts a corner far away)
    size = np.sqrt(float(m.sum()))
    gap = np.min(np.linalg.norm(P[None] - corners[:, None], axis=2), axis=1)
    if gap.max() > max(4.0, 0.15 * size):
        return _fail("not_quadrilateral", f"a corner lies {gap.max():.1f} px from the outline", explained)
    quad = order_corners(corners)
    if not _is_convex(quad):
        return _fail("not_quadrilateral", "the four lines give a non-convex quad", explained)
    return QuadResult(quad=quad, lines=_lines_in_corner_order(lines, quad), explained=explained, failure=None)


def best_subset_quad(P: np.ndarray, m: np.ndarray, origin: np.ndarray, params: QuadParams,
                     inlier_px: float, hint: np.ndarray) -> QuadResult | None:
    """Step 7 of :func:`mask_to_quad`: the quad of four of the ``subset_lines`` greedy lines that
    the predicted corners ``hint`` confirm, or None where no four pass.

    P (N, 2) px: the outline of the blob crop m (uint8 0/1, its pixel (0, 0) at ``origin`` (2,)
    px); hint (4, 2) px: predicted corners in any cyclic order. Each candidate line is refitted to
    its own inliers (within ``inlier_px``), oriented outward and shifted by the half-pixel edge
    offset. Four lines, sorted by their normals' angle, make a quad when neighbours meet in a
    convex quad whose corners lie within a mean ``subset_hint_px`` of the hint's (both TL TR BR
    BL; checked first, so only confirmed quads are rasterised) and no farther than half the mask's
    size outside its box. It passes when the mask fills ``subset_min_fill`` of it, leaves at most
    ``subset_max_outside`` of its pixels outside it, and each side (as a segment) has outline
    points within ``inlier_px`` along ``subset_min_cover`` of its Chebyshev length. Of the
    passing quads the nearest to the hint is kept (ties: the first).
    """
    hint = np.asarray(hint, dtype=np.float64)
    if hint.shape != (4, 2) or not np.all(np.isfinite(hint)):
        return None  # corners that cannot confirm anything
    hint = order_corners(hint)
    cand = _choose_lines(P, params, inlier_px, n=params.subset_lines)
    if cand is None:
        return None
    centre = P.mean(axis=0)
    lines = []
    for line in cand:
        pts = P[np.abs(P @ line[:2] - line[2]) < inlier_px]
        line = fit_line(pts) if len(pts) >= 3 else line
        line = -line if line[:2] @ centre > line[2] else line
        lines.append(line + np.array([0.0, 0.0, edge_offset_px(line[:2])]))
    lines = np.array(lines)
    shift = np.array([edge_offset_px(n) for n in lines[:, :2]])
    near = np.abs(P @ lines[:, :2].T - (lines[:, 2] - shift)) < inlier_px  # (N, L), unshifted lines
    pad = int(np.ceil(max(m.shape) / 2.0))
    mask = np.pad(m.astype(bool), pad)
    n_mask = int(mask.sum())
    best, best_dist = None, np.inf
    for combo in itertools.combinations(range(len(lines)), 4):
        idx = sorted(combo, key=lambda k: np.arctan2(lines[k, 1], lines[k, 0]))
        ang = np.sort(np.arctan2(lines[idx, 1], lines[idx, 0]))
        if np.diff(np.append(ang, ang[0] + 2 * np.pi)).max() >= np.pi:
            continue  # the normals do not go round: no closed quad
        quad = np.array([intersect(lines[idx[k]], lines[idx[(k + 1) % 4]]) for k in range(4)])
        if not np.all(np.isfinite(quad)) or not _is_convex(quad):
            continue
        dist = float(np.linalg.norm(order_corners(quad) - hint, axis=1).mean())
        local = quad - origin + pad
        if dist > params.subset_hint_px or dist >= best_dist or local.min() < 0 \
                or np.any(local.max(axis=0) >= mask.shape[::-1]):
            continue
        area = np.zeros_like(mask, dtype=np.uint8)
        cv2.fillConvexPoly(area, np.round(local * 16).astype(np.int32), 1, lineType=cv2.LINE_8, shift=4)
        inside = int(np.count_nonzero(mask & (area > 0)))
        if inside < params.subset_min_fill * max(int(area.sum()), 1) or \
                n_mask - inside > params.subset_max_outside * n_mask:
            continue
        if all(_side_covered(P, near[:, idx[k]], quad[k - 1], quad[k], params.subset_min_cover)
               for k in range(4)):  # side idx[k] runs from corner k-1 to corner k
            best, best_dist = (quad, idx), dist
    if best is None:
        return None
    quad, idx = order_corners(best[0]), best[1]
    explained = float(np.count_nonzero(near[:, idx].any(axis=1))) / len(P)  # within inlier_px of a side's line
    return QuadResult(quad=quad, lines=_lines_in_corner_order(lines[idx], quad), explained=explained, failure=None)


def _side_covered(P: np.ndarray, near: np.ndarray, a: np.ndarray, b: np.ndarray, min_cover: float) -> bool:
    """Do the outline points P (N, 2) flagged ``near`` (N,) the side's line, whose projection lies
    between corners a and b (2,), number at least ``min_cover`` x the side's Chebyshev length?"""
    d = b - a
    t = (P - a) @ d / max(float(d @ d), 1e-12)
    return int(np.count_nonzero(near & (t >= 0.0) & (t <= 1.0))) >= min_cover * max(float(np.abs(d).max()), 1.0)


def _refit_short_sides(P: np.ndarray, lines: np.ndarray, corners: np.ndarray, window: int,
                       band_px: float, params: QuadParams, iters: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Refit each side shorter than ``window`` outline points (a thin window's short sides) to the
    outline points within ``band_px`` of it between ``side_trim`` and ``1 - side_trim`` of the way
    from its first corner to its second, then intersect again.

    lines (4, 3) outward, half-pixel shifted, in contour order; corners (4, 2): corner k joins
    side k and side k+1. Returns (lines, corners); a side with fewer than 3 such points is kept.
    """
    lines, corners = lines.copy(), corners.copy()
    for it in range(iters + 1):
        trim = params.side_trim if it < iters else 0.0  # last pass: the whole side, from a level start
        changed = False
        for k in range(4):
            a, b = corners[k - 1], corners[k]
            d = b - a
            if np.abs(d).max() >= window:
                continue
            t = (P - a) @ d / max(float(d @ d), 1e-12)
            shift = np.array([edge_offset_px(n) for n in lines[:, :2]])
            dist = np.abs(P @ lines[:, :2].T - (lines[:, 2] - shift))  # (N, 4), to the unshifted lines
            near = (np.argmin(dist, axis=1) == k) & (dist[:, k] < band_px)
            pts = P[near & (t >= trim) & (t <= 1.0 - trim)]
            if len(pts) < 3:
                continue
            new = fit_line(pts)
            if new[:2] @ lines[k, :2] < 0:
                new = -new
            new[2] += edge_offset_px(new[:2])
            lines[k] = new
            changed = True
        if not changed:
            break
        fresh = np.array([intersect(lines[k], lines[(k + 1) % 4]) for k in range(4)])
        if not np.all(np.isfinite(fresh)):
            break
        corners = fresh
    return lines, corners


def _side_support(corners: np.ndarray, counts: np.ndarray, N: int, params: QuadParams) -> str | None:
    """None if every side is supported by the outline, else the failure's detail (a ``not_quadrilateral``).

    corners (4, 2): corner k joins side k and side k+1; counts (4,): outline points explained by
    side k. A side passes with ``min_side_frac`` of the outline, or else (a thin window's short
    side) with ``min_side_own`` of its own expected outline points while at least
    ``min_opposite_ratio`` x as long as the side opposite it.
    """
    ends = corners - np.roll(corners, 1, axis=0)  # side k runs from corner k-1 to corner k
    length = np.linalg.norm(ends, axis=1)
    expected = np.maximum(np.abs(ends).max(axis=1), 1.0)  # outline points along each side
    for k in np.argsort(counts):
        if counts[k] >= params.min_side_frac * N:
            return None  # every remaining side explains more
        own, opposite = counts[k] / expected[k], length[k] / max(length[(k + 2) % 4], 1e-9)
        if own < params.min_side_own or opposite < params.min_opposite_ratio:
            return (f"a side explains only {counts[k] / N:.1%} of the outline "
                    f"< min_side_frac={params.min_side_frac:.0%}, and {min(own, 9.99):.0%} of its own "
                    f"{length[k]:.1f} px (min_side_own={params.min_side_own:.0%}) at "
                    f"{min(opposite, 9.99):.2f} x the opposite side's length "
                    f"(min_opposite_ratio={params.min_opposite_ratio})")
    return None


def _lines_in_corner_order(lines: np.ndarray, quad: np.ndarray) -> np.ndarray:
    """Lines reordered top, right, bottom, left: side k passes through quad[k] and quad[k+1]."""
    out = np.empty_like(lines)
    for k in range(4):
        mid = (quad[k] + quad[(k + 1) % 4]) / 2.0
        out[k] = lines[int(np.argmin(np.abs(lines[:, :2] @ mid - lines[:, 2])))]
    return out


def _is_convex(quad: np.ndarray) -> bool:
    """True if the (4, 2) quad turns the same way at every corner."""
    e = np.roll(quad, -1, axis=0) - quad
    cross = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
    return bool(np.all(cross > 0) or np.all(cross < 0))


def corners_to_quad(corners: np.ndarray | None, min_side_px: float = 3.0) -> QuadResult:
    """The QuadResult of four predicted corners (4, 2) px (a detector's corner head), in cyclic
    order (TL TR BR BL as predicted; any start or direction is reordered by order_corners).

    Fails (never raises) with ``no_corners`` (None, wrong shape or not finite) or
    ``not_quadrilateral`` (not convex, or a side shorter than ``min_side_px``). lines: the sides
    through neighbouring corners, normals pointing out; explained = 1 (no outline is fitted).
    """
    if corners is None:
        return _fail("no_corners", "the detection has no predicted corners")
    c = np.asarray(corners, dtype=np.float64)
    if c.shape != (4, 2) or not np.all(np.isfinite(c)):
        return _fail("no_corners", f"corners must be (4, 2) finite px, got shape {c.shape}")
    quad = order_corners(c)
    if not _is_convex(quad):
        return _fail("not_quadrilateral", "the predicted corners are not convex")
    sides = np.linalg.norm(np.roll(quad, -1, axis=0) - quad, axis=1)
    if sides.min() < min_side_px:
        return _fail("not_quadrilateral", f"a predicted side is {sides.min():.1f} px < {min_side_px} px")
    centre = quad.mean(axis=0)
    lines = np.zeros((4, 3))
    for k in range(4):
        a, b = quad[k], quad[(k + 1) % 4]
        n = np.array([b[1] - a[1], a[0] - b[0]]) / np.linalg.norm(b - a)
        if n @ centre > n @ a:
            n = -n
        lines[k] = (n[0], n[1], n @ a)
    return QuadResult(quad=quad, lines=lines, explained=1.0, failure=None)


def corners_agree_with_mask(quad: np.ndarray, mask: np.ndarray, origin: tuple[int, int] = (0, 0),
                            area_ratio: tuple[float, float] = (0.5, 2.0)) -> bool:
    """Do predicted corners (4, 2) px describe the detection's own mask (full, or a crop at
    ``origin``)? Their quad's area must be within ``area_ratio`` x the mask's pixel count and the
    mask's centroid inside the quad: a corner head that put one corner on another window fails."""
    m = np.asarray(mask, dtype=bool)
    n = int(m.sum())
    if n == 0:
        return False
    x, y = quad[:, 0], quad[:, 1]
    area = 0.5 * abs(float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))
    ys, xs = np.nonzero(m)
    c = (float(xs.mean()) + origin[0], float(ys.mean()) + origin[1])
    inside = cv2.pointPolygonTest(quad.astype(np.float32).reshape(-1, 1, 2), c, False) >= 0
    return bool(area_ratio[0] * n <= area <= area_ratio[1] * n and inside)
