"""mask -> quad on exactly rasterised masks, and its explicit failures on degenerate masks.

Ground truth: a quad projected from a known rectangle and camera; the mask holds exactly the
pixels whose centres lie inside it (what a rasteriser draws), computed by half-plane tests.
"""
import cv2
import numpy as np
import pytest

from fenestra.conventions import make_K
from fenestra.pipeline.quad import QuadParams, mask_to_quad, order_corners
from fenestra.tolerances import TOL
from quad_image import pixel_centre_mask, view_window

K = make_K(800.0, 800.0, 319.5, 239.5)
SHAPE = (480, 640)


def views(n, seed):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        yield view_window(K, rng.uniform(0.6, 1.8), rng.uniform(0.8, 1.8), rng.uniform(-50, 50),
                          rng.uniform(-30, 30), rng.uniform(-15, 15), rng.uniform(5, 9),
                          tuple(rng.uniform(-80, 80, 2)))


def test_exact_mask_gives_true_corners():
    errs = []
    for sw in views(25, seed=0):
        r = mask_to_quad(pixel_centre_mask(sw.corners_px, SHAPE))
        assert r.failure is None, r.failure
        errs.append(np.linalg.norm(r.quad - sw.corners_px, axis=1))
    errs = np.concatenate(errs)
    assert errs.max() < 0.75 and np.median(errs) < 0.15, (np.median(errs), errs.max())


def test_axis_aligned_rectangle_on_pixel_edges_is_exact():
    # pixels 100..199 x 50..129 filled: the rectangle's true edges are half a pixel outside them
    m = np.zeros(SHAPE, bool)
    m[50:130, 100:200] = True
    r = mask_to_quad(m)
    truth = np.array([[99.5, 49.5], [199.5, 49.5], [199.5, 129.5], [99.5, 129.5]])
    assert np.abs(r.quad - truth).max() < 1e-6


def test_corner_order_tl_tr_br_bl():
    sq = np.array([[10.0, 10.0], [50.0, 12.0], [48.0, 60.0], [9.0, 58.0]])
    for k in range(4):
        assert np.allclose(order_corners(np.roll(sq, k, axis=0)), sq)
        assert np.allclose(order_corners(np.roll(sq[::-1], k, axis=0)), sq)


def test_lines_are_outward_and_ordered():
    sw = next(views(1, seed=3))
    r = mask_to_quad(pixel_centre_mask(sw.corners_px, SHAPE))
    centre = sw.corners_px.mean(axis=0)
    for k, line in enumerate(r.lines):  # side k runs from corner k to corner k+1
        assert line[:2] @ centre < line[2]
        for c in (r.quad[k], r.quad[(k + 1) % 4]):
            assert abs(line[:2] @ c - line[2]) < 1e-6


def disc(shape, centre, radius):
    m = np.zeros(shape, np.uint8)
    cv2.circle(m, centre, radius, 1, -1)
    return m


@pytest.mark.parametrize("make, code", [
    (lambda: np.zeros(SHAPE, bool), "empty_mask"),
    (lambda: disc(SHAPE, (300, 200), 3), "too_small"),
    (lambda: disc(SHAPE, (300, 200), 60), "not_quadrilateral"),
    (lambda: cv2.fillPoly(np.zeros(SHAPE, np.uint8), [np.array([[100, 300], [400, 320], [250, 60]])], 1),
     "not_quadrilateral"),
    (lambda: cv2.rectangle(cv2.rectangle(np.zeros(SHAPE, np.uint8), (50, 50), (120, 150), 1, -1),
                           (300, 50), (380, 150), 1, -1), "multiple_blobs"),
    (lambda: cv2.rectangle(np.zeros(SHAPE, np.uint8), (0, 100), (120, 200), 1, -1), "touches_border"),
])
def test_degenerate_masks_fail_explicitly(make, code):
    r = mask_to_quad(make())
    assert r.quad is None and r.failure is not None and r.failure.code == code, r.failure


def test_border_allowed_when_asked_and_bad_shape_raises():
    m = cv2.rectangle(np.zeros(SHAPE, np.uint8), (0, 100), (120, 200), 1, -1)
    assert mask_to_quad(m, QuadParams(allow_border=True)).failure is None
    with pytest.raises(ValueError, match="2-D"):
        mask_to_quad(np.zeros((4, 4, 3)))


def test_speck_ignored():
    sw = next(views(1, seed=5))
    m = pixel_centre_mask(sw.corners_px, SHAPE)
    m[5, 5] = True  # a one-pixel speck far away
    r = mask_to_quad(m)
    assert r.failure is None and np.linalg.norm(r.quad - sw.corners_px, axis=1).max() < 0.75


def test_mask_plus_corners_takes_the_corner_head_only_where_the_mask_fit_finds_no_quad():
    """quad source ``mask+corners``: a round (not quadrilateral) mask fails the mask fit; the
    detection's predicted corners that describe it stand in; corners on another window, a mask cut
    by the image border, and the plain ``mask`` source keep the failure; a good mask keeps its fit."""
    from fenestra.pipeline.reconstruct import fit_quads
    from fenestra.pipeline.types import Detection

    yy, xx = np.mgrid[:120, :160]
    disk = (yy - 60) ** 2 + (xx - 80) ** 2 < 40 ** 2
    inscribed = np.array([[52.0, 32.0], [108.0, 32.0], [108.0, 88.0], [52.0, 88.0]])  # TL TR BR BL
    box = np.array([40, 20, 120, 100])

    def quad_of(mask, corners, source):
        det = Detection(mask=mask, box=box, score=0.9, corners=corners)
        return fit_quads([det], QuadParams(source=source), mask.shape)[0].result

    assert quad_of(disk, inscribed, "mask").failure.code == "not_quadrilateral"
    np.testing.assert_allclose(quad_of(disk, inscribed, "mask+corners").quad, inscribed)
    elsewhere = inscribed + [150.0, 0.0]  # its centroid test fails: not this mask's window
    assert quad_of(disk, elsewhere, "mask+corners").quad is None
    assert quad_of(disk, None, "mask+corners").quad is None
    cut = (yy - 10) ** 2 + (xx - 80) ** 2 < 40 ** 2  # reaches the top edge: corners unseen
    assert quad_of(cut, inscribed - [0, 50], "mask+corners").failure.code == "touches_border"
    rect = (yy >= 30) & (yy < 90) & (xx >= 40) & (xx < 120)
    fit = quad_of(rect, inscribed, "mask+corners").quad  # the mask fit where it succeeds, not the head
    np.testing.assert_allclose(fit, [[39.5, 29.5], [119.5, 29.5], [119.5, 89.5], [39.5, 89.5]], atol=0.3)


# --- thin windows (issue 36): a short side of 10-20 px is shorter than the local line fit --------------

THIN = (200, 200)


def rotated_rect(w, h, angle_deg, centre):
    """Corners (4, 2) of a w x h px rectangle turned by angle_deg about centre (independent truth)."""
    a = np.radians(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]]) @ R.T + centre


def rounded_mask(corners, radius, shape):
    """Pixels whose centre lies inside the rectangle ``corners`` (TL TR BR BL, any projective view of
    a rectangle) with its corners rounded by ``radius`` in the rectangle's own frame (unit square
    scaled to its side lengths in px at the TL corner): mapped back through the exact homography."""
    wpx = np.linalg.norm(corners[1] - corners[0])
    hpx = np.linalg.norm(corners[3] - corners[0])
    frame = np.array([[0, 0], [wpx, 0], [wpx, hpx], [0, hpx]], np.float32)
    H = cv2.getPerspectiveTransform(np.asarray(corners, np.float32), frame).astype(np.float64)
    v, u = np.mgrid[:shape[0], :shape[1]]
    X = np.stack([u.ravel(), v.ravel(), np.ones(u.size)], axis=1) @ H.T
    x, y = X[:, 0] / X[:, 2], X[:, 1] / X[:, 2]
    qx = np.abs(x - wpx / 2) - (wpx / 2 - radius)
    qy = np.abs(y - hpx / 2) - (hpx / 2 - radius)
    d = np.hypot(np.maximum(qx, 0), np.maximum(qy, 0)) + np.minimum(np.maximum(qx, qy), 0)
    return (d <= radius).reshape(shape)


def in_frame(q, shape, margin=3.0):
    return bool(np.all(q >= margin) and np.all(q[:, 0] < shape[1] - margin) and np.all(q[:, 1] < shape[0] - margin))


def corner_err(r, truth):
    assert r.failure is None, r.failure
    return np.linalg.norm(r.quad - order_corners(truth), axis=1).max()


@pytest.mark.parametrize("w, h", [(10, 60), (14, 70), (20, 120)])
def test_thin_rectangle_on_pixel_edges_is_exact(w, h):
    # the colleague's case: a 14 x 70 px rectangle failed with "a side explains only 0.0%"
    for m, truth in ((np.zeros(THIN, bool), np.array([[49.5, 59.5], [49.5 + w, 59.5], [49.5 + w, 59.5 + h], [49.5, 59.5 + h]])),
                     (np.zeros(THIN, bool), np.array([[59.5, 49.5], [59.5 + h, 49.5], [59.5 + h, 49.5 + w], [59.5, 49.5 + w]]))):
        x0, y0 = truth[0] + 0.5
        x1, y1 = truth[2] + 0.5
        m[int(y0):int(y1), int(x0):int(x1)] = True
        r = mask_to_quad(m)
        assert r.failure is None, r.failure
        assert np.abs(r.quad - truth).max() < 1e-6, r.quad - truth


@pytest.mark.parametrize("w, h", [(10, 60), (14, 70), (20, 120)])
def test_thin_rotated_rectangles_within_half_a_pixel(w, h):
    """Every 2.5 deg, at random sub-pixel centres. Away from the pixel axes every corner is within
    TOL.thin_quad_exact_px; within 10 deg of an axis a 10-20 px edge is one or two pixel rows, which
    fix its position only to the pixel, and its few points its direction poorly: up to 1.13 px
    measured (14 x 70 at 90.5 deg), bounded here at 1.2 px."""
    rng = np.random.default_rng(w)
    errs, fails = {}, []
    for ang in np.arange(0.5, 180.0, 2.5):
        truth = rotated_rect(w, h, ang, 100.0 + rng.uniform(0, 1, 2))
        r = mask_to_quad(pixel_centre_mask(truth, THIN))
        if r.failure is not None:
            fails.append((ang, r.failure))
            continue
        errs[ang] = corner_err(r, truth)
    assert len(fails) <= (1 if w == 10 else 0), fails  # 10 px: one sub-pixel phase in 72 fails
    off_axis = [e for a, e in errs.items() if min(a % 90.0, 90.0 - a % 90.0) >= 10.0]
    assert max(off_axis) < TOL.thin_quad_exact_px, max(off_axis)
    assert max(errs.values()) < 1.2 and np.median(list(errs.values())) < 0.3, errs


def test_thin_windows_in_perspective_within_half_a_pixel():
    """0.35-0.5 x 1.4-2 m windows seen at up to 75 deg yaw, short sides 12 px or more."""
    rng = np.random.default_rng(11)
    errs = []
    while len(errs) < 60:
        sw = view_window(K, rng.uniform(0.35, 0.5), rng.uniform(1.4, 2.0), rng.uniform(-75, 75),
                         rng.uniform(-30, 30), rng.uniform(-15, 15), rng.uniform(5, 20),
                         tuple(rng.uniform(-120, 120, 2)))
        q = sw.corners_px
        if np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1).min() < 12 or not in_frame(q, SHAPE):
            continue
        errs.append(corner_err(mask_to_quad(pixel_centre_mask(q, SHAPE)), q))
    errs = np.array(errs)
    assert np.median(errs) < 0.25 and np.mean(errs < TOL.thin_quad_exact_px) >= 0.9, np.sort(errs)[-8:]
    assert errs.max() < 1.0, np.sort(errs)[-8:]


@pytest.mark.parametrize("w, h, radius", [(10, 60, 3), (14, 70, 4.5), (20, 120, 6.5), (24, 100, 8), (45, 160, 15)])
def test_thin_rounded_masks_give_the_straight_sided_quad(w, h, radius):
    # a learned mask rounds the corners: 24 x 100 px with radius 8 failed ("3.1% of the outline")
    rng = np.random.default_rng(int(radius * 10))
    for ang in (0.0, 4.0, 17.0, 45.0, 73.0, 90.0):
        truth = rotated_rect(w, h, ang, 100.0 + rng.uniform(0, 1, 2))
        err = corner_err(mask_to_quad(rounded_mask(truth, radius, THIN)), truth)
        assert err < TOL.thin_quad_rounded_px, (ang, err)


def test_thin_rounded_windows_in_perspective():
    rng = np.random.default_rng(12)
    n = 0
    while n < 30:
        sw = view_window(K, rng.uniform(0.35, 0.5), rng.uniform(1.4, 2.0), rng.uniform(-60, 60),
                         rng.uniform(-30, 30), rng.uniform(-15, 15), rng.uniform(4, 12),
                         tuple(rng.uniform(-100, 100, 2)))
        q = sw.corners_px
        short = np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1).min()
        if short < 12 or not in_frame(q, SHAPE):
            continue
        m = rounded_mask(q, rng.uniform(0.0, 1.0 / 3.0) * short, SHAPE)
        assert corner_err(mask_to_quad(m), q) < TOL.thin_quad_rounded_px
        n += 1


def clipped_triangle(tri, k, frac):
    """Triangle (3, 2) with corner k cut off at ``frac`` of both sides that meet there."""
    A, B, C = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
    return np.array([A + frac * (B - A), B, C, A + frac * (C - A)])


@pytest.mark.parametrize("make", [
    lambda: cv2.fillPoly(np.zeros(SHAPE, np.uint8), [np.int32(clipped_triangle(
        np.array([[100.0, 300.0], [400.0, 320.0], [250.0, 60.0]]), 2, 0.05))], 1),
    lambda: cv2.fillPoly(np.zeros(SHAPE, np.uint8), [np.int32(clipped_triangle(
        np.array([[100.0, 300.0], [400.0, 320.0], [250.0, 60.0]]), 0, 0.04))], 1),
    lambda: cv2.fillPoly(np.zeros(SHAPE, np.uint8), [np.int32(clipped_triangle(  # a sliver: thin
        np.array([[90.0, 110.0], [470.0, 310.0], [141.0, 71.0]]), 0, 0.04))], 1),
    lambda: cv2.fillPoly(np.zeros(SHAPE, np.uint8), [np.int32([[300, 100], [330, 110], [310, 400]])], 1),
    lambda: cv2.ellipse(np.zeros(SHAPE, np.uint8), (320, 240), (20, 90), 17, 0, 360, 1, -1),
    lambda: cv2.ellipse(np.zeros(SHAPE, np.uint8), (320, 240), (12, 60), 0, 0, 360, 1, -1),
    lambda: disc(SHAPE, (300, 200), 15),
])
def test_thin_and_clipped_non_quadrilaterals_still_fail(make):
    """The side rule judged against each side's own length keeps its guard: a triangle with a
    clipped corner (a short side facing a long one), a thin triangle, thin ellipses, small discs."""
    r = mask_to_quad(make())
    assert r.quad is None and r.failure.code == "not_quadrilateral", r.failure


def test_two_thin_windows_in_one_mask_fail():
    m = np.zeros(SHAPE, bool)
    m[100:170, 200:214] = True
    m[100:170, 230:244] = True
    assert mask_to_quad(m).failure.code == "multiple_blobs"


# --- quad source mask+lines: the best four of more lines where the greedy fit finds no quad ---------

LINES = QuadParams(source="mask+lines")


def notched(q, frac):
    """The convex pentagon (5, 2) of quad q (4, 2) TL TR BR BL with its TR corner cut off at ``frac``
    of both sides meeting there (a learned mask that left out a shadowed corner of the reveal)."""
    tl, tr, br, bl = q
    return np.array([tl, tr + frac * (tl - tr), tr + frac * (br - tr), br, bl])


def test_mask_plus_lines_recovers_the_window_of_a_notched_mask():
    """A mask with one corner notched off fails the greedy fit (a corner far from the outline); the
    source mask+lines finds the window's four sides among more lines, confirmed by predicted
    corners 1 px off (a corner head's noise), and its corners are the window's own (the notch's
    edge is not taken as a side). Predicted corners 10 px off, or none, confirm nothing: the
    greedy fit's failure stays. Ground truth: the projected window."""
    rng = np.random.default_rng(0)
    recovered = []
    for sw in views(30, seed=11):
        q = sw.corners_px
        m = pixel_centre_mask(notched(q, 0.3), SHAPE)
        assert mask_to_quad(m).failure.code == "not_quadrilateral"
        assert mask_to_quad(m, LINES).failure.code == "not_quadrilateral"  # no hint
        assert mask_to_quad(m, LINES, hint=q + [10.0, 0.0]).quad is None
        r = mask_to_quad(m, LINES, hint=q + rng.normal(0.0, 1.0, (4, 2)))
        if r.quad is not None:
            recovered.append(corner_err(r, q))
    assert len(recovered) >= 26 and max(recovered) < TOL.notched_quad_px, (len(recovered), max(recovered))


def test_mask_plus_lines_reaches_the_quad_fit_through_a_detection():
    """fit_quads hands a detection's predicted corners (full-image px) to the fit of its mask crop."""
    from fenestra.pipeline.reconstruct import fit_quads
    from fenestra.pipeline.types import Detection

    sw = next(views(1, seed=13))
    q = sw.corners_px
    full = pixel_centre_mask(notched(q, 0.3), SHAPE)
    ys, xs = np.nonzero(full)
    x0, y0 = int(xs.min()), int(ys.min())
    crop = full[y0:ys.max() + 1, x0:xs.max() + 1]
    det = Detection(mask=crop, box=np.array([x0, y0, xs.max() + 1, ys.max() + 1]), score=0.9, corners=q,
                    origin=(x0, y0))
    assert fit_quads([det], QuadParams(source="mask"), SHAPE)[0].result.quad is None
    fit = fit_quads([det], LINES, SHAPE)[0].result
    assert corner_err(fit, q) < TOL.notched_quad_px


def test_mask_plus_lines_keeps_the_greedy_fit_where_it_succeeds():
    for sw in views(5, seed=12):
        m = pixel_centre_mask(sw.corners_px, SHAPE)
        np.testing.assert_array_equal(mask_to_quad(m, LINES, hint=sw.corners_px).quad, mask_to_quad(m).quad)


@pytest.mark.parametrize("make", [
    lambda: disc(SHAPE, (300, 200), 60),
    lambda: cv2.fillPoly(np.zeros(SHAPE, np.uint8), [np.array([[100, 300], [400, 320], [250, 60]])], 1),
    lambda: cv2.fillPoly(np.zeros(SHAPE, np.uint8), [np.array([[100, 100], [300, 100], [300, 160], [160, 160],
                                                               [160, 300], [100, 300]])], 1),  # an L
    lambda: cv2.ellipse(np.zeros(SHAPE, np.uint8), (320, 240), (20, 90), 17, 0, 360, 1, -1),
])
def test_mask_plus_lines_still_refuses_non_quadrilaterals(make):
    """A disc, a triangle, an L and an ellipse have no four lines that the mask fills and covers,
    even with predicted corners at their bounding box."""
    m = make()
    ys, xs = np.nonzero(m)
    box = np.array([[xs.min(), ys.min()], [xs.max(), ys.min()], [xs.max(), ys.max()], [xs.min(), ys.max()]], float)
    r = mask_to_quad(m, LINES, hint=box)
    assert r.quad is None and r.failure.code == "not_quadrilateral", r.failure


def test_subset_lines_below_four_is_refused():
    with pytest.raises(ValueError, match="subset_lines"):
        QuadParams(subset_lines=3)
