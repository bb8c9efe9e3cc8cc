"""Façade geometry (pipeline/facade.py, pipeline/walls.py) on synthetic walls with known answers.

Ground truth by construction: window rectangles on known world planes, a camera from
fenestra.conventions.look_at, corners projected with conventions.project (plain pinhole algebra,
independent of the code under test). The true window-frame rotation of a wall whose windows run
along world direction ``ex`` with world z up is R_cam @ [ex, z, ex x z].
"""
import numpy as np
import pytest

from fenestra.conventions import TOL, look_at, make_K, project, rotation_error_deg
from pipeline import facade, walls
from pipeline.types import WindowResult

K = make_K(820.0, 820.0, 319.5, 239.5)
SHAPE = (480, 640)  # H, W
UP = np.array([0.0, 0.0, 1.0])


def wall_windows(origin, ex, spots):
    """World corners (N, 4, 3) TL TR BR BL of windows (x0, z0, w, h) on the vertical plane through
    ``origin`` spanned by unit ``ex`` and world z (outward normal ex x z)."""
    origin, ex = np.asarray(origin, float), np.asarray(ex, float)
    out = []
    for x0, z0, w, h in spots:
        bl = origin + x0 * ex + z0 * UP
        out.append([bl + h * UP, bl + w * ex + h * UP, bl + w * ex, bl])
    return np.array(out)


def true_R(R_cam, ex):
    ex = np.asarray(ex, float)
    return R_cam @ np.stack([ex, UP, np.cross(ex, UP)], axis=1)


FRONT = [(-2.0, 1.0, 1.0, 1.3), (0.0, 1.0, 0.8, 1.3), (1.8, 1.0, 1.2, 1.0), (-2.0, 3.6, 1.0, 1.2),
         (0.2, 3.6, 0.6, 0.6)]
SIDE = [(0.8, 1.0, 0.9, 1.2), (2.4, 1.0, 0.9, 1.2), (1.2, 3.5, 1.4, 1.0)]
EX_FRONT, EX_SIDE = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


def scene():
    """Camera seeing a house corner: the front wall (y = 0, windows along +x, facing -y) and the
    side wall (x = 3.5, along +y, facing +x). Returns R, t, quads (N, 4, 2), labels (N,), windows."""
    R, t = look_at(np.array([8.0, -7.0, 1.7]), np.array([1.5, 1.0, 2.3]))
    front = wall_windows([0.0, 0.0, 0.0], EX_FRONT, FRONT)
    side = wall_windows([3.5, 0.0, 0.0], EX_SIDE, SIDE)
    C = np.concatenate([front, side])
    quads = np.array([project(K, R, t, c) for c in C])
    return R, t, quads, np.array([0] * len(front) + [1] * len(side)), C


def test_vanishing_direction_is_the_walls_horizontal():
    R, _, quads, labels, _ = scene()
    for lab, ex in ((0, EX_FRONT), (1, EX_SIDE)):
        seg = facade.side_segments(quads[labels == lab], facade.H_SIDES)
        d = facade.orient(facade.vanishing_direction(facade.edge_normals(seg, K)), seg, K)
        np.testing.assert_allclose(d, R @ ex, atol=1e-9)
        segv = facade.side_segments(quads[labels == lab], facade.V_SIDES)
        dv = facade.orient(facade.vanishing_direction(facade.edge_normals(segv, K)), segv, K)
        np.testing.assert_allclose(dv, R @ UP, atol=1e-9)


def test_vanishing_direction_at_infinity():
    """A fronto-parallel wall: its horizontal sides are parallel in the image (VP at infinity)."""
    R, t = look_at(np.array([0.5, -8.0, 2.0]), np.array([0.5, 0.0, 2.0]))
    C = wall_windows([0.0, 0.0, 0.0], EX_FRONT, FRONT[:3])
    quads = np.array([project(K, R, t, c) for c in C])
    seg = facade.side_segments(quads, facade.H_SIDES)
    d = facade.orient(facade.vanishing_direction(facade.edge_normals(seg, K)), seg, K)
    np.testing.assert_allclose(d, [1.0, 0.0, 0.0], atol=1e-9)
    assert facade.focal_from_vanishing(d, R @ UP, K) is None


def test_group_walls_separates_the_two_walls_under_noise():
    _, _, quads, labels, _ = scene()
    rng = np.random.default_rng(3)
    noisy = quads + rng.normal(0.0, 0.3, quads.shape)
    groups = facade.group_walls(noisy, K)
    found = sorted(sorted(g.members) for g in groups)
    expected = sorted(sorted(np.flatnonzero(labels == lab).tolist()) for lab in (0, 1))
    assert found == expected


def test_focal_from_vanishing_exact():
    R, _, quads, labels, _ = scene()
    K0 = walls.pseudo_K(SHAPE, 500.0)  # wrong focal, right principal point
    d_h, d_v = facade.fit_vps(quads, np.flatnonzero(labels == 0).tolist(), K0)
    f = facade.focal_from_vanishing(d_h, d_v, K0)
    assert f == pytest.approx(820.0, rel=1e-9)


def test_focal_from_walls_with_noise_within_its_sd():
    _, _, quads, _, _ = scene()
    rng = np.random.default_rng(5)
    f, sd = walls.focal_from_walls(quads + rng.normal(0.0, 0.2, quads.shape), SHAPE)
    assert abs(f - 820.0) < 3 * sd and abs(f - 820.0) < 0.05 * 820.0


def test_joint_rotation_exact_and_better_than_single_windows():
    R, t, quads, labels, C = scene()
    members = np.flatnonzero(labels == 0)
    R_gt = true_R(R, EX_FRONT)
    g = facade.group_walls(quads, K)[0]
    fit = facade.refine_walls(quads[members], K, facade.initial_rotation(g.d_h, g.d_v))
    assert rotation_error_deg(fit.R[0], R_gt) < TOL.exact_rotation_deg
    widths = np.linalg.norm(C[members, 1] - C[members, 0], axis=1)
    heights = np.linalg.norm(C[members, 0] - C[members, 3], axis=1)
    np.testing.assert_allclose(fit.width / fit.height, widths / heights, rtol=1e-8)
    # with corner noise, the shared rotation beats the windows fitted one by one
    rng = np.random.default_rng(11)
    joint, single = [], []
    for _ in range(8):
        q = quads[members] + rng.normal(0.0, 0.5, (len(members), 4, 2))
        R0 = facade.initial_rotation(*facade.fit_vps(q, list(range(len(q))), K))
        joint.append(rotation_error_deg(facade.refine_walls(q, K, R0).R[0], R_gt))
        for k in range(len(q)):
            Rk = facade.initial_rotation(*facade.fit_vps(q, [k], K))
            single.append(rotation_error_deg(facade.refine_walls(q[k:k + 1], K, Rk).R[0], R_gt))
    assert np.median(joint) < 0.5 * np.median(single)


def test_covariance_matches_monte_carlo():
    R, _, quads, labels, _ = scene()
    q0 = quads[labels == 0]
    sigma = 0.4
    R0 = facade.initial_rotation(*facade.fit_vps(q0, list(range(len(q0))), K))
    ref = facade.refine_walls(q0, K, R0, sigma_px=sigma, prior_dof=np.inf)
    rng = np.random.default_rng(7)
    widths, rotvecs = [], []
    for _ in range(150):
        fit = facade.refine_walls(q0 + rng.normal(0.0, sigma, q0.shape), K, ref.R[0])
        widths.append(fit.width)
        dR = fit.R[0] @ ref.R[0].T
        rotvecs.append(np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / 2.0)
    sd_w_mc = np.std(widths, axis=0)
    sd_w = np.sqrt([ref.cov[ref.window_block(i), ref.window_block(i)][3, 3] for i in range(len(q0))])
    np.testing.assert_allclose(sd_w, sd_w_mc, rtol=0.2)  # 150 draws: ~6 % sampling error
    np.testing.assert_allclose(np.sqrt(np.diag(ref.cov[:3, :3])), np.std(rotvecs, axis=0), rtol=0.2)


def _results(quads):
    return [WindowResult(i, 1.0, q, q, None, "general", None, None, None, 1.0, None, None)
            for i, q in enumerate(quads)]


def test_intervals_cover_about_90_percent():
    R, _, quads, labels, C = scene()
    a_gt = np.linalg.norm(C[:, 1] - C[:, 0], axis=1) / np.linalg.norm(C[:, 0] - C[:, 3], axis=1)
    rng = np.random.default_rng(13)
    params = walls.WallParams(sigma_px=0.5, prior_dof=np.inf)  # the true corner sigma
    hits_a, hits_r = [], []
    for _ in range(30):
        out = walls.apply_walls(_results(quads + rng.normal(0.0, 0.5, quads.shape)), K, SHAPE, 1.0, None, params)
        for r, a, lab in zip(out, a_gt, labels):
            hits_a.append(r.uncertainty["aspect_lo"] <= a <= r.uncertainty["aspect_hi"])
            err = rotation_error_deg(r.R, true_R(R, EX_FRONT if lab == 0 else EX_SIDE))
            hits_r.append(err <= r.uncertainty["rot_deg"])
    assert 0.85 <= np.mean(hits_a) <= 0.95
    assert 0.83 <= np.mean(hits_r) <= 0.97  # one rotation per wall: fewer independent draws


def test_apply_walls_without_K_estimates_focal_and_poses():
    R, _, quads, labels, _ = scene()
    out = walls.apply_walls(_results(quads), None, SHAPE, 1.0, None, walls.WallParams())
    assert {r.wall for r in out} == {0, 1}
    for r, lab in zip(out, labels):
        assert r.failure is None and r.focal_estimate_px == pytest.approx(820.0, rel=1e-6)
        assert rotation_error_deg(r.R, true_R(R, EX_FRONT if lab == 0 else EX_SIDE)) < 1e-4


def test_apply_walls_without_K_fails_cleanly_when_unobservable():
    R, t = look_at(np.array([0.5, -8.0, 2.0]), np.array([0.5, 0.0, 2.0]))  # fronto-parallel
    quads = np.array([project(K, R, t, c) for c in wall_windows([0, 0, 0], EX_FRONT, FRONT[:3])])
    out = walls.apply_walls(_results(quads), None, SHAPE, 1.0, None, walls.WallParams())
    assert all(r.failure and "focal length unobservable" in r.failure and r.R is None for r in out)


def test_ill_conditioned_flag_small_window_not_large_one():
    """0.5 px corner noise: an ~80 px window's aspect is only known to ~ +-9 % (flagged), a
    350 px one's to < 1 % (not flagged)."""
    params = walls.WallParams(sigma_px=0.5, prior_dof=np.inf)
    cases = (((6.0, -9.0, 1.7), (-3.0, 1.0, 1.5, 1.5), True), ((3.0, -5.0, 1.7), (-0.5, 0.5, 2.5, 2.5), False))
    for eye, spot, flagged in cases:
        R, t = look_at(np.array(eye), np.array([1.0, 0.0, 2.0]))
        q = project(K, R, t, wall_windows([0, 0, 0], EX_FRONT, [spot])[0])[None]
        q = q + np.random.default_rng(1).normal(0, 0.5, q.shape)
        r = walls.apply_walls(_results(q), K, SHAPE, 1.0, None, params)[0]
        assert r.uncertainty["ill_conditioned"] is flagged
        assert (r.aspect_case == "ill_conditioned") is flagged


def test_wall_jacobian_matches_finite_differences():
    from scipy.optimize._numdiff import approx_derivative

    _, _, quads, labels, _ = scene()
    R0 = np.array([facade.initial_rotation(*facade.fit_vps(quads, list(np.flatnonzero(labels == g)), K))
                   for g in (0, 1)])
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.normal(0, 0.1, 6), rng.normal(0, 1, 4 * len(quads)) + np.tile([0, 0, 10, 1], len(quads)),
                        [800.0]])

    def residuals(x):
        R, t, w, Kx = facade._unpack(x, 2, len(quads), R0, K, True)
        return (facade.project_wall(R[labels], t, w, 1.0, Kx) - quads).ravel()

    J = facade.wall_jacobian(x, 2, labels, R0, K, 1.0, True)
    np.testing.assert_allclose(J, approx_derivative(residuals, x, method="3-point"), atol=1e-6 * np.abs(J).max())


def test_tie_walls_right_angles_only():
    R, _, _, _, _ = scene()
    front, side = true_R(R, EX_FRONT), true_R(R, EX_SIDE)
    oblique = true_R(R, np.array([np.cos(np.radians(45)), np.sin(np.radians(45)), 0.0]))
    group, Q = facade.tie_walls(np.array([front, side, oblique]))
    assert group.tolist() == [0, 0, 1]
    np.testing.assert_allclose(front @ Q[1], side, atol=1e-12)


def test_building_shares_one_rotation_across_walls():
    """Two walls at right angles: 'building' fits one rotation for both (exact on exact quads) and,
    under noise, beats one rotation per wall on the same draws."""
    R, _, quads, labels, _ = scene()
    truth = [true_R(R, EX_FRONT if lab == 0 else EX_SIDE) for lab in labels]
    exact = walls.apply_walls(_results(quads), K, SHAPE, 1.0, None, walls.WALL_STRATEGIES["building"])
    assert max(rotation_error_deg(r.R, g) for r, g in zip(exact, truth)) < TOL.exact_rotation_deg
    rng = np.random.default_rng(17)
    err = {"wall": [], "building": []}
    for _ in range(10):
        res = _results(quads + rng.normal(0.0, 0.5, quads.shape))
        for name in err:
            out = walls.apply_walls(res, K, SHAPE, 1.0, None, walls.WALL_STRATEGIES[name])
            err[name] += [rotation_error_deg(r.R, g) for r, g in zip(out, truth)]
    assert np.median(err["building"]) < 0.8 * np.median(err["wall"])
