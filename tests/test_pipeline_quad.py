"""mask -> quad on exactly rasterised masks, and its explicit failures on degenerate masks.

Ground truth: a quad projected from a known rectangle and camera; the mask holds exactly the
pixels whose centres lie inside it (what a rasteriser draws), computed by half-plane tests.
"""
import cv2
import numpy as np
import pytest

from fenestra.conventions import make_K
from fenestra.pipeline.quad import QuadParams, mask_to_quad, order_corners
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
    assert r.quad is None and r.failure is not None and r.failure.startswith(code), r.failure


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

    assert quad_of(disk, inscribed, "mask").failure.startswith("not_quadrilateral")
    np.testing.assert_allclose(quad_of(disk, inscribed, "mask+corners").quad, inscribed)
    elsewhere = inscribed + [150.0, 0.0]  # its centroid test fails: not this mask's window
    assert quad_of(disk, elsewhere, "mask+corners").quad is None
    assert quad_of(disk, None, "mask+corners").quad is None
    cut = (yy - 10) ** 2 + (xx - 80) ** 2 < 40 ** 2  # reaches the top edge: corners unseen
    assert quad_of(cut, inscribed - [0, 50], "mask+corners").failure.startswith("touches_border")
    rect = (yy >= 30) & (yy < 90) & (xx >= 40) & (xx < 120)
    fit = quad_of(rect, inscribed, "mask+corners").quad  # the mask fit where it succeeds, not the head
    np.testing.assert_allclose(fit, [[39.5, 29.5], [119.5, 29.5], [119.5, 89.5], [39.5, 89.5]], atol=0.3)
