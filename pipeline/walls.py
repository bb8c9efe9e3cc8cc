"""Per-wall strategies: group a photo's windows into walls, estimate each wall's geometry once.

Registry ``WALL_STRATEGIES`` (pose-strategy names beside ``pipeline.pose.POSE_SOLVERS``; the
bench's method combinations run both). A wall strategy takes the per-window results (their
snapped quads), groups the windows into walls (:func:`pipeline.facade.group_walls`), fits each
wall jointly (:func:`pipeline.facade.refine_wall`: one rotation, per-window translation and width)
and gives every window its aspect ratio, pose and error bars from the shared plane.

``+lines`` strategies also use the photo's straight line segments (wall edges, eaves, mullions,
window frames): those that agree with a wall's vanishing points join its fit (WallParams.lines);
they need the gray image (``apply_walls(..., gray)``).

Unknown intrinsics (K None): the focal length is estimated from the walls (each wall's two
vanishing directions, then the joint fit with f free; walls combined by inverse variance); the
principal point is the image centre.

Uncertainty per window (``WindowResult.uncertainty``): first-order covariance of the joint fit
with the corner sigma pooled from the residuals and a prior (TOL.wall_sigma_px; with
WallParams.snap_sigma, per window at least how far snapping moved its corners), reported as 90 %
intervals: ``aspect_lo/aspect_hi``, ``rot_deg`` (bound on the rotation error), ``trans_rel``
(bound on |t error| / |t|), and ``ill_conditioned`` (aspect_case becomes "ill_conditioned").
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import chi2, norm

from fenestra.conventions import TOL
from fenestra.errors import PipelineError
from pipeline import facade
from pipeline.types import WindowResult


@dataclass(frozen=True)
class WallParams:
    """sigma_px: prior corner sigma (px); prior_dof: its weight in pseudo-observations (inf:
    fixed sigma); base_pose: the per-window solver whose snapped quads feed the walls; manhattan:
    tie walls at right angles about a shared vertical into one rotation (facade.tie_walls);
    snap_sigma: each window's corner sigma for its error bars from its snapping
    (:func:`corner_sigmas`; the estimate is unchanged).

    lines: façade line segments of the photo (facade.detect_segments, at least line_min_px long)
    join each wall's vanishing points and its joint fit (:func:`wall_segments`). A segment is a
    candidate of a wall when its midpoint lies within line_margin x the wall's median window size
    of the hull of its windows (window borders included: measured to help, also with exact
    masks); the candidates that share a vanishing point within line_gate_deg of the wall's sides'
    one, and within line_refit_deg of each other (+ the angle of 2 line_sigma_px on their length),
    are the wall's. After the joint fit, every candidate is assigned again to the fitted vanishing
    point it points at within line_refit_deg (+ the same) and the fit repeated. line_sigma_px:
    end-point sigma of a segment. The defaults are the best of a sweep on the walls profile's views.
    description: one line for CLI help and docs (not a parameter: not compared).
    """

    sigma_px: float = TOL.wall_sigma_px
    prior_dof: float = TOL.wall_sigma_prior_dof
    base_pose: str = "ippe"
    manhattan: bool = False
    snap_sigma: bool = False
    lines: bool = False
    line_sigma_px: float = 0.5
    line_min_px: float = 20.0
    line_gate_deg: float = 8.0
    line_refit_deg: float = 0.25
    line_margin: float = 3.0
    description: str = field(default="", compare=False)


WALL_STRATEGIES: dict[str, WallParams] = {
    "wall": WallParams(description="per wall, one rotation fitted over all its windows' corners (the shared plane)"),
    "building": WallParams(manhattan=True, description="per wall, walls at right angles tied into one rotation"),
    "wall+lines": WallParams(lines=True, snap_sigma=True,
                             description="per wall, with the facade's line segments (LSD) in its vanishing points and fit; "
                                         "error bars from each window's snapping"),
    "building+lines": WallParams(manhattan=True, lines=True, snap_sigma=True,
                                 description="walls at right angles tied into one rotation, with the facade's line segments"),
}

def norm_quantile(cov: np.ndarray, level: float = TOL.interval_level) -> float:
    """``level`` quantile of |x| for x ~ N(0, cov (3, 3)): Satterthwaite's scaled chi-square,
    |x|^2 ~ c chi2(nu) with c = tr(S^2) / tr(S), nu = tr(S)^2 / tr(S^2) (exact when isotropic)."""
    S = 0.5 * (cov + cov.T)
    tr, tr2 = float(np.trace(S)), float(np.sum(S * S))
    if not tr > 0:
        return 0.0
    return float(np.sqrt(tr2 / tr * chi2.ppf(level, tr * tr / tr2)))


def window_uncertainty(fit: facade.WallFit, i: int, level: float = TOL.interval_level) -> dict:
    """90 % intervals of window i of a wall fit: aspect (lo, hi), rotation (deg), |dt| / |t|."""
    z = float(norm.ppf(0.5 + level / 2.0))
    wb, rb = fit.window_block(i), fit.rot_block(i)
    cw = fit.cov[wb, wb]
    a = fit.width[i] / fit.height
    a_sd = float(np.sqrt(max(cw[3, 3], 0.0))) / fit.height
    rot = np.degrees(norm_quantile(fit.cov[rb, rb], level))
    trans = norm_quantile(cw[:3, :3], level) / float(np.linalg.norm(fit.t[i]))
    ill = bool(z * a_sd / a > TOL.ill_conditioned_aspect_rel or rot > TOL.ill_conditioned_rot_deg)
    return {"level": level, "sigma_px": fit.sigma_px, "aspect_sd": a_sd, "aspect_lo": a - z * a_sd,
            "aspect_hi": a + z * a_sd, "rot_deg": float(rot), "trans_rel": float(trans),
            "ill_conditioned": ill}


def pseudo_K(image_shape: tuple[int, int], focal_px: float | None = None) -> np.ndarray:
    """Square-pixel K (3, 3) with the principal point at the centre of an (H, W) image; focal
    ``focal_px`` (default max(H, W), a placeholder for grouping)."""
    H, W = image_shape
    f = float(max(H, W)) if focal_px is None else float(focal_px)
    return np.array([[f, 0.0, (W - 1) / 2.0], [0.0, f, (H - 1) / 2.0], [0.0, 0.0, 1.0]])


Fit = tuple[tuple[int, ...], tuple[int, ...], "facade.WallFit | None"]  # windows, their walls, fit
WallLines = tuple[np.ndarray, np.ndarray]  # a wall's candidate façade segments (M, 2, 2) px, their family (M,)


def quad_sizes(quads: np.ndarray) -> np.ndarray:
    """Square root of the area (N,) px of quads (N, 4, 2) px."""
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    x, y = q[..., 0], q[..., 1]
    return np.sqrt(0.5 * np.abs(np.sum(x * np.roll(y, -1, 1) - y * np.roll(x, -1, 1), axis=1)))


def wall_segments(segments: np.ndarray, quads: np.ndarray, members: list[int], K: np.ndarray,
                  params: WallParams, rounds: int = 2) -> tuple[WallLines, tuple[np.ndarray, np.ndarray]]:
    """The candidate façade segments of the wall of windows ``members`` of quads (N, 4, 2) px among
    the photo's ``segments`` (M, 2, 2) px, the vanishing direction each follows, and the wall's
    vanishing directions (d_h, d_v) (3,) under K from its sides and those segments.

    Candidates: see WallParams.lines (none: the sides' vanishing points). Assignment (0: d_h, 1:
    d_v, -1: neither): per direction, the segments that agree on one vanishing point near the
    sides' (facade.vp_consensus, within line_gate_deg of it, line_refit_deg of each other);
    ``rounds`` times, each around the vanishing points refitted with the segments found.
    """
    vp = facade.fit_vps(quads, list(members), K, params.sigma_px)
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    if not len(s):
        return (s, np.zeros(0, dtype=int)), vp
    q = quads[list(members)]
    mid = 0.5 * (s[:, 0] + s[:, 1])
    s = s[facade.hull_distance(mid, q) >= -params.line_margin * float(np.median(quad_sizes(q)))]
    for _ in range(rounds):
        inl = [facade.vp_consensus(s, d, K, params.line_gate_deg, params.line_refit_deg, params.line_sigma_px)
               for d in vp]
        fam = np.where(inl[0] & ~inl[1], 0, np.where(inl[1] & ~inl[0], 1, -1))
        vp = facade.fit_vps(quads, list(members), K, params.sigma_px, lines=(s[fam == 0], s[fam == 1]),
                            line_sigma_px=params.line_sigma_px)
    return (s, fam), vp


def wall_vps(quads: np.ndarray, K: np.ndarray, walls: list[facade.WallVP], params: WallParams,
             segments: np.ndarray | None = None) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[WallLines] | None]:
    """Per wall: its vanishing directions (d_h, d_v) under K from its windows' sides and, given the
    photo's façade segments (M, 2, 2) px, those that follow them (:func:`wall_segments`); and the
    segments per wall (None without)."""
    if segments is None:
        return [facade.fit_vps(quads, list(w.members), K, params.sigma_px) for w in walls], None
    out = [wall_segments(segments, quads, list(w.members), K, params) for w in walls]
    return [vp for _, vp in out], [wl for wl, _ in out]


def _rotation_groups(quads: np.ndarray, K: np.ndarray, walls: list[facade.WallVP], params: WallParams,
                     segments: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[WallLines] | None]:
    """Per wall: initial rotation R0 (G, 3, 3) under K, rotation group (G,), Q (G, 3, 3), and its
    façade segments (:func:`wall_vps`)."""
    vps, lines = wall_vps(quads, K, walls, params, segments)
    R0 = np.array([facade.initial_rotation(*vp) for vp in vps])
    if params.manhattan:
        group, Q = facade.tie_walls(R0)
    else:
        group, Q = np.arange(len(walls)), np.repeat(np.eye(3)[None], len(walls), axis=0)
    return R0, group, Q, lines


def _line_obs(lines: list[WallLines], sel: list[int], set_of_wall: dict[int, int], Q: np.ndarray,
              weight: float) -> tuple[facade.LineObs, np.ndarray]:
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
    obs = facade.LineObs(seg, np.concatenate(grp), np.concatenate(Qs), np.tile([0, 1], len(seg) // 2),
                         np.full(len(seg), weight))
    return obs, np.concatenate(keep)


def _refit_lines(fit: Callable[[facade.LineObs | None], facade.WallFit], quads: np.ndarray, K: np.ndarray,
                 params: WallParams, obs: facade.LineObs, keep: np.ndarray) -> facade.WallFit:
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


def _fit_groups(quads: np.ndarray, K: np.ndarray, walls: list[facade.WallVP], groups: list[int],
                R0: np.ndarray, group: np.ndarray, Q: np.ndarray, height: float, params: WallParams,
                focal_free: bool, lines: list[WallLines] | None = None, sigmas: np.ndarray | None = None) -> Fit:
    """One joint fit of the walls of rotation groups ``groups`` (their first wall is the reference),
    with their façade segments ``lines`` (per wall) when given, and each window's corner sigma
    ``sigmas`` (N,) px (None: params.sigma_px for all)."""
    sel = [g for g in range(len(walls)) if group[g] in groups]
    members = tuple(i for g in sel for i in walls[g].members)
    wall_ids = tuple(g for g in sel for _ in walls[g].members)
    refs = {k: next(g for g in sel if group[g] == k and np.allclose(Q[g], np.eye(3))) for k in groups}
    set_of = np.array([groups.index(group[g]) for g in wall_ids])
    R0s = np.array([R0[refs[k]] for k in groups])
    q = quads[list(members)]
    cs = None if sigmas is None else np.asarray(sigmas, dtype=np.float64)[list(members)]

    def fit(obs: facade.LineObs | None = None) -> facade.WallFit:
        return facade.refine_walls(q, K, R0s, set_of, height, focal_free, params.sigma_px, params.prior_dof,
                                   Q[list(wall_ids)], lines=obs if obs is not None and len(obs) else None,
                                   corner_sigma=cs)

    try:
        if lines is None:
            wall_fit = fit()
        else:
            obs, keep = _line_obs(lines, sel, {g: groups.index(group[g]) for g in sel}, Q,
                                  params.sigma_px / params.line_sigma_px)
            wall_fit = _refit_lines(fit, q, K, params, obs, keep)
    except (PipelineError, np.linalg.LinAlgError, ValueError):
        if focal_free:
            raise
        wall_fit = None
    return members, wall_ids, wall_fit


def outlier_windows(quads: np.ndarray, fits: list[Fit], factor: float = TOL.wall_outlier_factor,
                    floor_px: float = TOL.wall_outlier_px) -> list[int]:
    """Windows (indices into quads (N, 4, 2) px) that do not fit their wall: in a fit of >= 3
    windows, an RMS corner residual above ``factor`` x the fit's median and above ``floor_px``."""
    bad = []
    for members, _, fit in fits:
        if fit is None or len(members) < 3:
            continue
        rms = np.sqrt(np.mean(np.sum((fit.reprojected - quads[list(members)]) ** 2, axis=2), axis=1))
        bad += [m for m, r in zip(members, rms) if r > max(factor * np.median(rms), floor_px)]
    return bad


def split_off(quads: np.ndarray, K: np.ndarray, walls: list[facade.WallVP], windows: list[int],
              sigma_px: float) -> list[facade.WallVP]:
    """The walls with ``windows`` taken out of theirs, each one a wall of its own (largest first)."""
    out = []
    for w in walls:
        keep = [m for m in w.members if m not in windows]
        if keep == list(w.members):
            out.append(w)
        elif keep:
            out.append(facade.WallVP(*facade.fit_vps(quads, keep, K, sigma_px), tuple(keep)))
    out += [facade.WallVP(*facade.fit_vps(quads, [m], K, sigma_px), (m,)) for m in windows]
    return sorted(out, key=lambda w: -len(w.members))


def fit_walls(quads: np.ndarray, K: np.ndarray, height: float, params: WallParams,
              segments: np.ndarray | None = None, sigmas: np.ndarray | None = None) -> list[Fit]:
    """Group quads (N, 4, 2) px into walls and fit each rotation group (K known, so groups are
    independent): [(window indices, their wall indices, fit or None where it failed)]. Windows that
    do not fit their wall (:func:`outlier_windows`) are split off and everything refitted (twice at
    most). segments: the photo's façade line segments (M, 2, 2) px (WallParams.lines), or None;
    sigmas (N,) px: each window's corner sigma (:func:`corner_sigmas`), or None."""
    walls = facade.group_walls(quads, K, params.sigma_px)
    for attempt in range(3):
        R0, group, Q, lines = _rotation_groups(quads, K, walls, params, segments)
        fits = [_fit_groups(quads, K, walls, [k], R0, group, Q, height, params, False, lines, sigmas)
                for k in sorted(set(group))]
        bad = outlier_windows(quads, fits) if attempt < 2 else []
        if not bad:
            return fits
        walls = split_off(quads, K, walls, bad, params.sigma_px)
    return fits


def fit_walls_focal(quads: np.ndarray, image_shape: tuple[int, int], height: float = 1.0,
                    params: WallParams = WallParams(), segments: np.ndarray | None = None,
                    sigmas: np.ndarray | None = None) -> Fit:
    """Unknown focal length: group quads (N, 4, 2) px of an (H, W) image into walls, start f at the
    median of the walls' vanishing-point estimates (:func:`facade.focal_from_vanishing`), then fit
    all walls jointly with one shared f (principal point at the image centre). segments: the
    photo's façade line segments (M, 2, 2) px, which join the vanishing points and the fit, or None;
    sigmas (N,) px: each window's corner sigma, or None.

    Returns (windows, their walls, the joint fit). Raises FacadeError when no wall gives f, or the
    fitted f's relative sd exceeds TOL.focal_max_rel_sd (unobservable).
    """
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    K0 = pseudo_K(image_shape)
    walls = facade.group_walls(q, K0, params.sigma_px)
    vps = [(w.d_h, w.d_v) for w in walls] if segments is None else wall_vps(q, K0, walls, params, segments)[0]
    f0 = [f for d_h, d_v in vps if (f := facade.focal_from_vanishing(d_h, d_v, K0)) is not None]
    if not f0:
        raise facade.FacadeError(f"focal length unobservable from {len(q)} window(s): no wall shows "
                                 f"two converging side pairs")
    K1 = pseudo_K(image_shape, float(np.median(f0)))
    R0, group, Q, lines = _rotation_groups(q, K1, walls, params, segments)
    try:
        members, wall_ids, fit = _fit_groups(q, K1, walls, sorted(set(group)), R0, group, Q, height, params,
                                             True, lines, sigmas)
    except (np.linalg.LinAlgError, ValueError) as e:
        raise facade.FacadeError(f"joint fit with free focal length failed: {e}") from e
    sd = float(np.sqrt(max(fit.cov[-1, -1], 0.0)))
    if not sd / fit.focal_px <= TOL.focal_max_rel_sd:
        raise facade.FacadeError(f"focal length unobservable: f = {fit.focal_px:.0f} +- {sd:.0f} px "
                                 f"(relative sd above {TOL.focal_max_rel_sd})")
    return members, wall_ids, fit


def focal_from_walls(quads: np.ndarray, image_shape: tuple[int, int],
                     params: WallParams = WallParams(), gray: np.ndarray | None = None) -> tuple[float, float]:
    """Focal length (px) and its standard deviation from window quads (N, 4, 2) px of an (H, W)
    image (:func:`fit_walls_focal`; gray (H, W): the photo, needed when params.lines);
    FacadeError when unobservable."""
    fit = fit_walls_focal(quads, image_shape, 1.0, params, photo_segments(gray, params))[2]
    return fit.focal_px, float(np.sqrt(fit.cov[-1, -1]))


def corner_sigmas(results: list[WindowResult], params: WallParams) -> np.ndarray | None:
    """Each window's corner sigma (N,) px when params.snap_sigma: at least params.sigma_px and the
    RMS distance its corners moved in snapping (quad_mask -> quad_snapped; when the snapper moved a
    corner by d, the mask or the snap is off by about d); else None (params.sigma_px for all)."""
    if not params.snap_sigma:
        return None
    moved = [0.0 if r.quad_mask is None else float(np.sqrt(np.mean(np.sum((r.quad_snapped - r.quad_mask) ** 2, axis=1))))
             for r in results]
    return np.maximum(params.sigma_px, np.array(moved))


def photo_segments(gray: np.ndarray | None, params: WallParams) -> np.ndarray | None:
    """The façade segments (M, 2, 2) px a strategy uses: those of the gray photo (H, W), uint8 or
    float in [0, 255] (facade.detect_segments) when params.lines, else None. ValueError when it needs the photo and
    has none."""
    if not params.lines:
        return None
    if gray is None:
        raise ValueError("a per-wall strategy with façade lines (WallParams.lines) needs the gray image")
    return facade.detect_segments(gray, params.line_min_px)


def usable_quad(quad: np.ndarray, min_side_px: float = 1.0) -> bool:
    """A quad (4, 2) px the wall geometry can use: finite, every side at least min_side_px."""
    q = np.asarray(quad, dtype=np.float64)
    sides = np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)
    return bool(np.all(np.isfinite(q)) and sides.min() >= min_side_px)


def apply_walls(results: list[WindowResult], K: np.ndarray | None, image_shape: tuple[int, int],
                height_m: float, width_m: float | None, params: WallParams,
                gray: np.ndarray | None = None) -> list[WindowResult]:
    """Replace the per-window aspect/pose of ``results`` by the per-wall estimates; gray (H, W)
    uint8 or float in [0, 255]: the photo, needed by a strategy with façade lines (WallParams.lines).

    K None: f from :func:`focal_from_walls` (every window then records it as focal_estimate_px);
    if unobservable, every window fails with that reason. Windows without a snapped quad keep
    their result; a window whose wall fit fails keeps its failure, named ``wall: ...``, and no
    focal estimate (not its per-window one).
    """
    idx = [k for k, r in enumerate(results) if r.quad_snapped is not None]
    out = list(results)
    for k in [k for k in idx if not usable_quad(results[k].quad_snapped)]:
        out[k] = replace(out[k], failure="wall: degenerate quad (a side under 1 px or non-finite)",
                         R=None, t=None, quad_reprojected=None, focal_estimate_px=None)
        idx.remove(k)
    if not idx:
        return out
    quads = np.array([results[k].quad_snapped for k in idx], dtype=np.float64)
    segments = photo_segments(gray, params)
    sigmas = corner_sigmas([results[k] for k in idx], params)
    f_est = None
    if K is None:
        try:
            fits = [fit_walls_focal(quads, image_shape, height_m, params, segments, sigmas)]
        except facade.FacadeError as e:
            for k in idx:
                out[k] = replace(out[k], failure=f"wall: {e}", R=None, t=None, quad_reprojected=None,
                                 focal_estimate_px=None)
            return out
        f_est = fits[0][2].focal_px
    else:
        fits = fit_walls(quads, K, height_m, params, segments, sigmas)
    for members, wall_ids, fit in fits:
        for j, (m, wid) in enumerate(zip(members, wall_ids)):
            k = idx[m]
            if fit is None:
                out[k] = replace(out[k], failure="wall: joint fit failed", R=None, t=None,
                                 quad_reprojected=None, focal_estimate_px=None, wall=wid)
                continue
            unc = window_uncertainty(fit, j)
            scale = 1.0 if width_m is None else width_m / fit.width[j]
            case = out[k].aspect_case or "general"
            out[k] = replace(out[k], aspect_ratio=float(fit.width[j] / fit.height),
                             aspect_case="ill_conditioned" if unc["ill_conditioned"] else case,
                             focal_estimate_px=f_est, R=fit.window_R(j), t=fit.t[j] * scale,
                             height_m=fit.height * scale, quad_reprojected=fit.reprojected[j],
                             failure=None, wall=wid, uncertainty=unc)
    return out
