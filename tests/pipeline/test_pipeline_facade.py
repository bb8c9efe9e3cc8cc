"""Per-wall geometry (fenestra/pipeline/walls/, fenestra/pipeline/segments.py) on synthetic walls with known answers.

Ground truth by construction: window rectangles on known world planes, a camera from
fenestra.conventions.look_at, corners projected with conventions.project (plain pinhole algebra,
independent of the code under test). The true window-frame rotation of a wall whose windows run
along world direction ``ex`` with world z up is R_cam @ [ex, z, ex x z].
"""
from dataclasses import replace

import cv2
import numpy as np
import pytest

from fenestra.conventions import look_at, make_K, project, rotation_error_deg
from fenestra.tolerances import TOL
from fenestra.pipeline.segments import SegmentCache, detect_segments
from fenestra.pipeline.walls import WALL_FIT
from fenestra.pipeline.walls import fit as wallfit
from fenestra.pipeline.walls import lines as facade_lines
from fenestra.pipeline.walls import strategies as walls
from fenestra.pipeline.walls import vanishing
from fenestra.pipeline.types import WindowResult

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
        seg = vanishing.side_segments(quads[labels == lab], vanishing.H_SIDES)
        d = vanishing.orient(vanishing.vanishing_direction(vanishing.edge_normals(seg, K)), seg, K)
        np.testing.assert_allclose(d, R @ ex, atol=1e-9)
        segv = vanishing.side_segments(quads[labels == lab], vanishing.V_SIDES)
        dv = vanishing.orient(vanishing.vanishing_direction(vanishing.edge_normals(segv, K)), segv, K)
        np.testing.assert_allclose(dv, R @ UP, atol=1e-9)


def test_vanishing_direction_at_infinity():
    """A fronto-parallel wall: its horizontal sides are parallel in the image (VP at infinity)."""
    R, t = look_at(np.array([0.5, -8.0, 2.0]), np.array([0.5, 0.0, 2.0]))
    C = wall_windows([0.0, 0.0, 0.0], EX_FRONT, FRONT[:3])
    quads = np.array([project(K, R, t, c) for c in C])
    seg = vanishing.side_segments(quads, vanishing.H_SIDES)
    d = vanishing.orient(vanishing.vanishing_direction(vanishing.edge_normals(seg, K)), seg, K)
    np.testing.assert_allclose(d, [1.0, 0.0, 0.0], atol=1e-9)
    assert vanishing.focal_from_vanishing(d, R @ UP, K) is None


def test_group_walls_separates_the_two_walls_under_noise():
    _, _, quads, labels, _ = scene()
    rng = np.random.default_rng(3)
    noisy = quads + rng.normal(0.0, 0.3, quads.shape)
    groups = vanishing.group_walls(noisy, K)
    found = sorted(sorted(g.members) for g in groups)
    expected = sorted(sorted(np.flatnonzero(labels == lab).tolist()) for lab in (0, 1))
    assert found == expected


def test_focal_from_vanishing_exact():
    R, _, quads, labels, _ = scene()
    K0 = walls.pseudo_K(SHAPE, 500.0)  # wrong focal, right principal point
    d_h, d_v = vanishing.fit_vps(quads, np.flatnonzero(labels == 0).tolist(), K0)
    f = vanishing.focal_from_vanishing(d_h, d_v, K0)
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
    g = vanishing.group_walls(quads, K)[0]
    fit = wallfit.refine_walls(quads[members], K, vanishing.initial_rotation(g.d_h, g.d_v))
    assert rotation_error_deg(fit.R[0], R_gt) < TOL.exact_rotation_deg
    widths = np.linalg.norm(C[members, 1] - C[members, 0], axis=1)
    heights = np.linalg.norm(C[members, 0] - C[members, 3], axis=1)
    np.testing.assert_allclose(fit.width / fit.height, widths / heights, rtol=1e-8)
    # with corner noise, the shared rotation beats the windows fitted one by one
    rng = np.random.default_rng(11)
    joint, single = [], []
    for _ in range(8):
        q = quads[members] + rng.normal(0.0, 0.5, (len(members), 4, 2))
        R0 = vanishing.initial_rotation(*vanishing.fit_vps(q, list(range(len(q))), K))
        joint.append(rotation_error_deg(wallfit.refine_walls(q, K, R0).R[0], R_gt))
        for k in range(len(q)):
            Rk = vanishing.initial_rotation(*vanishing.fit_vps(q, [k], K))
            single.append(rotation_error_deg(wallfit.refine_walls(q[k:k + 1], K, Rk).R[0], R_gt))
    assert np.median(joint) < 0.5 * np.median(single)


def test_covariance_matches_monte_carlo():
    R, _, quads, labels, _ = scene()
    q0 = quads[labels == 0]
    sigma = 0.4
    R0 = vanishing.initial_rotation(*vanishing.fit_vps(q0, list(range(len(q0))), K))
    ref = wallfit.refine_walls(q0, K, R0, sigma_px=sigma, prior_dof=np.inf)
    rng = np.random.default_rng(7)
    widths, rotvecs = [], []
    for _ in range(150):
        fit = wallfit.refine_walls(q0 + rng.normal(0.0, sigma, q0.shape), K, ref.R[0])
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
            hits_a.append(r.uncertainty.aspect_lo <= a <= r.uncertainty.aspect_hi)
            err = rotation_error_deg(r.R, true_R(R, EX_FRONT if lab == 0 else EX_SIDE))
            hits_r.append(err <= r.uncertainty.rot_deg)
    assert 0.85 <= np.mean(hits_a) <= 0.95
    assert 0.83 <= np.mean(hits_r) <= 0.97  # one rotation per wall: fewer independent draws


def test_apply_walls_without_K_estimates_focal_and_poses():
    R, _, quads, labels, _ = scene()
    out = walls.apply_walls(_results(quads), None, SHAPE, 1.0, None, walls.WallParams())
    assert {r.group for r in out} == {0, 1}
    for r, lab in zip(out, labels):
        assert r.failure is None and r.focal_estimate_px == pytest.approx(820.0, rel=1e-6)
        assert rotation_error_deg(r.R, true_R(R, EX_FRONT if lab == 0 else EX_SIDE)) < 1e-4


def test_apply_walls_without_K_fails_cleanly_when_unobservable():
    R, t = look_at(np.array([0.5, -8.0, 2.0]), np.array([0.5, 0.0, 2.0]))  # fronto-parallel
    quads = np.array([project(K, R, t, c) for c in wall_windows([0, 0, 0], EX_FRONT, FRONT[:3])])
    base = [replace(r, focal_estimate_px=700.0) for r in _results(quads)]  # a per-window (Zhang & He) f
    out = walls.apply_walls(base, None, SHAPE, 1.0, None, walls.WallParams())
    assert all(r.failure and r.failure.stage == "wall" and "focal length unobservable" in r.failure.reason
               and r.R is None for r in out)
    assert all(r.focal_estimate_px is None for r in out)  # the bench must not count the per-window f


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
        assert r.uncertainty.ill_conditioned is flagged
        assert (r.aspect_case == "ill_conditioned") is flagged


def test_wall_jacobian_matches_finite_differences():
    from scipy.optimize._numdiff import approx_derivative

    _, _, quads, labels, _ = scene()
    R0 = np.array([vanishing.initial_rotation(*vanishing.fit_vps(quads, list(np.flatnonzero(labels == g)), K))
                   for g in (0, 1)])
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.normal(0, 0.1, 6), rng.normal(0, 1, 4 * len(quads)) + np.tile([0, 0, 10, 1], len(quads)),
                        [800.0]])

    def residuals(x):
        R, t, w, Kx = wallfit._unpack(x, 2, len(quads), R0, K, True)
        return (wallfit.project_wall(R[labels], t, w, 1.0, Kx) - quads).ravel()

    J = wallfit.wall_jacobian(x, 2, labels, R0, K, 1.0, True)
    np.testing.assert_allclose(J, approx_derivative(residuals, x, method="3-point"), atol=1e-6 * np.abs(J).max())


def test_tie_walls_right_angles_only():
    R, _, _, _, _ = scene()
    front, side = true_R(R, EX_FRONT), true_R(R, EX_SIDE)
    oblique = true_R(R, np.array([np.cos(np.radians(45)), np.sin(np.radians(45)), 0.0]))
    group, Q = vanishing.tie_walls(np.array([front, side, oblique]))
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


# ------------------------------------------------------------------ façade lines

WALL_EDGES = {  # world segments on the two walls of scene(): (start, end), and which axis they follow
    "front": ([[-3.0, 0.0, 0.0], [3.5, 0.0, 0.0]], 0), "front_top": ([[-3.0, 0.0, 5.5], [3.5, 0.0, 5.5]], 0),
    "corner": ([[3.5, 0.0, 0.0], [3.5, 0.0, 5.5]], 1), "front_left": ([[-3.0, 0.0, 0.0], [-3.0, 0.0, 5.5]], 1),
    "side": ([[3.5, 0.0, 0.0], [3.5, 4.0, 0.0]], 0), "side_right": ([[3.5, 4.0, 0.0], [3.5, 4.0, 5.5]], 1),
}


def draw_scene(R, t, quads):
    """Gray image (480, 640) uint8 of scene(): the front wall (150), the side wall (110), the
    windows (40) on a light background, edges antialiased at 1/16 px."""
    img = np.full(SHAPE, 200, np.uint8)

    def fill(p, value):
        cv2.fillPoly(img, [np.round(np.asarray(p) * 16).astype(np.int32)], int(value), cv2.LINE_AA, shift=4)

    fill(project(K, R, t, np.array([[-3, 0, 0], [3.5, 0, 0], [3.5, 0, 5.5], [-3, 0, 5.5]], float)), 150)
    fill(project(K, R, t, np.array([[3.5, 0, 0], [3.5, 4, 0], [3.5, 4, 5.5], [3.5, 0, 5.5]], float)), 110)
    for q in quads:
        fill(q, 40)
    return img


def edge_segments(R, t, names):
    """Image segments (M, 2, 2) px of WALL_EDGES ``names`` (shortened by 5 % at each end)."""
    out = []
    for n in names:
        a, b = np.array(WALL_EDGES[n][0])
        out.append(project(K, R, t, np.array([a + 0.05 * (b - a), b - 0.05 * (b - a)])))
    return np.array(out)


def drawn_edge() -> tuple[np.ndarray, np.ndarray]:
    """A gray uint8 image (H, W) with a step edge along the line n . (x, y) = -150, n = (0.28, -0.96)
    (drawn by 8 x 8 supersampling, pixel centres at integers), and n."""
    n = np.array([0.28, -0.96])
    ss = 8
    yy, xx = np.mgrid[0:SHAPE[0] * ss, 0:SHAPE[1] * ss]
    inside = (n[0] * ((xx + 0.5) / ss - 0.5) + n[1] * ((yy + 0.5) / ss - 0.5)) > -150.0
    return (40 + 160 * inside.reshape(SHAPE[0], ss, SHAPE[1], ss).mean(axis=(1, 3))).round().astype(np.uint8), n


@pytest.mark.parametrize("scale", [WALL_FIT.lsd_scale, 1.0])
def test_detect_segments_on_a_drawn_edge(scale):
    """LSD at the walls' scale and the snapper's: a segment lies on the drawn edge within 0.3 px at
    both ends; the cache gives the same, and nothing shorter than the minimum length."""
    img, n = drawn_edge()
    seg = detect_segments(img, scale)
    assert seg.shape[1:] == (2, 2) and seg.dtype == np.float64 and len(seg) >= 1
    longest = seg[np.argmax(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1))]
    assert np.linalg.norm(longest[1] - longest[0]) > 300.0
    assert np.all(np.abs(longest @ n + 150.0) < 0.3)
    cache = SegmentCache(img.astype(np.float32))  # as reconstruct.to_gray gives it
    long_ones = cache.segments(scale, 100.0)
    assert len(long_ones) >= 1 and np.all(np.linalg.norm(long_ones[:, 1] - long_ones[:, 0], axis=1) >= 100.0)
    assert np.array_equal(long_ones, seg[np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) >= 100.0])
    assert len(cache.segments(scale, 2000.0)) == 0


def test_detect_segments_in_a_crop_are_in_image_coordinates():
    """A box around part of the edge: its segments lie on the same line in full-image pixels, and
    within the box."""
    img, n = drawn_edge()
    box = (200, 150, 420, 330)
    seg = detect_segments(img, 1.0, box)
    assert len(seg) >= 1
    assert np.all(np.abs(seg @ n + 150.0) < 0.3)
    assert np.all((seg[..., 0] >= box[0] - 0.5) & (seg[..., 0] <= box[2] - 0.5))
    assert np.all((seg[..., 1] >= box[1] - 0.5) & (seg[..., 1] <= box[3] - 0.5))


def test_detect_segments_rejects_bad_input():
    with pytest.raises(ValueError, match="uint8 or float"):
        detect_segments(np.zeros((*SHAPE, 3), np.uint8), 1.0)
    with pytest.raises(ValueError, match="uint8 or float"):
        SegmentCache(np.zeros(SHAPE, np.int32))


def test_segment_cache_runs_the_detector_once_per_scale(monkeypatch):
    """One photo's cache asked again (another minimum length too) runs the detector once per
    scale; what it returns is the caller's (changing it leaves the kept segments). The counter
    wraps the real detector."""
    import fenestra.pipeline.segments as segments_module  # noqa: PLC0415

    calls = []
    real = segments_module.detect_segments

    def counted(gray, scale, box=None):
        calls.append(scale)
        return real(gray, scale, box)

    monkeypatch.setattr(segments_module, "detect_segments", counted)
    img = np.full(SHAPE, 60, np.uint8)
    img[:, SHAPE[1] // 2:] = 200  # one vertical step edge
    cache = SegmentCache(img)
    a = cache.segments(0.8, 100.0)
    b = cache.segments(0.8, 100.0)
    assert calls == [0.8] and len(a) >= 1 and np.array_equal(a, b)
    a[:] = 0
    assert np.array_equal(cache.segments(0.8, 100.0), b) and len(cache.segments(0.8, 50.0)) >= len(b)
    cache.segments(1.0)
    assert calls == [0.8, 1.0]


def test_segment_families_follow_the_walls_vanishing_points():
    """Front-wall edges go to its horizontal (0) or vertical (1) vanishing point; a side-wall
    horizontal and a roof rake (45 deg on the front wall) follow neither (-1)."""
    R, t, quads, labels, _ = scene()
    d_h, d_v = vanishing.fit_vps(quads, np.flatnonzero(labels == 0).tolist(), K)
    names = ["front", "front_top", "corner", "front_left", "side"]
    rake = project(K, R, t, np.array([[-3.0, 0.0, 5.5], [0.25, 0.0, 8.75]]))[None]
    seg = np.concatenate([edge_segments(R, t, names), rake])
    fam = facade_lines.segment_families(seg, d_h, d_v, K, 0.5, 0.5)
    assert fam.tolist() == [0, 0, 1, 1, -1, -1]
    # direction-free: a segment given end to start is the same line
    np.testing.assert_array_equal(facade_lines.segment_families(seg[:, ::-1], d_h, d_v, K, 0.5, 0.5), fam)


def test_wall_segments_keep_the_walls_own_lines():
    """Of the photo's segments, a wall keeps those near its windows' hull that follow its
    vanishing points, and its vanishing points then come from its sides and those segments."""
    R, t, quads, labels, _ = scene()
    front = np.flatnonzero(labels == 0).tolist()
    rake = project(K, R, t, np.array([[-3.0, 0.0, 5.5], [-1.0, 0.0, 7.5]]))[None]
    seg = np.concatenate([edge_segments(R, t, ["front", "corner", "side_right", "front_left"]), rake])
    # midpoints 83, 76, 201 and 39 px off the hull of the front windows (median size 64 px)
    params = walls.WallParams(lines=True, line_margin=2.0)
    (kept, fam), vp = facade_lines.wall_segments(seg, quads, front, K, params)
    np.testing.assert_allclose(kept, seg[[0, 1, 3, 4]])  # side_right is beyond the front wall's windows
    assert fam.tolist() == [0, 1, 1, -1]
    np.testing.assert_allclose(vp, (R @ EX_FRONT, R @ UP), atol=1e-9)
    noisy = quads + np.random.default_rng(0).normal(0.0, 1.0, quads.shape)
    (_, fam), vp = facade_lines.wall_segments(seg, noisy, front, K, params)
    assert fam.tolist() == [0, 1, 1, -1]

    def err(vp):
        return max(np.degrees(np.arccos(min(abs(d @ g), 1.0))) for d, g in zip(vp, (R @ EX_FRONT, R @ UP)))

    assert err(vp) < 0.25 * err(vanishing.fit_vps(noisy, front, K))  # measured 0.16 deg vs 2.4 deg


def test_facade_segments_per_photo_values_are_the_per_subset_ones():
    """FacadeSegments computes each segment's normal, weight, threshold and angle once per photo
    and hands out rows of them: that is only exact because every one of these is row-wise, the
    value of a row the same bit for bit whatever other rows are computed with it (subsets of 1 to
    M rows here, as the walls take them)."""
    rng = np.random.default_rng(7)
    seg = rng.uniform(0.0, 640.0, (60, 2, 2))
    fs = facade_lines.FacadeSegments(seg)
    vp = K @ np.array([0.3, -0.1, 0.9])
    for n in (1, 2, 3, 5, 8, 13, 30, 59, 60):
        idx = np.sort(rng.choice(len(seg), n, replace=False))
        s = seg[idx]
        assert np.array_equal(fs.normals(K, idx), vanishing.edge_normals(s, K))
        assert np.array_equal(fs.weights(0.5)[idx], vanishing.segment_weights(s, 0.5))
        assert np.array_equal(fs.thresholds(0.5, 8.0)[idx], vanishing.side_thresholds_deg(s, 0.5, 8.0))
        assert np.array_equal(vanishing.angles_to_vp(fs.mid_h[idx], fs.e[idx], fs.length[idx], vp),
                              vanishing.side_angles_to_vp(s, vp))
    with pytest.raises(ValueError):
        fs.segments[0, 0, 0] = 1.0  # handed out read-only
    flat = facade_lines.FacadeSegments(np.array([[[5.0, 5.0], [5.0, 5.0]], [[0.0, 0.0], [30.0, 0.0]]]))
    assert np.all(np.isfinite(flat.normals(K, np.array([1]))))
    with pytest.raises(vanishing.FacadeError, match="degenerate"):
        flat.normals(K, np.array([0, 1]))


def test_group_walls_gives_each_wall_its_fit_vps():
    """group_walls' vanishing directions per wall are fit_vps' of its windows, bit for bit (it
    takes them from the sides it already has: per-side values are row-wise), noisy quads too."""
    R, t, quads, labels, _ = scene()
    for noise in (0.0, 1.5):
        q = quads + np.random.default_rng(3).normal(0.0, noise, quads.shape)
        found = vanishing.group_walls(q, K, 0.7)
        assert len(found) >= 2
        for w in found:
            d_h, d_v = vanishing.fit_vps(q, list(w.members), K, 0.7)
            assert np.array_equal(w.d_h, d_h) and np.array_equal(w.d_v, d_v)


def test_wall_segments_are_made_once_per_photo_and_wall():
    """Through the photo's FacadeSegments (photo_segments keeps one per SegmentCache), a wall's
    segments and vanishing points are those of the plain array, made once per distinct wall,
    K and parameters."""
    R, t, quads, labels, _ = scene()
    front = np.flatnonzero(labels == 0).tolist()
    seg = edge_segments(R, t, ["front", "corner", "side_right", "front_left"])
    params = walls.WallParams(lines=True, line_margin=2.0)
    fs = facade_lines.FacadeSegments(seg)
    plain = facade_lines.wall_segments(seg, quads, front, K, params)
    shared = facade_lines.wall_segments(fs, quads, front, K, params)
    for a, b in zip((*plain[0], *plain[1]), (*shared[0], *shared[1])):
        assert np.array_equal(a, b)
    assert facade_lines.wall_segments(fs, quads.copy(), list(front), K.copy(), replace(params, manhattan=False)) is shared
    other = facade_lines.wall_segments(fs, quads, front, K, replace(params, line_refit_deg=2.0))
    assert other is not shared
    K2 = make_K(700.0, 700.0, 319.5, 239.5)
    assert facade_lines.wall_segments(fs, quads, front, K2, params) is not shared
    for a, b in zip(facade_lines.wall_vps(quads, K2, [vanishing.WallVP(None, None, tuple(front))], params, fs)[0][0],
                    facade_lines.wall_vps(quads, K2, [vanishing.WallVP(None, None, tuple(front))], params, seg)[0][0]):
        assert np.array_equal(a, b)
    cache = SegmentCache(np.zeros(SHAPE, np.uint8))
    got = facade_lines.photo_segments(cache, params, SHAPE)
    assert got is facade_lines.photo_segments(cache, replace(params, manhattan=False), SHAPE)
    assert got is not facade_lines.photo_segments(cache, replace(params, line_min_px=40.0), SHAPE)


def test_vanishing_points_from_lines_and_quads():
    """Exact façade lines pin the vanishing directions: exact with exact quads, and with 1 px
    corner noise on a single window far closer than the window alone."""
    R, t, quads, labels, _ = scene()
    lines = (edge_segments(R, t, ["front", "front_top"]), edge_segments(R, t, ["corner", "front_left"]))
    d_h, d_v = vanishing.fit_vps(quads, [0], K, lines=lines, line_sigma_px=0.5)
    np.testing.assert_allclose(d_h, R @ EX_FRONT, atol=1e-9)
    np.testing.assert_allclose(d_v, R @ UP, atol=1e-9)
    rng = np.random.default_rng(2)
    err_q, err_l = [], []
    for _ in range(20):
        q = quads + rng.normal(0.0, 1.0, quads.shape)
        for fit, err in ((vanishing.fit_vps(q, [1], K), err_q), (vanishing.fit_vps(q, [1], K, lines=lines), err_l)):
            err.append(max(np.degrees(np.arccos(np.clip(abs(d @ g), 0, 1)))
                           for d, g in zip(fit, (R @ EX_FRONT, R @ UP))))
    assert np.median(err_l) < 0.1 * np.median(err_q)


def test_line_jacobian_matches_finite_differences():
    from scipy.optimize._numdiff import approx_derivative

    R, t, quads, labels, _ = scene()
    R0 = np.array([vanishing.initial_rotation(*vanishing.fit_vps(quads, list(np.flatnonzero(labels == g)), K))
                   for g in (0, 1)])
    seg = edge_segments(R, t, ["front", "corner", "side", "side_right"])
    obs = facade_lines.LineObs(seg, np.array([0, 0, 1, 1]), np.repeat(np.eye(3)[None], 4, axis=0),
                         np.array([0, 1, 0, 1]), np.array([1.0, 2.0, 0.5, 1.0]))
    rng = np.random.default_rng(4)
    for focal_free in (False, True):
        x = np.concatenate([rng.normal(0, 0.1, 6), [790.0] if focal_free else []])

        def residuals(x):
            Rx, _, _, Kx = wallfit._unpack(x, 2, 0, R0, K, focal_free)
            return obs.residuals(Rx, Kx)

        Rx, _, _, Kx = wallfit._unpack(x, 2, 0, R0, K, focal_free)
        J = obs.jacobian(x, Rx, Kx, len(x), focal_free)
        np.testing.assert_allclose(J, approx_derivative(residuals, x, method="3-point"), atol=1e-6 * np.abs(J).max())
        # the residuals kept from the last point asked for are those of that point only
        fresh = facade_lines.LineObs(*(a.copy() for a in (obs.segments, obs.group, obs.Q, obs.axis, obs.weight)))
        assert np.array_equal(obs.residuals(Rx, Kx), fresh.residuals(Rx, Kx))
        assert np.array_equal(J, fresh.jacobian(x, Rx, Kx, len(x), focal_free))
        R2 = Rx.copy()
        R2[0] = R2[0] @ vanishing.rot_y(1.0)
        assert not np.array_equal(obs.residuals(R2, Kx), fresh.residuals(Rx, Kx))
        assert np.array_equal(obs.jacobian(x, Rx, Kx, len(x), focal_free), J)


def test_refine_walls_with_lines_exact_and_better_under_noise():
    """Exact quads and lines: the exact rotation. 1 px corner noise with exact façade lines: the
    rotation error falls well below the corners-only fit's on the same draws."""
    R, t, quads, labels, _ = scene()
    front = np.flatnonzero(labels == 0)
    R_gt = true_R(R, EX_FRONT)
    seg = edge_segments(R, t, ["front", "front_top", "corner", "front_left"])
    obs = facade_lines.LineObs(seg, np.zeros(4, int), np.repeat(np.eye(3)[None], 4, axis=0), np.array([0, 0, 1, 1]),
                         np.ones(4))
    R0 = vanishing.initial_rotation(*vanishing.fit_vps(quads, front.tolist(), K))
    fit = wallfit.refine_walls(quads[front], K, R0, lines=obs)
    assert rotation_error_deg(fit.R[0], R_gt) < TOL.exact_rotation_deg and fit.n_lines == 4
    rng = np.random.default_rng(6)
    plain, with_lines = [], []
    for _ in range(10):
        q = quads[front] + rng.normal(0.0, 1.0, (len(front), 4, 2))
        R0 = vanishing.initial_rotation(*vanishing.fit_vps(q, list(range(len(q))), K))
        plain.append(rotation_error_deg(wallfit.refine_walls(q, K, R0).R[0], R_gt))
        with_lines.append(rotation_error_deg(wallfit.refine_walls(q, K, R0, lines=obs).R[0], R_gt))
    assert np.median(with_lines) < 0.3 * np.median(plain)


def test_focal_with_lines():
    """K withheld, one window (60 x 70 px) with 0.5 px corner noise: alone it leaves f unobservable
    or far off; with its wall's four edges (exact segments) f comes out within 1 %."""
    R, t, quads, _, _ = scene()
    seg = edge_segments(R, t, ["front", "front_top", "corner", "front_left"])
    params = walls.WallParams(lines=True, line_margin=20.0, line_gate_deg=5.0)
    rng = np.random.default_rng(8)
    err_q, err_l = [], []
    for _ in range(10):
        q = quads[[2]] + rng.normal(0.0, 0.5, (1, 4, 2))
        try:
            err_q.append(abs(walls.fit_walls_focal(q, SHAPE, 1.0, walls.WallParams())[2].focal_px / 820.0 - 1))
        except vanishing.FacadeError:
            err_q.append(np.inf)
        err_l.append(abs(walls.fit_walls_focal(q, SHAPE, 1.0, params, seg)[2].focal_px / 820.0 - 1))
    assert np.max(err_l) < 0.01
    assert np.median(err_q) > 10 * np.max(err_l)


def test_wall_lines_strategy_on_a_drawn_photo():
    """apply_walls with 'wall+lines' on a drawn two-wall photo (its segments found by LSD) and 1 px
    corner noise: the median rotation error well below 'wall''s on the same quads; without the
    photo it refuses."""
    R, t, quads, labels, _ = scene()
    gray = draw_scene(R, t, quads).astype(np.float32)  # as reconstruct.to_gray gives it
    truth = [true_R(R, EX_FRONT if lab == 0 else EX_SIDE) for lab in labels]
    rng = np.random.default_rng(9)
    err = {"wall": [], "wall+lines": []}
    for _ in range(5):
        res = _results(quads + rng.normal(0.0, 1.0, quads.shape))
        for name in err:
            out = walls.apply_walls(res, K, SHAPE, 1.0, None, walls.WALL_STRATEGIES[name], SegmentCache(gray))
            err[name] += [rotation_error_deg(r.R, g) for r, g in zip(out, truth)]
    assert np.median(err["wall+lines"]) < 0.4 * np.median(err["wall"])  # measured 0.27 deg vs 1.05 deg
    with pytest.raises(ValueError, match="SegmentCache"):
        walls.apply_walls(_results(quads), K, SHAPE, 1.0, None, walls.WALL_STRATEGIES["wall+lines"])
    with pytest.raises(ValueError, match="segment cache's photo"):
        walls.apply_walls(_results(quads), K, SHAPE, 1.0, None, walls.WALL_STRATEGIES["wall+lines"],
                          SegmentCache(gray[:, :-1]))


def test_corner_sigmas_from_snapping():
    """Each window's sigma: the RMS distance its corners moved in snapping, at least the prior."""
    _, _, quads, _, _ = scene()
    moves = np.zeros((3, 4, 2))
    moves[1, :, 0] = 2.0  # every corner 2 px right
    moves[2, 0] = [3.0, 4.0]  # one corner 5 px
    res = [replace(r, quad_snapped=r.quad_mask + m) for r, m in zip(_results(quads[:3]), moves)]
    sig = walls.corner_sigmas(res, walls.WallParams(snap_sigma=True))
    np.testing.assert_allclose(sig, [WALL_FIT.sigma_px, 2.0, 2.5])
    assert walls.corner_sigmas(res, walls.WallParams()) is None


def test_per_window_sigma_covariance_matches_monte_carlo():
    """Windows with different corner noise (0.2 px and 1.5 px): with those sigmas given, the
    (sandwich) covariance of the unweighted fit matches a 150-draw Monte Carlo, per window."""
    _, _, quads, labels, _ = scene()
    q0 = quads[labels == 0]
    sig = np.array([0.2, 1.5, 0.2, 1.5, 0.2])
    R0 = vanishing.initial_rotation(*vanishing.fit_vps(q0, list(range(len(q0))), K))
    ref = wallfit.refine_walls(q0, K, R0, sigma_px=0.2, prior_dof=np.inf, corner_sigma=sig)
    rng = np.random.default_rng(12)
    widths = [wallfit.refine_walls(q0 + rng.normal(0.0, 1.0, q0.shape) * sig[:, None, None], K, ref.R[0]).width
              for _ in range(150)]
    sd_w = np.sqrt([ref.cov[ref.window_block(i), ref.window_block(i)][3, 3] for i in range(len(q0))])
    np.testing.assert_allclose(sd_w, np.std(widths, axis=0), rtol=0.2)
    plain = wallfit.refine_walls(q0, K, R0, sigma_px=0.2, prior_dof=np.inf)
    np.testing.assert_allclose(plain.width, ref.width)  # the estimate itself is unweighted


def test_whole_image_segments_of_a_large_photo_on_a_bounded_copy():
    """Above max_pixels the segments come from a resized copy, mapped back to the photo's pixels:
    a vertical step edge at x = 399.5 (between columns 399 and 400) is found there within 0.5 px."""
    from fenestra.pipeline.segments import whole_image_segments

    img = np.full((600, 800), 60, np.uint8)
    img[100:500, 400:] = 200
    small = whole_image_segments(img, 0.8, max_pixels=120_000)  # a 400 x 300 copy
    full = whole_image_segments(img, 0.8)
    for seg in (small, full):
        vertical = seg[np.abs(seg[:, 0, 0] - seg[:, 1, 0]) < 1.0]
        assert len(vertical) >= 1
        longest = vertical[np.argmax(np.abs(vertical[:, 0, 1] - vertical[:, 1, 1]))]
        assert abs(longest[:, 0].mean() - 399.5) < 0.5, longest
        assert abs(longest[0, 1] - longest[1, 1]) > 300  # most of the 400 px edge


# ------------------------------------------------------------------ the per-photo memo

def _same_results(a: list[WindowResult], b: list[WindowResult]) -> bool:
    """Every field of every result identical (arrays bit for bit)."""
    from dataclasses import fields  # noqa: PLC0415

    def same(x, y) -> bool:
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            return x is not None and y is not None and x.dtype == y.dtype and x.shape == y.shape \
                and x.tobytes() == y.tobytes()
        return x == y

    return len(a) == len(b) and all(same(getattr(r, f.name), getattr(s, f.name))
                                    for r, s in zip(a, b) for f in fields(WindowResult))


def test_memo_key_is_exact():
    """Two inputs share a memo entry only when identical: arrays by dtype, shape and bytes (0.0
    and -0.0 differ), containers element by element; an unhashable part raises at once."""
    from fenestra.pipeline.memo import key  # noqa: PLC0415

    a = np.array([[0.0, 1.5], [2.0, 3.0]])
    assert key(a, 1.0, "x", (a, None)) == key(a.copy(), 1.0, "x", (a.copy(), None))
    assert key(a) != key(np.where(a == 0.0, -0.0, a))
    assert key(a) != key(a.astype(np.float32)) and key(a) != key(a.reshape(4))
    assert key(a) != key(np.where(a == 3.0, np.nextafter(3.0, 4.0), a))  # one ulp apart
    assert key([a]) != key((a,))
    assert key(1) != key(1.0) and key(1.0) != key(np.float64(1.0))
    with pytest.raises(TypeError):
        key({"unhashable": 1})


def test_memo_shared_by_strategies_gives_their_own_results():
    """One memo for every per-wall strategy on a photo (as the bench keeps one per view): each
    strategy's results are bit for bit those of a run on its own, with K and without (focal
    fit), with a window that does not fit its wall (the split-and-refit loop); the memo did
    share work, and what it keeps cannot be written to."""
    from fenestra.pipeline.memo import StepMemo  # noqa: PLC0415

    R, t, quads, _, _ = scene()
    gray = draw_scene(R, t, quads).astype(np.float32)
    rng = np.random.default_rng(5)
    snapped = quads + rng.normal(0.0, 0.7, quads.shape)
    snapped[2, 1] += [9.0, -6.0]  # an outlier corner: split off and refitted
    res = [replace(r, quad_mask=r.quad_mask + rng.normal(0.0, 0.5, (4, 2))) for r in _results(snapped)]
    for K_in in (K, None):
        memo, cache = StepMemo(), SegmentCache(gray)
        for name in ("wall", "building", "wall+lines", "building+lines", "wall", "wall+sigma", "building+lines"):
            # wall+sigma: 'wall' with error bars from snapping (the fit kept, its covariance not)
            params = replace(walls.WALL_STRATEGIES["wall"], snap_sigma=True) if name == "wall+sigma" \
                else walls.WALL_STRATEGIES[name]
            shared = walls.apply_walls(res, K_in, SHAPE, 1.0, None, params, cache, memo)
            alone = walls.apply_walls(res, K_in, SHAPE, 1.0, None, params, SegmentCache(gray))
            assert _same_results(shared, alone), (name, K_in is None)
        assert memo.hits > 0 and len(memo) > 0
    out = walls.apply_walls(res, K, SHAPE, 1.0, None, walls.WALL_STRATEGIES["wall"], memo=memo)
    with pytest.raises(ValueError, match="read-only"):
        out[0].quad_reprojected[0, 0] = 0.0


def test_quantiles_are_scipy_stats_bit_for_bit():
    """The intervals' quantiles (special functions called directly, skipping scipy.stats' argument
    handling) equal scipy.stats' chi2.ppf and norm.ppf exactly over the degrees of freedom that
    norm_quantile gives (1 to 3) and beyond."""
    from scipy.stats import chi2, norm  # noqa: PLC0415

    rng = np.random.default_rng(2)
    for dof in np.concatenate([rng.uniform(0.5, 4.0, 2000), [1.0, 2.0, 3.0]]):
        for level in (0.5, 0.9, 0.95):
            assert wallfit.chi2_ppf(level, dof) == float(chi2.ppf(level, dof))
    for level in (0.5, 0.9, 0.95, 0.975):
        assert wallfit.norm_ppf(level) == float(norm.ppf(level))


def test_a_runaway_focal_length_stops_early_and_a_good_one_is_unchanged(monkeypatch):
    """Issue 35: with K withheld on a fronto-parallel wall f is unobservable and LM let it drift
    for thousands of evaluations (148 CPU-s on one photo) before the answer was rejected. The fit
    now stops as soon as f leaves WALL_FIT.focal_range_rel x the long side, or after max_nfev
    evaluations; a well-posed fit (two walls at an angle) gives the same f with or without the bounds."""
    R, t = look_at(np.array([0.5, -8.0, 2.0]), np.array([0.5, 0.0, 2.0]))  # fronto-parallel
    quads = np.array([project(K, R, t, c) for c in wall_windows([0, 0, 0], EX_FRONT, FRONT)])
    quads = quads + np.random.default_rng(4).normal(0.0, 0.3, quads.shape)
    R0 = R @ np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # window frame (x, y up, z out) -> camera
    calls = []
    real = wallfit.least_squares

    def counting(fun, *a, **k):  # the real solver, its residual evaluations counted
        def f(x):
            calls.append(1)
            return fun(x)
        return real(f, *a, **k)

    monkeypatch.setattr(wallfit, "least_squares", counting)
    with pytest.raises(vanishing.FacadeError, match=r"f ran away to -?\d+ px, outside \[100, 6400\]"):
        wallfit.refine_walls(quads, K, R0, focal_free=True, focal_bounds=(100.0, 6400.0))
    ran_away = len(calls)
    calls.clear()
    with pytest.raises(vanishing.FacadeError, match="did not converge in 5 evaluations"):
        wallfit.refine_walls(quads, K, R0, focal_free=True, max_nfev=5)
    assert ran_away < 100 and len(calls) <= 6
    monkeypatch.undo()
    with pytest.raises(vanishing.FacadeError, match="focal length unobservable"):
        walls.fit_walls_focal(quads, SHAPE)
    _, _, q2, _, _ = scene()  # two walls at an angle: f observable (true 820 px)
    q2 = q2 + np.random.default_rng(5).normal(0.0, 0.3, q2.shape)
    f_bounded, sd = walls.focal_from_walls(q2, SHAPE)
    assert abs(f_bounded - 820.0) < 3.0 * sd
    members, wall_ids, fit = walls.fit_walls_focal(q2, SHAPE)
    one = wallfit.refine_walls(q2[list(members)], walls.pseudo_K(SHAPE, fit.focal_px), fit.R, fit.wall_of,
                               focal_free=True, max_nfev=None)
    assert one.focal_px == pytest.approx(f_bounded, rel=1e-6)  # the cap does not bind on a well-posed fit


def test_vp_consensus_memory_is_bounded_on_a_brick_wall():
    """A brick wall gives 10^5 segments near one vanishing point (issue 37: a 4200 x 3150 brick
    façade grew past 21 GB in the (hypotheses x segments) consensus). 60 000 horizontal mortar
    segments, exactly converging on a known vanishing point, plus 1 % clutter: the consensus keeps
    the mortar and drops the clutter, and its peak memory (tracemalloc) stays far below the
    hypotheses x segments matrices (60 000^2 booleans = 3.6 GB)."""
    import tracemalloc

    from fenestra.pipeline.walls.lines import vp_consensus

    rng = np.random.default_rng(7)
    K = np.array([[1500.0, 0, 1000], [0, 1500.0, 750], [0, 0, 1]])
    vp = np.array([9000.0, 760.0])  # the wall's horizontal vanishing point, px
    start = np.column_stack([rng.uniform(0, 2000, 60_000), rng.uniform(0, 1500, 60_000)])
    direction = (vp - start) / np.linalg.norm(vp - start, axis=1, keepdims=True)
    mortar = np.stack([start, start + direction * rng.uniform(8, 30, (60_000, 1))], axis=1)
    clutter = np.stack([start[:600], start[:600] + rng.normal(0, 1, (600, 2)) * [2, 20]], axis=1)
    segments = np.concatenate([mortar, clutter])
    d0 = np.linalg.solve(K, [vp[0], vp[1], 1.0])
    tracemalloc.start()
    keep = vp_consensus(segments, d0 / np.linalg.norm(d0), K, gate_deg=3.0, tight_deg=1.0, noise_px=0.5)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert keep[:60_000].mean() > 0.99 and keep[60_000:].mean() < 0.2
    assert peak < 400e6, f"{peak / 1e6:.0f} MB"


def test_focal_of_a_level_camera_at_a_corner():
    """A level camera (optical axis horizontal: every wall's verticals are parallel in the image, so
    no wall alone gives f) at a house corner: the two walls' horizontal vanishing points at a right
    angle give f (issue 35: two horizontal vanishing points where a corner shows)."""
    R, t = look_at(np.array([8.0, -7.0, 2.3]), np.array([1.5, 1.0, 2.3]))
    assert abs((R @ UP)[2]) < 1e-12  # level: the vertical vanishing point is at infinity
    C = np.concatenate([wall_windows([0.0, 0.0, 0.0], EX_FRONT, FRONT), wall_windows([3.5, 0.0, 0.0], EX_SIDE, SIDE)])
    quads = np.array([project(K, R, t, c) for c in C])
    front_only = quads[:len(FRONT)]
    with pytest.raises(vanishing.FacadeError, match="meet at a right angle"):
        walls.focal_from_walls(front_only, SHAPE)  # one wall, level camera: unobservable
    f, sd = walls.focal_from_walls(quads, SHAPE)
    assert f == pytest.approx(820.0, rel=1e-6)
    rng = np.random.default_rng(11)
    f, sd = walls.focal_from_walls(quads + rng.normal(0.0, 0.3, quads.shape), SHAPE)
    assert abs(f - 820.0) < 3 * sd and abs(f - 820.0) < 0.05 * 820.0


def test_corner_focals_need_two_directions_at_a_right_angle():
    K0 = walls.pseudo_K(SHAPE, 500.0)
    R, _ = look_at(np.array([8.0, -7.0, 2.3]), np.array([1.5, 1.0, 2.3]))
    d_front, d_side = R @ EX_FRONT, R @ EX_SIDE
    assert walls.corner_focals([d_front, d_side], K0) == [pytest.approx(500.0, rel=1e-9)]  # K0's own f: exact
    assert walls.corner_focals([d_front, d_front], K0) == []  # one façade split in two: no corner
    assert walls.corner_focals([d_front], K0) == []
