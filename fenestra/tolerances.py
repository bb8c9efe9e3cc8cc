"""Numerical tolerances of Fenestra's checks and tests (units in the names), apart from the
algorithms' settings.

Tests in ``tests/`` compare against these; the benchmark uses the matching threshold and the
recall thresholds. An algorithm's own parameters live beside the algorithm (the per-wall fit's:
``pipeline.walls.settings.WALL_FIT``).
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
    all_corners_px: float = 5.0  # a window's quad is usable when all four corners are this close
    # `fenestra compare RUN_A RUN_B` (fenestra/reports/compare.py): a method regresses when a metric's
    # median over the windows paired in both runs gets worse by more than its tolerance AND the
    # paired Wilcoxon test gives p < compare_p_value. The tolerances are about 5-10 % of the CLI
    # method's medians on `make bench` (1.02 px, 1.9 %, 0.32 deg): below them, a change is noise to a user.
    compare_p_value: float = 0.01
    compare_corner_px: float = 0.05  # corner_err_px_snap
    compare_aspect_rel: float = 0.002  # aspect_err_rel (0.2 percentage points)
    compare_rot_deg: float = 0.02  # rot_err_deg
    # mask -> quad on thin windows (tests/pipeline/test_pipeline_quad.py): every corner of an exact
    # pixel-centre mask of a thin rectangle (10x60 .. 20x120 px, any rotation), and of a thin window
    # with corners rounded up to a third of its short side against its straight-sided truth
    thin_quad_exact_px: float = 0.5
    thin_quad_rounded_px: float = 1.5
    # quad source mask+lines (pipeline.quad.best_subset_quad): every corner of a window whose mask has
    # one corner notched off (30 % of both sides meeting there), against the whole window's truth
    notched_quad_px: float = 1.5
    # row regularization (pipeline.row_lines; its own agreement threshold, ROW_AGREE_FRACTION,
    # lives beside it): the exported whole windows of one export.json storey row that agreed with
    # their row's sill and head lines have heights within this share of their median (the target)
    row_height_spread_rel: float = 0.05
    # model.ifc's walls (pipeline.export.walls_plan): two fitted walls are one façade plane, and one
    # IfcWall, when their normals agree within facade_plane_deg and their planes' distances from the
    # camera within facade_plane_offset_rel of the nearer one (a setback of a neighbouring building
    # at 20 m is 0.6 m); otherwise each is a wall of its own, and two walls whose corner line the
    # photo shows meet there within corner_meet_m (tests/pipeline/test_ifc_walls.py, exact corner scene)
    facade_plane_deg: float = 3.0
    facade_plane_offset_rel: float = 0.03
    corner_meet_m: float = 0.01


TOL = Tolerances()
