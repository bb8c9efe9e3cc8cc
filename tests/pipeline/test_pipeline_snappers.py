"""Corner snappers on antialiased renders of exactly known quads (exact area coverage + noise)."""
import dataclasses

import numpy as np
import pytest

from fenestra.conventions import make_K
from fenestra.pipeline.quad import mask_to_quad
from fenestra.pipeline.snappers import SNAPPERS, snap
from quad_image import pixel_centre_mask, render_window_image, view_window

K = make_K(800.0, 800.0, 319.5, 239.5)
SHAPE = (480, 640)


def cases(n, seed, noise):
    rng = np.random.default_rng(seed)
    for i in range(n):
        sw = view_window(K, rng.uniform(0.6, 1.8), rng.uniform(0.8, 1.8), rng.uniform(-45, 45),
                         rng.uniform(-25, 25), rng.uniform(-10, 10), rng.uniform(5, 9),
                         tuple(rng.uniform(-80, 80, 2)))
        gray = render_window_image(sw.corners_px, SHAPE, noise_sigma=noise, seed=i)[:, :, 0]
        start = mask_to_quad(pixel_centre_mask(sw.corners_px, SHAPE)).quad
        yield sw.corners_px, gray, start


@pytest.mark.parametrize("name", sorted(SNAPPERS))
def test_registry_entry(name):
    s = SNAPPERS[name]
    p = s.params()
    assert dataclasses.is_dataclass(p) and p.__dataclass_params__.frozen
    assert s.name == name and s.snap.__doc__ and s.description.strip() and s.test_median_px > 0


def test_registry_entry_must_declare_its_capabilities():
    from fenestra.pipeline.snappers.base import Snapper
    from fenestra.pipeline.snappers.none import NoneParams, snap_none

    with pytest.raises(ValueError, match="'x' needs a description"):
        Snapper("x", snap_none, NoneParams, description=" ", test_median_px=1.0)
    with pytest.raises(ValueError, match="test_median_px must be > 0, got 0"):
        Snapper("x", snap_none, NoneParams, description="d", test_median_px=0)


@pytest.mark.parametrize("name", sorted(SNAPPERS))
def test_snapper_corner_error(name):
    """Every registered snapper meets the median corner-error bound it declares (noise sigma 2,
    starting from the mask-fit quad)."""
    errs = []
    for truth, gray, start in cases(8, seed=1, noise=2.0):
        q, info = snap(name, gray, start)
        assert q.shape == (4, 2) and len(info["moved"]) == 4
        errs.append(np.linalg.norm(q - truth, axis=1))
    errs = np.concatenate(errs)
    print(f"{name}: median corner error {np.median(errs):.3f} px, max {errs.max():.3f} px "
          f"(declared bound {SNAPPERS[name].test_median_px} px)")  # shown by pytest -s: how to choose a bound
    assert np.median(errs) < SNAPPERS[name].test_median_px, (name, np.median(errs), errs.max())


def test_linefit_subpixel_on_clean_edges():
    # start 1-2 px off the truth: linefit must land within 0.1 px on clean antialiased edges
    rng = np.random.default_rng(7)
    for truth, gray, _ in cases(10, seed=2, noise=0.0):
        start = truth + rng.uniform(-2.0, 2.0, truth.shape)
        q, _ = snap("linefit", gray, start)
        assert np.linalg.norm(q - truth, axis=1).max() <= 0.1


def test_linefit_with_noise_beats_mask_quad():
    e_mask, e_fit = [], []
    for truth, gray, start in cases(8, seed=3, noise=4.0):
        e_mask.append(np.linalg.norm(start - truth, axis=1))
        e_fit.append(np.linalg.norm(snap("linefit", gray, start)[0] - truth, axis=1))
    assert np.median(e_fit) < 0.1 and np.median(e_fit) < np.median(e_mask)


def test_snap_bad_input():
    gray = np.zeros((50, 50), np.uint8)
    with pytest.raises(ValueError, match="unknown snapper 'sift'"):
        snap("sift", gray, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="shape"):
        snap("harris", gray, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="2-D"):
        snap("linefit", np.zeros((50, 50, 3)), np.zeros((4, 2)))


@pytest.mark.parametrize("name", sorted(SNAPPERS))
def test_flat_image_keeps_corners(name):
    # nothing to snap to: every strategy must keep the input corners (no crash, no wild jump)
    quad = np.array([[20.0, 20.0], [80.0, 22.0], [78.0, 70.0], [21.0, 68.0]])
    q, _ = snap(name, np.full((100, 100), 128, np.uint8), quad)
    assert np.allclose(q, quad)


@pytest.mark.parametrize("name", sorted(SNAPPERS))
def test_corner_far_outside_the_image_is_kept(name):
    """A quad corner extrapolated beyond the border (a window cut by the frame, a slanted fit), 10 px
    outside: snapped or kept, never an error (a bench run once died on it: harris took the maximum
    of an empty search window)."""
    sw = next(cases(1, 3, 2.0))
    gray = sw[1]
    quad = sw[2].copy()
    quad[0] = (-10.0, quad[0][1])  # within the Harris crop's margin, beyond its search window
    q, _ = snap(name, gray, quad)
    assert q.shape == (4, 2) and np.isfinite(q).all()
    if name in ("harris", "none"):
        assert np.allclose(q[0], quad[0])
