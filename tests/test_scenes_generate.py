"""Procedural houses: the loader's ground truth equals the generator's construction."""
from __future__ import annotations

import time

import numpy as np
import pytest

from fenestra.conventions import TOL
from scenes.generate import HouseSpec, check_footprint, make_house, plan_windows, rotate_xy
from scenes.loader import load_scene


def test_loader_recovers_generated_windows_on_rotated_walls(tmp_path):
    spec = HouseSpec(seed=7, rotation_deg=23.0, reveal_depth=0.12)
    house = make_house(spec, tmp_path / "house.ifc")
    normals = np.array([w.normal for w in house.windows])
    assert np.sum(np.abs(normals[:, :2]).min(axis=1) > 0.1) >= 4  # walls not axis-aligned
    t0 = time.perf_counter()
    scene = load_scene(tmp_path / "house.ifc", cache_dir=tmp_path / "cache")
    load_s = time.perf_counter() - t0
    assert load_s < 5.0, load_s  # ~1 s on the dev machine
    assert scene.skipped == () and len(scene.windows) == len(house.windows) == 5
    by_id = {w.id: w for w in scene.windows}
    for e in house.windows:
        w = by_id[e.window_id]
        assert np.abs(w.corners_world - e.corners_world).max() <= TOL.generator_roundtrip_m
        assert np.abs(w.normal - e.normal).max() <= 1e-9
        assert abs(w.width - e.width) <= TOL.generator_roundtrip_m
        assert abs(w.height - e.height) <= TOL.generator_roundtrip_m
        assert w.ifc_overall_width == pytest.approx(e.width, abs=1e-9)
        assert w.shape == "rectangle" and w.notes == ""


def test_expected_corners_by_construction():
    """Independent of IFC: corner geometry of the plan against the footprint edges."""
    spec = HouseSpec(seed=2, rotation_deg=40.0, storeys=2, windows_per_wall=2)
    poly = rotate_xy(check_footprint(spec.footprint), spec.rotation_deg)
    plan = plan_windows(spec, poly)
    assert len({(w.width, w.height) for w in plan}) == len(plan)  # many sizes / aspect ratios
    for w in plan:
        a, b = poly[w.wall_index], poly[(w.wall_index + 1) % len(poly)]
        u = (b - a) / np.linalg.norm(b - a)
        bl = w.corners_world[3]
        # BL on the exterior face line, inside the wall, at the sill above the storey floor
        d = bl[:2] - a
        assert abs(u[0] * d[1] - u[1] * d[0]) < 1e-9
        assert 0 < (bl[:2] - a) @ u < np.linalg.norm(b - a) - w.width
        assert bl[2] == pytest.approx(w.storey * spec.storey_height + w.sill)
        assert np.linalg.norm(w.corners_world[1] - w.corners_world[0]) == pytest.approx(w.width)
        # outward: the footprint centroid is behind the face
        assert (poly.mean(axis=0) - a) @ w.normal[:2] < 0


@pytest.mark.parametrize("bad, word", [
    ([(0, 0), (1, 0)], "3 points"),
    ([(0, 0), (4, 0), (1, 1), (0, 4)], "convex"),
    ([(0, 0), (1, 0), (2, 0)], "zero area"),
])
def test_bad_footprint_is_rejected(bad, word, tmp_path):
    with pytest.raises(ValueError, match=word):
        make_house(HouseSpec(footprint=tuple(bad)), tmp_path / "x.ifc")


def test_clockwise_footprint_is_reversed():
    cw = [(0, 0), (0, 5), (5, 5), (5, 0)]
    assert np.array_equal(check_footprint(cw), np.array(cw[::-1], dtype=float))
