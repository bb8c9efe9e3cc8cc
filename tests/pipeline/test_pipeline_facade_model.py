"""pipeline.facade_model: one plane and one scale per wall, merged walls, implausible windows
flagged (issue 24 items 3 and 4). Truth: windows placed on a known façade plane; the wall fit's
per-window scale ambiguity is reproduced by scaling each about the camera centre (same image)."""
from __future__ import annotations

import numpy as np
import pytest

from fenestra.conventions import look_at, project
from fenestra.pipeline.facade_model import DEFAULT_WINDOW_HEIGHT_M, FLAG_WIDEN, Known, facade_model
from fenestra.pipeline.types import Uncertainty, WindowResult

# a façade plane z = 0 (world), x along the wall, y up; seen obliquely from 12 m
R_W, T_W = look_at(np.array([4.0, 1.5, 12.0]), np.array([0.0, 3.0, 0.0]), up=(0.0, 1.0, 0.0))
K = np.array([[1000.0, 0, 640], [0, 1000.0, 480], [0, 0, 1]])
# (x0, y0, w, h) m on the façade: two rows of windows, 1.2 x 1.6 m, storey pitch 3.2 m
TRUE = [(-4.0, 1.0, 1.2, 1.6), (-1.0, 1.0, 1.2, 1.6), (2.0, 1.0, 1.2, 1.6),
        (-4.0, 4.2, 1.2, 1.6), (-1.0, 4.2, 1.2, 1.6), (2.0, 4.2, 1.2, 1.6)]
UNC = Uncertainty(level=0.9, sigma_px=0.5, aspect_sd=0.01, aspect_lo=0.73, aspect_hi=0.77, rot_deg=1.0,
                  trans_rel=0.02, ill_conditioned=False)


def _window(i: int, x0: float, y0: float, w: float, h: float, s: float, wall: int | None = 0, R_F=np.eye(3)):
    """WindowResult of a true window (façade frame R_F, world) scaled by s about the camera centre,
    fitted in the joint fit's wall group ``wall``."""
    R = R_W @ R_F  # window frame -> camera: x along the wall, y up, z outward (towards +z world)
    t = R_W @ (R_F @ np.array([x0, y0, 0.0])) + T_W
    q = project(K, R, t, np.array([[0, h, 0], [w, h, 0], [w, 0, 0], [0, 0, 0]], dtype=float))
    return WindowResult(i, 0.9, q, q, w / h, "general", None, R, t * s, h * s, q, None, group=wall,
                        uncertainty=UNC)


def _scrambled(true=TRUE, seed=0):
    """The wall fit's answer: every window the same height (1 m), so each at its own depth."""
    rng = np.random.default_rng(seed)
    return [_window(i, *p, s=1.0 / p[3] * rng.uniform(0.8, 1.0)) for i, p in enumerate(true)]


def _centre(r):
    return np.asarray(r.t) + np.asarray(r.R) @ np.array([r.aspect_ratio * r.height_m / 2, r.height_m / 2, 0.0])


@pytest.mark.parametrize("known, source", [(Known(window_height_m=1.6), "known window height"),
                                           (Known(window_width_m=1.2), "known window width"),
                                           (Known(storey_m=3.2), "known storey height")])
def test_one_plane_and_one_scale_per_wall_recover_the_true_facade(known, source):
    results, model = facade_model(_scrambled(), known)
    assert len(model.walls) == 1 and model.walls[0].scale_source.startswith(source) and not model.walls[0].assumed
    assert not model.flags
    for r, (x0, y0, w, h) in zip(results, TRUE):
        truth = R_W @ np.array([x0 + w / 2, y0 + h / 2, 0.0]) + T_W
        assert np.allclose(_centre(r), truth, atol=1e-6) and r.height_m == pytest.approx(h)
        corners = np.array([[0, r.height_m, 0], [r.aspect_ratio * r.height_m, 0, 0]])
        assert np.allclose(project(K, r.R, r.t, corners), r.quad_reprojected[[0, 2]], atol=1e-6)  # same image
    n = R_W[:, 2]
    d = [float(n @ _centre(r)) for r in results]
    assert np.ptp(d) < 1e-9  # one plane


def test_without_known_the_scale_is_assumed_and_says_so():
    results, model = facade_model(_scrambled(), Known())
    assert model.walls[0].assumed and "assumed" in model.walls[0].scale_source
    assert np.median([r.height_m for r in results]) == pytest.approx(DEFAULT_WINDOW_HEIGHT_M)


def test_walls_with_the_same_rotation_merge_and_a_corner_wall_does_not():
    side = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # the wall at 90 deg: x along -z, facing +x (the camera)
    ws = [_window(i, *p, s=1.0, wall=0 if i < 3 else 1) for i, p in enumerate(TRUE)]
    ws += [_window(6, 1.0, 1.0, 1.2, 1.6, 1.0, wall=2, R_F=side), _window(7, 3.0, 1.0, 1.2, 1.6, 1.0, wall=2, R_F=side)]
    results, model = facade_model(ws, Known(window_height_m=1.6))
    assert [w.members for w in model.walls] == [(0, 1, 2, 3, 4, 5), (6, 7)]
    assert model.walls[0].merged_from == (0, 1) and [model.wall_of(r.index).id for r in results] == [0] * 6 + [1, 1]
    assert not model.flags  # a right-angle corner is a façade, not an implausible plane


def test_implausible_windows_are_flagged_with_reasons_and_wider_error_bars():
    true = TRUE + [(-3.0, 0.2, 6.0, 0.8), (0.0, 7.0, 0.3, 9.0), (-4.0, 7.5, 1.2, 0.05)]  # sign, pole, sliver
    results, model = facade_model(_scrambled(true), Known(window_height_m=1.6))
    assert set(model.flags) == {6, 7, 8}
    assert any("unlike its wall's other windows (width/height 7.50 against 0.75)" in f for f in model.flags[6])
    assert any(f.startswith("its shape is no window's (width/height 24.00") for f in model.flags[8])  # w/h 24
    assert any(f.startswith("its shape") or f.startswith("its height") or f.startswith("too ") for f in model.flags[7])
    for k in (6, 7, 8):
        u = results[k].uncertainty
        assert u.aspect_hi - u.aspect_lo == pytest.approx(FLAG_WIDEN * (UNC.aspect_hi - UNC.aspect_lo))
        assert 0.5 * (u.aspect_hi + u.aspect_lo) == pytest.approx(0.5 * (UNC.aspect_hi + UNC.aspect_lo))
        assert u.rot_deg == pytest.approx(FLAG_WIDEN * UNC.rot_deg) and u.widened == FLAG_WIDEN
        assert u.trans_rel == pytest.approx(FLAG_WIDEN * UNC.trans_rel) and u.aspect_sd == pytest.approx(0.03)
        assert u.to_json() == {**UNC.to_json(), "aspect_sd": u.aspect_sd, "aspect_lo": u.aspect_lo,
                               "aspect_hi": u.aspect_hi, "rot_deg": u.rot_deg, "trans_rel": u.trans_rel,
                               "widened": FLAG_WIDEN}  # windows.json: the same keys, widened last
    assert results[0].uncertainty == UNC and "widened" not in UNC.to_json()  # plausible ones keep theirs


def test_known_takes_one_positive_size():
    with pytest.raises(ValueError, match="at most one"):
        Known(window_width_m=1.0, window_height_m=1.5)
    with pytest.raises(ValueError, match=r"Known.storey_m must be a length in m within the physical range \[1, 50\]"):
        Known(storey_m=-3.0)


def test_a_lone_window_near_the_facade_joins_it_and_a_lone_one_off_plane_is_flagged():
    tilt = np.array([[np.cos(0.14), 0, np.sin(0.14)], [0, 1, 0], [-np.sin(0.14), 0, np.cos(0.14)]])  # 8 deg
    side = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # 90 deg, facing the camera
    ws = [_window(i, *p, s=1.0, wall=0) for i, p in enumerate(TRUE)]
    ws += [_window(6, -2.0, 7.0, 1.2, 1.6, 1.0, wall=1, R_F=tilt), _window(7, 1.0, 1.0, 1.2, 1.6, 1.0, wall=2, R_F=side)]
    results, model = facade_model(ws, Known(window_height_m=1.6))
    assert [w.members for w in model.walls] == [(0, 1, 2, 3, 4, 5, 6), (7,)]
    assert list(model.flags) == [7] and model.flags[7][0] == "it stands alone in a plane at 90° to the façade"


def test_bad_boxes_do_not_set_the_scale_nor_flag_the_clean_windows():
    """Issue 35 (img_498): boxes over two windows at once and over a shop front set the wall's
    medians, so the clean windows were flagged and a 7 m "window" exported. The scale and the
    medians now come from the typical windows (plausible shape, agreeing with each other): the
    clean windows keep the assumed 1.5 m height exactly, every bad box is flagged."""
    true = [(-4.0, 4.2, 1.2, 1.6), (-1.0, 4.2, 1.2, 1.6),  # clean windows, w/h 0.75
            (-4.0, 7.4, 3.4, 1.6), (-0.2, 7.4, 3.4, 1.6),  # two windows in one box each, w/h 2.125
            (-4.5, 0.3, 7.0, 3.5)]  # a shop front, w/h 2
    results, model = facade_model(_scrambled(true), Known())
    assert len(model.walls) == 1 and model.walls[0].assumed
    assert set(model.flags) == {2, 3, 4}
    k = DEFAULT_WINDOW_HEIGHT_M / 1.6  # the scale the clean windows set: true size x k
    for r, (_, _, w, h) in zip(results, true):
        assert r.height_m == pytest.approx(h * k) and r.aspect_ratio * r.height_m == pytest.approx(w * k)
    assert any("against 0.75)" in f for f in model.flags[2])
    assert any(f.startswith("too wide for a window (6.6 m, more than 4.0 m") for f in model.flags[4])  # 7.0 x 1.5 / 1.6


def test_a_window_taller_than_the_known_storey_is_flagged():
    """--known-storey 3.2: the rows' pitch sets the scale (the true one here), and a 3.5 m tall box
    on the ground floor (taller than a storey: issue 35, img_481 / img_294) is flagged, the others not."""
    true = TRUE + [(5.0, 1.0, 1.4, 3.5)]
    results, model = facade_model(_scrambled(true), Known(storey_m=3.2))
    assert model.walls[0].scale_source.startswith("known storey height") and not model.walls[0].assumed
    for r, (_, _, _, h) in zip(results, true):
        assert r.height_m == pytest.approx(h)  # the true scale: pitch 3.2 m between the rows
    assert list(model.flags) == [6]
    assert "too tall for a window (3.5 m, more than 3.2 m: the known storey, 3.2 m)" in model.flags[6]


def test_typical_members_is_the_largest_agreeing_set_of_plausible_shapes():
    from fenestra.pipeline.facade_model import typical_members  # noqa: PLC0415

    a = np.array([0.75, 0.7, 2.1, 0.8, 0.72, 0.1])  # a wide box and a sliver: not window-shaped
    h = np.array([1.0, 1.1, 1.0, 3.0, 0.95, 1.0])  # the third window-shaped one is three times taller
    assert typical_members(a, h).tolist() == [0, 1, 4]
    assert typical_members(np.array([3.0, 0.1]), np.array([1.0, 1.0])).tolist() == [0, 1]  # none: all


def test_rows_that_are_not_a_storey_apart_do_not_take_the_storey_height():
    """Two rows 1.9 m apart of 1.6 m windows (a high and a low row of one storey, or a basement row):
    a 3.2 m storey would make the windows 2.7 m tall (0.84 of the storey), so the wall keeps the
    assumed height and says why; rows 3.2 m apart take it (the true scale)."""
    close = [(x, y if y < 2 else 2.9, w, h) for x, y, w, h in TRUE]
    results, model = facade_model(_scrambled(close), Known(storey_m=3.2))
    wall = model.walls[0]
    assert wall.assumed and "not a storey apart" in wall.scale_source and "2.69 m tall" in wall.scale_source
    assert float(np.median([r.height_m for r in results])) == pytest.approx(DEFAULT_WINDOW_HEIGHT_M)
    results, model = facade_model(_scrambled(), Known(storey_m=3.2))
    assert not model.walls[0].assumed and results[0].height_m == pytest.approx(1.6)
