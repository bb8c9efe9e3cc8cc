"""Settings of the per-wall geometry: the fixed algorithm settings of the wall fit
(:class:`WallFitSettings`, one instance :data:`WALL_FIT`) and a per-wall strategy's parameters
(:class:`WallParams`, the entries of ``pipeline.walls.WALL_STRATEGIES``).

WALL_FIT holds what every strategy shares (vanishing-point inlier angles, the prior corner sigma,
outlier and ill-conditioning thresholds, the interval level); WallParams what a strategy chooses
(ties at right angles, façade lines, its base per-window solver). Neither is a test tolerance.
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class WallFitSettings:
    """Algorithm settings of the wall fit (units in the names).

    vp_angle_deg, corner_noise_px: a side points at its wall's vanishing point within vp_angle_deg
    plus the angle that corner_noise_px makes on its length; sigma_px, sigma_prior_dof: the prior
    corner sigma pooled with the fit's residuals, and the pseudo-observations given to it;
    ill_conditioned_aspect_rel, ill_conditioned_rot_deg: a window whose 90 % half-width of w/h, or
    bound of the rotation error, is above these is ill-conditioned; outlier_factor, outlier_px: a
    window whose corner RMS in its wall fit exceeds outlier_factor x the median and outlier_px is
    split off into a wall of its own; manhattan_deg: walls this close to k x 90 deg about a shared
    vertical are tied; focal_max_rel_sd: a focal estimate with a larger relative sd is not used;
    max_nfev: at most this many residual evaluations per joint fit (a well-posed fit converges in
    tens; an unobservable focal length drifts for thousands: 148 CPU-s on one street photo, issue
    35); focal_range_rel: with the focal length free, the fit stops as soon as f leaves this range
    x the image's long side (a 0.05x .. 20x focal length is a 170 .. 2.9 deg field of view: f is
    running away, the façade is near fronto-parallel); focal_give_up_factor: with f free and a
    relative-sd gate, the first of the +lines fit's two passes stops the chain when its relative sd
    is above this x the gate (the second pass reassigns the lines, which tightens f by well under
    that; its answer would be rejected anyway);
    interval_level: the level of the reported uncertainty intervals; lsd_scale: the image scale
    OpenCV's LSD sees when it finds a photo's façade line segments (0.8, OpenCV's default: what the
    line settings of WallParams were tuned with).
    """

    vp_angle_deg: float = 1.5
    corner_noise_px: float = 1.5
    sigma_px: float = 0.5
    sigma_prior_dof: float = 4.0
    ill_conditioned_aspect_rel: float = 0.05
    ill_conditioned_rot_deg: float = 5.0
    outlier_factor: float = 3.0
    outlier_px: float = 1.0
    manhattan_deg: float = 8.0
    focal_max_rel_sd: float = 0.25
    max_nfev: int = 400
    focal_range_rel: tuple[float, float] = (0.05, 20.0)
    focal_give_up_factor: float = 3.0
    interval_level: float = 0.90
    lsd_scale: float = 0.8


WALL_FIT = WallFitSettings()


@dataclass(frozen=True)
class WallParams:
    """sigma_px: prior corner sigma (px); prior_dof: its weight in pseudo-observations (inf:
    fixed sigma); base_pose: the per-window solver whose snapped quads feed the walls; manhattan:
    tie walls at right angles about a shared vertical into one rotation (vanishing.tie_walls);
    snap_sigma: each window's corner sigma for its error bars from its snapping
    (strategies.corner_sigmas; the estimate is unchanged).

    lines: façade line segments of the photo (lines.photo_segments, at least line_min_px long)
    join each wall's vanishing points and its joint fit (lines.wall_segments). A segment is a
    candidate of a wall when its midpoint lies within line_margin x the wall's median window size
    of the hull of its windows (window borders included: measured to help, also with exact
    masks); the candidates that share a vanishing point within line_gate_deg of the wall's sides'
    one, and within line_refit_deg of each other (+ the angle of 2 line_sigma_px on their length),
    are the wall's. After the joint fit, every candidate is assigned again to the fitted vanishing
    point it points at within line_refit_deg (+ the same) and the fit repeated. line_sigma_px:
    end-point sigma of a segment. The defaults are the best of a sweep on the walls profile's views.
    description: one line for CLI help and docs (not a parameter: not compared).
    """

    sigma_px: float = WALL_FIT.sigma_px
    prior_dof: float = WALL_FIT.sigma_prior_dof
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
