"""Numerical tolerances of Fenestra's checks and tests (units in the names), apart from the
algorithms' settings.

Tests in ``tests/`` compare against these; the benchmark uses the matching threshold and the
recall thresholds. An algorithm's own parameters live beside the algorithm.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Tolerances:
    """Numerical tolerances used by checks and tests (units in the names)."""

    gt_size_vs_ifc_m: float = 0.005  # loader width/height vs IfcWindow OverallWidth/Height
    gt_right_angle_deg: float = 0.01  # ground-truth rectangle corners
    gt_coplanar_m: float = 1e-6  # corners vs wall face plane
    generator_roundtrip_m: float = 1e-6  # procedural house: loader vs generator parameters
    projection_vs_mask_px: float = 0.1  # projected GT corners vs instance-map edges
    distortion_roundtrip_px: float = 1e-3
    backend_instance_iou: float = 0.99  # pyrender vs mitsuba instance maps
    exact_aspect_rel: float = 1e-6  # aspect ratio from an exact synthetic quad
    exact_rotation_deg: float = 1e-4  # pose from an exact synthetic quad
    parallel_sides_deg: float = 0.05  # opposite image sides closer than this count as parallel
    match_iou: float = 0.5  # detection <-> ground truth matching
    recall_thresholds_px: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0)
    # moving to pipeline/walls/settings.py: the façade geometry's algorithm settings (pipeline/facade.py,
    # pipeline/walls.py), not tolerances
    wall_vp_angle_deg: float = 1.5  # a side points at its wall's vanishing point within this ...
    wall_corner_noise_px: float = 1.5  # ... plus the angle that this corner noise makes on its length
    wall_sigma_px: float = 0.5  # prior corner sigma (px) pooled with the wall fit's residuals
    wall_sigma_prior_dof: float = 4.0  # pseudo-observations given to that prior
    ill_conditioned_aspect_rel: float = 0.05  # 90 % half-width of w/h above this: ill-conditioned
    ill_conditioned_rot_deg: float = 5.0  # 90 % bound of the rotation error above this: ill-conditioned
    wall_outlier_factor: float = 3.0  # a window whose corner RMS in its wall fit exceeds this x the median ...
    wall_outlier_px: float = 1.0  # ... and this (px) is split off into a wall of its own
    manhattan_deg: float = 8.0  # walls this close to k x 90 deg about a shared vertical are tied
    focal_max_rel_sd: float = 0.25  # a wall's focal estimate with larger relative sd is not used
    interval_level: float = 0.90  # the reported uncertainty intervals


TOL = Tolerances()
