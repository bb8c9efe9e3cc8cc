"""Aspect ratio (Zhang & He 2007) and pose (solvePnP) on exact synthetic quads.

Ground truth by construction: a known w x h rectangle, a known K and pose, projected with plain
pinhole algebra (renders.quad_image.view_window), independent of pipeline.aspect / pipeline.pose.
"""
import numpy as np
import pytest

from fenestra.conventions import make_K, rotation_error_deg
from fenestra.tolerances import TOL
from fenestra.pipeline.aspect import AspectError, aspect_ratio, classify, focal_from_quad
from fenestra.pipeline.pose import PoseError, estimate_pose
from fenestra.pipeline.poses import POSES
from quad_image import view_window

K = make_K(812.0, 805.0, 331.3, 238.9)


def random_views(n, seed, K=K):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        w, h = rng.uniform(0.4, 2.5), rng.uniform(0.6, 2.5)
        yield view_window(K, w, h, rng.uniform(-65, 65), rng.uniform(-45, 45), rng.uniform(-30, 30),
                          rng.uniform(2.0, 12.0), tuple(rng.uniform(-150, 150, 2)))


def expected_case(q):
    """Independent classification: count opposite side pairs closer than TOL.parallel_sides_deg."""
    def direction(a, b):
        return np.degrees(np.arctan2(b[1] - a[1], b[0] - a[0])) % 180.0

    def diff(x, y):
        d = abs(x - y) % 180.0
        return min(d, 180.0 - d)

    top_bottom = diff(direction(q[0], q[1]), direction(q[3], q[2]))
    left_right = diff(direction(q[0], q[3]), direction(q[1], q[2]))
    n = int(top_bottom < TOL.parallel_sides_deg) + int(left_right < TOL.parallel_sides_deg)
    return ["general", "one_pair_parallel", "fronto_parallel"][n]


def test_aspect_with_K_exact():
    for sw in random_views(40, seed=1):
        r = aspect_ratio(sw.corners_px, K)
        assert abs(r.ratio / (sw.width_m / sw.height_m) - 1) < TOL.exact_aspect_rel
        assert r.case == expected_case(sw.corners_px) and r.focal_source == "K"


@pytest.mark.parametrize("yaw, pitch, case", [(0.0, 0.0, "fronto_parallel"), (0.01, 0.0, "fronto_parallel"),
                                              (0.0, 25.0, "one_pair_parallel"), (30.0, 0.0, "one_pair_parallel"),
                                              (30.0, 0.5, "general")])
def test_near_degenerate_cases_with_K(yaw, pitch, case):
    # K with centred principal point so a yaw-only view keeps the vertical sides exactly parallel
    Kc = make_K(800.0, 800.0, 320.0, 240.0)
    sw = view_window(Kc, 1.1, 1.7, yaw, pitch, 0.0, 5.0)
    r = aspect_ratio(sw.corners_px, Kc)
    assert r.case == case
    assert abs(r.ratio / (1.1 / 1.7) - 1) < TOL.exact_aspect_rel


def test_unknown_focal_recovered():
    Kc = make_K(950.0, 950.0, 319.5, 239.5)
    for sw in random_views(30, seed=2, K=Kc):
        if classify(sw.corners_px) != "general":
            continue
        r = aspect_ratio(sw.corners_px, None, principal_point=(319.5, 239.5))
        assert r.focal_source == "estimated"
        assert abs(r.focal_px / 950.0 - 1) < 1e-6
        assert abs(r.ratio / (sw.width_m / sw.height_m) - 1) < TOL.exact_aspect_rel


def test_unknown_focal_degenerate_cases():
    Kc = make_K(900.0, 900.0, 320.0, 240.0)
    one_pair = view_window(Kc, 1.0, 1.5, 0.0, 20.0, 0.0, 5.0).corners_px
    assert focal_from_quad(one_pair, (320.0, 240.0)) is None
    with pytest.raises(AspectError, match="focal length undefined"):
        aspect_ratio(one_pair, None, principal_point=(320.0, 240.0))
    r = aspect_ratio(one_pair, None, principal_point=(320.0, 240.0), fallback_focal_px=900.0)
    assert r.focal_source == "fallback" and abs(r.ratio / (1.0 / 1.5) - 1) < 1e-9
    fronto = view_window(Kc, 1.0, 1.5, 0.0, 0.0, 7.0, 5.0).corners_px  # rolled, still fronto-parallel
    r = aspect_ratio(fronto, None, principal_point=(320.0, 240.0))
    assert r.case == "fronto_parallel" and abs(r.ratio / (1.0 / 1.5) - 1) < 1e-9


def test_aspect_bad_input():
    with pytest.raises(ValueError, match="shape"):
        aspect_ratio(np.zeros((3, 2)), K)
    with pytest.raises(ValueError, match="K must be 3x3"):
        aspect_ratio(np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]), np.eye(2))
    with pytest.raises(AspectError, match="collinear"):
        aspect_ratio(np.array([[0, 0], [1, 0], [2, 0], [0, 1.0]]), K)


@pytest.mark.parametrize("solver", POSES.where(per_wall=False))
def test_pose_exact(solver):
    for sw in random_views(30, seed=3):
        ratio = aspect_ratio(sw.corners_px, K).ratio
        p = estimate_pose(sw.corners_px, K, ratio, height_m=sw.height_m, solver=solver)
        assert rotation_error_deg(p.R, sw.R) < TOL.exact_rotation_deg
        assert np.linalg.norm(p.t - sw.t) < 1e-6 * np.linalg.norm(sw.t)
        assert np.abs(p.reprojected - sw.corners_px).max() < 1e-4 and p.rms_px < 1e-4


def test_pose_scale_by_width_and_default_height():
    sw = next(random_views(1, seed=4))
    ratio = sw.width_m / sw.height_m
    by_w = estimate_pose(sw.corners_px, K, ratio, width_m=sw.width_m)
    assert abs(by_w.height_m - sw.height_m) < 1e-9 and np.allclose(by_w.t, sw.t, atol=1e-6)
    unit = estimate_pose(sw.corners_px, K, ratio)  # h = 1 m: same rotation, t scaled by 1/h
    assert rotation_error_deg(unit.R, sw.R) < TOL.exact_rotation_deg
    assert np.allclose(unit.t * sw.height_m, sw.t, atol=1e-6)


def test_pose_bad_input():
    sw = next(random_views(1, seed=5))
    with pytest.raises(ValueError, match="unknown pose strategy 'epnp'"):
        estimate_pose(sw.corners_px, K, 1.0, solver="epnp")
    with pytest.raises(ValueError, match="aspect ratio must be positive"):
        estimate_pose(sw.corners_px, K, -1.0)
    with pytest.raises(PoseError):  # corners mirrored: the window would face away from the camera
        estimate_pose(sw.corners_px[::-1], K, sw.width_m / sw.height_m, solver="lm")


def test_aspect_rejects_quad_with_coincident_corners():
    from fenestra.pipeline.aspect import AspectError, aspect_ratio

    quad = np.array([[10.0, 10.0], [10.0, 10.0], [50.0, 60.0], [10.0, 60.0]])
    with pytest.raises(AspectError, match="coincide"):
        aspect_ratio(quad, K=np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]))


def test_aspect_cross_is_numpy_cross_bit_for_bit():
    """Zhang & He's cross products (pipeline.aspect._cross, plain float arithmetic) are np.cross's
    exactly: the same products and differences in the same order, over magnitudes 1e-3..1e3."""
    from fenestra.pipeline.aspect import _cross  # noqa: PLC0415

    rng = np.random.default_rng(4)
    for _ in range(5000):
        a, b = (rng.normal(size=3) * 10.0 ** rng.uniform(-3, 3) for _ in range(2))
        assert _cross(a, b).tobytes() == np.cross(a, b).tobytes()
