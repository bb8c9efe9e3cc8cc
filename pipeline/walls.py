"""Per-wall strategies: group a photo's windows into walls, estimate each wall's geometry once.

Registry ``WALL_STRATEGIES`` (pose-strategy names beside ``pipeline.pose.POSE_SOLVERS``; the
bench's method combinations run both). A wall strategy takes the per-window results (their
snapped quads), groups the windows into walls (:func:`pipeline.facade.group_walls`), fits each
wall jointly (:func:`pipeline.facade.refine_wall`: one rotation, per-window translation and width)
and gives every window its aspect ratio, pose and error bars from the shared plane.

Unknown intrinsics (K None): the focal length is estimated from the walls (each wall's two
vanishing directions, then the joint fit with f free; walls combined by inverse variance); the
principal point is the image centre.

Uncertainty per window (``WindowResult.uncertainty``): first-order covariance of the joint fit
with the corner sigma pooled from the residuals and a prior (TOL.wall_sigma_px), reported as 90 %
intervals: ``aspect_lo/aspect_hi``, ``rot_deg`` (bound on the rotation error), ``trans_rel``
(bound on |t error| / |t|), and ``ill_conditioned`` (aspect_case becomes "ill_conditioned").
"""
from __future__ import annotations

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
    description: one line for CLI help and docs (not a parameter: not compared)."""

    sigma_px: float = TOL.wall_sigma_px
    prior_dof: float = TOL.wall_sigma_prior_dof
    base_pose: str = "ippe"
    manhattan: bool = False
    description: str = field(default="", compare=False)


WALL_STRATEGIES: dict[str, WallParams] = {
    "wall": WallParams(description="per wall, one rotation fitted over all its windows' corners (the shared plane)"),
    "building": WallParams(manhattan=True, description="per wall, walls at right angles tied into one rotation"),
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


def _rotation_groups(quads: np.ndarray, K: np.ndarray, walls: list[facade.WallVP], params: WallParams
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per wall: initial rotation R0 (G, 3, 3) under K, rotation group (G,) and Q (G, 3, 3)."""
    R0 = np.array([facade.initial_rotation(*facade.fit_vps(quads, list(w.members), K, params.sigma_px))
                   for w in walls])
    if params.manhattan:
        group, Q = facade.tie_walls(R0)
    else:
        group, Q = np.arange(len(walls)), np.repeat(np.eye(3)[None], len(walls), axis=0)
    return R0, group, Q


def _fit_groups(quads: np.ndarray, K: np.ndarray, walls: list[facade.WallVP], groups: list[int],
                R0: np.ndarray, group: np.ndarray, Q: np.ndarray, height: float, params: WallParams,
                focal_free: bool) -> Fit:
    """One joint fit of the walls of rotation groups ``groups`` (their first wall is the reference)."""
    sel = [g for g in range(len(walls)) if group[g] in groups]
    members = tuple(i for g in sel for i in walls[g].members)
    wall_ids = tuple(g for g in sel for _ in walls[g].members)
    refs = {k: next(g for g in sel if group[g] == k and np.allclose(Q[g], np.eye(3))) for k in groups}
    set_of = np.array([groups.index(group[g]) for g in wall_ids])
    R0s = np.array([R0[refs[k]] for k in groups])
    try:
        fit = facade.refine_walls(quads[list(members)], K, R0s, set_of, height, focal_free, params.sigma_px,
                                  params.prior_dof, Q[list(wall_ids)])
    except (PipelineError, np.linalg.LinAlgError, ValueError):
        if focal_free:
            raise
        fit = None
    return members, wall_ids, fit


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


def fit_walls(quads: np.ndarray, K: np.ndarray, height: float, params: WallParams) -> list[Fit]:
    """Group quads (N, 4, 2) px into walls and fit each rotation group (K known, so groups are
    independent): [(window indices, their wall indices, fit or None where it failed)]. Windows that
    do not fit their wall (:func:`outlier_windows`) are split off and everything refitted (twice at most)."""
    walls = facade.group_walls(quads, K, params.sigma_px)
    for attempt in range(3):
        R0, group, Q = _rotation_groups(quads, K, walls, params)
        fits = [_fit_groups(quads, K, walls, [k], R0, group, Q, height, params, False) for k in sorted(set(group))]
        bad = outlier_windows(quads, fits) if attempt < 2 else []
        if not bad:
            return fits
        walls = split_off(quads, K, walls, bad, params.sigma_px)
    return fits


def fit_walls_focal(quads: np.ndarray, image_shape: tuple[int, int], height: float = 1.0,
                    params: WallParams = WallParams()) -> Fit:
    """Unknown focal length: group quads (N, 4, 2) px of an (H, W) image into walls, start f at the
    median of the walls' vanishing-point estimates (:func:`facade.focal_from_vanishing`), then fit
    all walls jointly with one shared f (principal point at the image centre).

    Returns (windows, their walls, the joint fit). Raises FacadeError when no wall gives f, or the
    fitted f's relative sd exceeds TOL.focal_max_rel_sd (unobservable).
    """
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    K0 = pseudo_K(image_shape)
    walls = facade.group_walls(q, K0, params.sigma_px)
    f0 = [f for w in walls if (f := facade.focal_from_vanishing(w.d_h, w.d_v, K0)) is not None]
    if not f0:
        raise facade.FacadeError(f"focal length unobservable from {len(q)} window(s): no wall shows "
                                 f"two converging side pairs")
    K1 = pseudo_K(image_shape, float(np.median(f0)))
    R0, group, Q = _rotation_groups(q, K1, walls, params)
    try:
        members, wall_ids, fit = _fit_groups(q, K1, walls, sorted(set(group)), R0, group, Q, height, params, True)
    except (np.linalg.LinAlgError, ValueError) as e:
        raise facade.FacadeError(f"joint fit with free focal length failed: {e}") from e
    sd = float(np.sqrt(max(fit.cov[-1, -1], 0.0)))
    if not sd / fit.focal_px <= TOL.focal_max_rel_sd:
        raise facade.FacadeError(f"focal length unobservable: f = {fit.focal_px:.0f} +- {sd:.0f} px "
                                 f"(relative sd above {TOL.focal_max_rel_sd})")
    return members, wall_ids, fit


def focal_from_walls(quads: np.ndarray, image_shape: tuple[int, int],
                     params: WallParams = WallParams()) -> tuple[float, float]:
    """Focal length (px) and its standard deviation from window quads (N, 4, 2) px of an (H, W)
    image (:func:`fit_walls_focal`); FacadeError when unobservable."""
    fit = fit_walls_focal(quads, image_shape, 1.0, params)[2]
    return fit.focal_px, float(np.sqrt(fit.cov[-1, -1]))


def usable_quad(quad: np.ndarray, min_side_px: float = 1.0) -> bool:
    """A quad (4, 2) px the wall geometry can use: finite, every side at least min_side_px."""
    q = np.asarray(quad, dtype=np.float64)
    sides = np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)
    return bool(np.all(np.isfinite(q)) and sides.min() >= min_side_px)


def apply_walls(results: list[WindowResult], K: np.ndarray | None, image_shape: tuple[int, int],
                height_m: float, width_m: float | None, params: WallParams) -> list[WindowResult]:
    """Replace the per-window aspect/pose of ``results`` by the per-wall estimates.

    K None: f from :func:`focal_from_walls` (every window then records it as focal_estimate_px);
    if unobservable, every window fails with that reason. Windows without a snapped quad keep
    their result; a window whose wall fit fails keeps its failure, named ``wall: ...``.
    """
    idx = [k for k, r in enumerate(results) if r.quad_snapped is not None]
    out = list(results)
    for k in [k for k in idx if not usable_quad(results[k].quad_snapped)]:
        out[k] = replace(out[k], failure="wall: degenerate quad (a side under 1 px or non-finite)",
                         R=None, t=None, quad_reprojected=None)
        idx.remove(k)
    if not idx:
        return out
    quads = np.array([results[k].quad_snapped for k in idx], dtype=np.float64)
    f_est = None
    if K is None:
        try:
            fits = [fit_walls_focal(quads, image_shape, height_m, params)]
        except facade.FacadeError as e:
            for k in idx:
                out[k] = replace(out[k], failure=f"wall: {e}", R=None, t=None, quad_reprojected=None)
            return out
        f_est = fits[0][2].focal_px
    else:
        fits = fit_walls(quads, K, height_m, params)
    for members, wall_ids, fit in fits:
        for j, (m, wid) in enumerate(zip(members, wall_ids)):
            k = idx[m]
            if fit is None:
                out[k] = replace(out[k], failure="wall: joint fit failed", R=None, t=None,
                                 quad_reprojected=None, wall=wid)
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
