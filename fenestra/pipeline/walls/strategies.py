"""Per-wall strategies: group a photo's windows into walls, estimate each wall's geometry once.

The built-in strategies are :data:`WALL_STRATEGIES`, registered (beside the per-window solvers
of pipeline.pose) in the one pose registry ``fenestra.pipeline.poses.POSES``; the bench's method
combinations run both kinds. A wall strategy takes the per-window results (their
snapped quads), groups the windows into walls (:func:`pipeline.walls.vanishing.group_walls`), fits
each wall jointly (:func:`pipeline.walls.fit.refine_walls`: one rotation, per-window translation
and width) and gives every window its aspect ratio, pose and error bars from the shared plane
(:func:`apply_walls`).

``+lines`` strategies also use the photo's straight line segments (wall edges, eaves, mullions,
window frames): those that agree with a wall's vanishing points join its fit (WallParams.lines,
pipeline.walls.lines); they need the photo's segment cache (``apply_walls(...,
segments=SegmentCache(gray))``, pipeline.segments).

Unknown intrinsics (K None): the focal length is estimated from the walls (each wall's two
vanishing directions, then the joint fit with f free; walls combined by inverse variance); the
principal point is the image centre (:func:`fit_walls_focal`, :func:`focal_from_walls`).

Uncertainty per window (``WindowResult.uncertainty``, a pipeline.types.Uncertainty): first-order covariance of the joint fit
with the corner sigma pooled from the residuals and a prior (WALL_FIT.sigma_px; with
WallParams.snap_sigma, per window at least how far snapping moved its corners), reported as 90 %
intervals: ``aspect_lo/aspect_hi``, ``rot_deg`` (bound on the rotation error), ``trans_rel``
(bound on |t error| / |t|), and ``ill_conditioned`` (aspect_case becomes "ill_conditioned").
"""
from __future__ import annotations

from dataclasses import fields, replace
from itertools import combinations

import numpy as np

from fenestra.errors import PipelineError
from fenestra.pipeline.memo import StepMemo, key
from fenestra.pipeline.segments import SegmentCache
from fenestra.pipeline.types import AspectCase, Failure, WindowResult
from fenestra.pipeline.walls.fit import WallFit, refine_walls, window_uncertainty
from fenestra.pipeline.walls.lines import LineObs, WallLines, line_obs, photo_segments, refit_lines, wall_vps
from fenestra.pipeline.walls.settings import WALL_FIT, WallParams
from fenestra.pipeline.walls.vanishing import (FacadeError, WallVP, fit_vps, focal_from_vanishing, group_walls,
                                      initial_rotation, tie_walls)


WALL_STRATEGIES: dict[str, WallParams] = {  # built-in entries of pipeline.poses.POSES (read there once)
    "wall": WallParams(description="per wall, one rotation fitted over all its windows' corners (the shared plane)"),
    "building": WallParams(manhattan=True, description="per wall, walls at right angles tied into one rotation"),
    "wall+lines": WallParams(lines=True, snap_sigma=True,
                             description="per wall, with the facade's line segments (LSD) in its vanishing points and fit; "
                                         "error bars from each window's snapping"),
    "building+lines": WallParams(manhattan=True, lines=True, snap_sigma=True,
                                 description="walls at right angles tied into one rotation, with the facade's line segments"),
}


def pseudo_K(image_shape: tuple[int, int], focal_px: float | None = None) -> np.ndarray:
    """Square-pixel K (3, 3) with the principal point at the centre of an (H, W) image; focal
    ``focal_px`` (default max(H, W), a placeholder for grouping)."""
    H, W = image_shape
    f = float(max(H, W)) if focal_px is None else float(focal_px)
    return np.array([[f, 0.0, (W - 1) / 2.0], [0.0, f, (H - 1) / 2.0], [0.0, 0.0, 1.0]])


Fit = tuple[tuple[int, ...], tuple[int, ...], "WallFit | None"]  # windows, their walls, fit


def corner_sigmas(results: list[WindowResult], params: WallParams) -> np.ndarray | None:
    """Each window's corner sigma (N,) px when params.snap_sigma: at least params.sigma_px and the
    RMS distance its corners moved in snapping (quad_mask -> quad_snapped; when the snapper moved a
    corner by d, the mask or the snap is off by about d); else None (params.sigma_px for all)."""
    if not params.snap_sigma:
        return None
    moved = [0.0 if r.quad_mask is None else float(np.sqrt(np.mean(np.sum((r.quad_snapped - r.quad_mask) ** 2, axis=1))))
             for r in results]
    return np.maximum(params.sigma_px, np.array(moved))


def usable_quad(quad: np.ndarray, min_side_px: float = 1.0) -> bool:
    """A quad (4, 2) px the wall geometry can use: finite, every side at least min_side_px."""
    q = np.asarray(quad, dtype=np.float64)
    sides = np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)
    return bool(np.all(np.isfinite(q)) and sides.min() >= min_side_px)


def _shared(params: WallParams) -> WallParams:
    """params without what only the tie of walls at right angles (manhattan) and the windows'
    corner sigmas (snap_sigma, given to the steps as ``sigmas``) read: the memo key of the steps
    (grouping, vanishing points, fits) that ``wall`` and ``building`` (and their ``+lines``) share."""
    return replace(params, manhattan=False, snap_sigma=False)


def _wall_vps(quads: np.ndarray, K: np.ndarray, walls: list[WallVP], params: WallParams,
              segments: np.ndarray | None, memo: StepMemo) -> tuple[list, list[WallLines] | None]:
    """:func:`pipeline.walls.lines.wall_vps`, wall by wall (each a function of its own windows), each
    wall's kept in ``memo``."""
    per = [memo("wall_vps", key(quads, K, w.members, _shared(params), segments),
                lambda w=w: wall_vps(quads, K, [w], params, segments)) for w in walls]
    vps = [vp for vp_list, _ in per for vp in vp_list]
    return vps, None if segments is None else [wl for _, lines in per for wl in lines]


def _rotation_groups(quads: np.ndarray, K: np.ndarray, walls: list[WallVP], params: WallParams,
                     segments: np.ndarray | None = None, memo: StepMemo | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[WallLines] | None]:
    """Per wall: initial rotation R0 (G, 3, 3) under K, rotation group (G,), Q (G, 3, 3), and its
    façade segments (:func:`wall_vps`); memo: kept vanishing points (None: a new memo)."""
    vps, lines = _wall_vps(quads, K, walls, params, segments, StepMemo() if memo is None else memo)
    R0 = np.array([initial_rotation(*vp) for vp in vps])
    if params.manhattan:
        group, Q = tie_walls(R0)
    else:
        group, Q = np.arange(len(walls)), np.repeat(np.eye(3)[None], len(walls), axis=0)
    return R0, group, Q, lines


def _fit_groups(quads: np.ndarray, K: np.ndarray, walls: list[WallVP], groups: list[int],
                R0: np.ndarray, group: np.ndarray, Q: np.ndarray, height: float, params: WallParams,
                focal_free: bool, lines: list[WallLines] | None = None, sigmas: np.ndarray | None = None,
                memo: StepMemo | None = None, focal_bounds: tuple[float, float] | None = None,
                give_up_rel_sd: float | None = None) -> Fit:
    """One joint fit of the walls of rotation groups ``groups`` (their first wall is the reference),
    with their façade segments ``lines`` (per wall) when given, and each window's corner sigma
    ``sigmas`` (N,) px (None: params.sigma_px for all); the fit kept in ``memo`` under its inputs
    (None: not kept). With ``focal_free``: focal_bounds (lo, hi) px stop a runaway f
    (refine_walls), and a pass whose focal relative sd is above give_up_rel_sd stops the fit
    (FacadeError) before the +lines refit runs (None: never)."""
    sel = [g for g in range(len(walls)) if group[g] in groups]
    members = tuple(i for g in sel for i in walls[g].members)
    wall_ids = tuple(g for g in sel for _ in walls[g].members)
    refs = {k: next(g for g in sel if group[g] == k and np.allclose(Q[g], np.eye(3))) for k in groups}
    set_of = np.array([groups.index(group[g]) for g in wall_ids])
    R0s = np.array([R0[refs[k]] for k in groups])
    q = quads[list(members)]
    cs = None if sigmas is None else np.asarray(sigmas, dtype=np.float64)[list(members)]

    Qw = Q[list(wall_ids)]

    def fit(obs: LineObs | None = None) -> WallFit:  # kept too: refit_lines' second fit often repeats its first
        lines_in = obs if obs is not None and len(obs) else None

        def run() -> WallFit:
            return refine_walls(q, K, R0s, set_of, height, focal_free, params.sigma_px, params.prior_dof, Qw,
                                lines=lines_in, corner_sigma=cs, focal_bounds=focal_bounds)

        if memo is None:
            out = run()
        else:
            obs_key = None if lines_in is None else tuple(getattr(lines_in, f.name) for f in fields(lines_in))
            out = memo("refine_walls", key(q, K, R0s, set_of, Qw, height, focal_free, params.sigma_px,
                                           params.prior_dof, cs, obs_key, focal_bounds), run)
        if focal_free and give_up_rel_sd is not None:
            check_focal_sd(out, give_up_rel_sd, "already after the first pass")
        return out

    def solve() -> WallFit | None:
        try:
            if lines is None:
                return fit()
            obs, keep = line_obs(lines, sel, {g: groups.index(group[g]) for g in sel}, Q,
                                 params.sigma_px / params.line_sigma_px)
            return refit_lines(fit, q, K, params, obs, keep)
        except (PipelineError, np.linalg.LinAlgError, ValueError):
            if focal_free:
                raise
            return None

    if memo is None:
        return members, wall_ids, solve()
    wall_lines = None if lines is None else ([lines[g] for g in sel], [groups.index(group[g]) for g in sel], Q[sel])
    k = key(q, K, R0s, set_of, Qw, height, focal_free, _shared(params), cs, wall_lines, focal_bounds, give_up_rel_sd)
    return members, wall_ids, memo("fit", k, solve)


def outlier_windows(quads: np.ndarray, fits: list[Fit], factor: float = WALL_FIT.outlier_factor,
                    floor_px: float = WALL_FIT.outlier_px) -> list[int]:
    """Windows (indices into quads (N, 4, 2) px) that do not fit their wall: in a fit of >= 3
    windows, an RMS corner residual above ``factor`` x the fit's median and above ``floor_px``."""
    bad = []
    for members, _, fit in fits:
        if fit is None or len(members) < 3:
            continue
        rms = np.sqrt(np.mean(np.sum((fit.reprojected - quads[list(members)]) ** 2, axis=2), axis=1))
        bad += [m for m, r in zip(members, rms) if r > max(factor * np.median(rms), floor_px)]
    return bad


def split_off(quads: np.ndarray, K: np.ndarray, walls: list[WallVP], windows: list[int],
              sigma_px: float) -> list[WallVP]:
    """The walls with ``windows`` taken out of theirs, each one a wall of its own (largest first)."""
    out = []
    for w in walls:
        keep = [m for m in w.members if m not in windows]
        if keep == list(w.members):
            out.append(w)
        elif keep:
            out.append(WallVP(*fit_vps(quads, keep, K, sigma_px), tuple(keep)))
    out += [WallVP(*fit_vps(quads, [m], K, sigma_px), (m,)) for m in windows]
    return sorted(out, key=lambda w: -len(w.members))


def _group_walls(quads: np.ndarray, K: np.ndarray, params: WallParams, memo: StepMemo) -> list[WallVP]:
    """:func:`pipeline.walls.vanishing.group_walls` of quads under K, kept in ``memo``."""
    return memo("group_walls", key(quads, K, params.sigma_px), lambda: group_walls(quads, K, params.sigma_px))


def fit_walls(quads: np.ndarray, K: np.ndarray, height: float, params: WallParams,
              segments: np.ndarray | None = None, sigmas: np.ndarray | None = None,
              memo: StepMemo | None = None) -> list[Fit]:
    """Group quads (N, 4, 2) px into walls and fit each rotation group (K known, so groups are
    independent): [(window indices, their wall indices, fit or None where it failed)]. Windows that
    do not fit their wall (:func:`outlier_windows`) are split off and everything refitted (twice at
    most). segments: the photo's façade line segments (M, 2, 2) px (WallParams.lines), or None;
    sigmas (N,) px: each window's corner sigma (:func:`corner_sigmas`), or None. memo: the
    photo's :class:`~pipeline.memo.StepMemo` (None: a new one for this call; the refits
    after a split reuse the walls that kept their windows either way)."""
    memo = StepMemo() if memo is None else memo
    walls = _group_walls(quads, K, params, memo)
    for attempt in range(3):
        R0, group, Q, lines = _rotation_groups(quads, K, walls, params, segments, memo)
        fits = [_fit_groups(quads, K, walls, [k], R0, group, Q, height, params, False, lines, sigmas, memo)
                for k in sorted(set(group))]
        bad = outlier_windows(quads, fits) if attempt < 2 else []
        if not bad:
            return fits
        walls = split_off(quads, K, walls, bad, params.sigma_px)
    return fits


def check_focal_sd(fit: WallFit, max_rel_sd: float, when: str = "") -> float:
    """The sd (px) of a free-focal fit's f; FacadeError when its variance is not positive or its
    relative sd is above max_rel_sd (``when``: words for the message)."""
    var = float(fit.cov[-1, -1])
    if not var > 0.0:  # an indefinite covariance (rank-deficient fit): no sd to trust
        raise FacadeError(f"focal length unobservable: f = {fit.focal_px:.0f} px, its variance {var:.3g} "
                          f"is not positive")
    sd = float(np.sqrt(var))
    if not sd / fit.focal_px <= max_rel_sd:
        raise FacadeError(f"focal length unobservable: f = {fit.focal_px:.0f} +- {sd:.0f} px "
                          f"(relative sd above {max_rel_sd:.3g}{' ' + when if when else ''})")
    return sd


CORNER_MIN_WINDOWS = 2  # windows a wall needs to count in a corner (one window's horizontal is too vague)


def corner_focals(d_hs: list[np.ndarray], K0: np.ndarray) -> list[float]:
    """Focal lengths (px) of a building's corners: for each pair of walls whose horizontal vanishing
    directions d_h (3,) (found under the pseudo-K0 (3, 3)) are seen at a right angle
    (:func:`focal_from_vanishing` of the two: f^2 = -(v1 - p).(v2 - p) > 0), that f; pairs seen
    nearly parallel (one façade split in two) or with a vanishing point at infinity give none."""
    return [f for a, b in combinations(range(len(d_hs)), 2)
            if (f := focal_from_vanishing(d_hs[a], d_hs[b], K0)) is not None]


def fit_walls_focal(quads: np.ndarray, image_shape: tuple[int, int], height: float = 1.0,
                    params: WallParams = WallParams(), segments: np.ndarray | None = None,
                    sigmas: np.ndarray | None = None, memo: StepMemo | None = None,
                    give_up_rel_sd: float | None = None) -> Fit:
    """Unknown focal length: group quads (N, 4, 2) px of an (H, W) image into walls, start f at the
    median of the walls' vanishing-point estimates (:func:`focal_from_vanishing`), then fit
    all walls jointly with one shared f (principal point at the image centre). Where no wall alone
    gives f (a level camera: each wall's verticals parallel in the image), two walls of at least
    CORNER_MIN_WINDOWS windows seen at a right angle do (a corner, :func:`corner_focals`): f starts
    at their median and the fit ties the walls at right angles (WallParams.manhattan), which is what
    constrains it; only then, since f from a corner assumes the right angle it would check
    (docs/DESIGN.md). segments: the
    photo's façade line segments (M, 2, 2) px, which join the vanishing points and the fit, or None;
    sigmas (N,) px: each window's corner sigma, or None; memo: as for :func:`fit_walls`.

    Returns (windows, their walls, the joint fit). Raises FacadeError when no wall gives f, or the
    fitted f's relative sd exceeds WALL_FIT.focal_max_rel_sd (unobservable). Bounded time: the fit
    stops when f leaves WALL_FIT.focal_range_rel x the long side, after WALL_FIT.max_nfev
    evaluations, and (give_up_rel_sd, the caller's own gate x WALL_FIT.focal_give_up_factor; None:
    not used) when a pass's relative sd already exceeds give_up_rel_sd.
    """
    memo = StepMemo() if memo is None else memo
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    K0 = pseudo_K(image_shape)
    walls = _group_walls(q, K0, params, memo)
    vps = [(w.d_h, w.d_v) for w in walls] if segments is None else _wall_vps(q, K0, walls, params, segments, memo)[0]
    f0 = [f for d_h, d_v in vps if (f := focal_from_vanishing(d_h, d_v, K0)) is not None]
    if not f0:  # no wall alone (a level camera): a corner of the building?
        f0 = corner_focals([d_h for (d_h, _), w in zip(vps, walls) if len(w.members) >= CORNER_MIN_WINDOWS], K0)
        params = replace(params, manhattan=True)
    if not f0:
        raise FacadeError(f"focal length unobservable from {len(q)} window(s): no wall shows "
                          f"two converging side pairs, and no two walls of {CORNER_MIN_WINDOWS}+ windows "
                          f"meet at a right angle")
    K1 = pseudo_K(image_shape, float(np.median(f0)))
    R0, group, Q, lines = _rotation_groups(q, K1, walls, params, segments, memo)
    bounds = tuple(float(r * max(image_shape)) for r in WALL_FIT.focal_range_rel)
    try:
        members, wall_ids, fit = _fit_groups(q, K1, walls, sorted(set(group)), R0, group, Q, height, params,
                                             True, lines, sigmas, memo, bounds, give_up_rel_sd)
    except (np.linalg.LinAlgError, ValueError) as e:
        raise FacadeError(f"joint fit with free focal length failed: {e}") from e
    check_focal_sd(fit, WALL_FIT.focal_max_rel_sd)
    return members, wall_ids, fit


def focal_from_walls(quads: np.ndarray, image_shape: tuple[int, int],
                     params: WallParams = WallParams(),
                     segment_cache: SegmentCache | None = None, max_rel_sd: float | None = None) -> tuple[float, float]:
    """Focal length (px) and its standard deviation from window quads (N, 4, 2) px of an (H, W)
    image (:func:`fit_walls_focal`; segment_cache: the photo's segments, needed when params.lines,
    see :func:`apply_walls`); FacadeError when unobservable. max_rel_sd: the caller's own gate on
    the relative sd (None: none): a pass above WALL_FIT.focal_give_up_factor x it stops the fit early."""
    segments = photo_segments(segment_cache, params, image_shape)
    give_up = None if max_rel_sd is None else WALL_FIT.focal_give_up_factor * max_rel_sd
    fit = fit_walls_focal(quads, image_shape, 1.0, params, segments, give_up_rel_sd=give_up)[2]
    return fit.focal_px, float(np.sqrt(fit.cov[-1, -1]))  # > 0: fit_walls_focal checked it


def apply_walls(results: list[WindowResult], K: np.ndarray | None, image_shape: tuple[int, int],
                height_m: float, width_m: float | None, params: WallParams,
                segment_cache: SegmentCache | None = None, memo: StepMemo | None = None) -> list[WindowResult]:
    """Replace the per-window aspect/pose of ``results`` by the per-wall estimates. segment_cache:
    the photo's segments (``pipeline.segments.SegmentCache(gray)``, gray (H, W) uint8 or float in
    [0, 255], one per photo, shared with the other steps that need them), needed by a strategy with
    façade lines (WallParams.lines); ValueError without it, or when its photo is not image_shape.
    memo: the photo's :class:`~pipeline.memo.StepMemo`, shared by the strategies run on it (the
    grouping, each wall's vanishing points and each fit computed once per distinct input; the
    results are those of a run without it); None: a new one for this call.

    K None: f from :func:`focal_from_walls` (every window then records it as focal_estimate_px);
    if unobservable, every window fails with that reason. Windows without a snapped quad keep
    their result; a window whose wall fit fails keeps its failure, named ``wall: ...``, and no
    focal estimate (not its per-window one).
    """
    idx = [k for k, r in enumerate(results) if r.quad_snapped is not None]
    out = list(results)
    for k in [k for k in idx if not usable_quad(results[k].quad_snapped)]:
        out[k] = replace(out[k], failure=Failure("wall", None, "degenerate quad (a side under 1 px or non-finite)"),
                         R=None, t=None, quad_reprojected=None, focal_estimate_px=None)
        idx.remove(k)
    if not idx:
        return out
    quads = np.array([results[k].quad_snapped for k in idx], dtype=np.float64)
    segments = photo_segments(segment_cache, params, image_shape)
    sigmas = corner_sigmas([results[k] for k in idx], params)
    f_est = None
    if K is None:
        try:
            fits = [fit_walls_focal(quads, image_shape, height_m, params, segments, sigmas, memo)]
        except FacadeError as e:
            for k in idx:
                out[k] = replace(out[k], failure=Failure("wall", None, str(e)), R=None, t=None, quad_reprojected=None,
                                 focal_estimate_px=None)
            return out
        f_est = fits[0][2].focal_px
    else:
        fits = fit_walls(quads, K, height_m, params, segments, sigmas, memo)
    for members, wall_ids, fit in fits:
        for j, (m, wid) in enumerate(zip(members, wall_ids)):
            k = idx[m]
            if fit is None:
                out[k] = replace(out[k], failure=Failure("wall", None, "joint fit failed"), R=None, t=None,
                                 quad_reprojected=None, focal_estimate_px=None, group=wid)
                continue
            unc = window_uncertainty(fit, j)
            scale = 1.0 if width_m is None else width_m / fit.width[j]
            case = out[k].aspect_case or AspectCase.GENERAL
            out[k] = replace(out[k], aspect_ratio=float(fit.width[j] / fit.height),
                             aspect_case=AspectCase.ILL_CONDITIONED if unc.ill_conditioned else case,
                             focal_estimate_px=f_est, R=fit.window_R(j), t=fit.t[j] * scale,
                             height_m=fit.height * scale, quad_reprojected=fit.reprojected[j],
                             failure=None, group=wid, uncertainty=unc)
    return out
