"""Procedural houses: the loader's ground truth equals the generator's construction."""
from __future__ import annotations

import time
import warnings

import numpy as np
import pytest

from fenestra.tolerances import TOL
from fenestra.scenes.generate import (DEFAULT_FOOTPRINT, HouseSpec, check_footprint, corner_margins,
                             make_house, offset_polygon, plan_windows, rotate_xy)
from fenestra.scenes.loader import load_scene


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


# --------------------------------------------------------------------------- optional parts
def _edges(poly):
    """Per footprint edge: start a (2,), unit direction u (2,), outward normal n (2,), length."""
    out = []
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        u = (b - a) / np.linalg.norm(b - a)
        out.append((a, u, np.array([u[1], -u[0]]), float(np.linalg.norm(b - a))))
    return out


def _on_wall(corners, edge):
    """Do corners (4, 3) lie on the exterior face line of edge, within its length?"""
    a, u, n, length = edge
    d = corners[:, :2] - a
    return np.abs(d @ n).max() < 1e-5 and (d @ u).min() > -1e-5 and (d @ u).max() < length + 1e-5


def _overlap(c1, c2, u):
    """Positive-area overlap of two face rectangles (4, 3) on one wall line (u (2,) along it)."""
    x1, x2 = sorted(c1[:2, :2] @ u), sorted(c2[:2, :2] @ u)
    return (min(x1[1], x2[1]) - max(x1[0], x2[0]) > 1e-9
            and min(c1[0, 2], c2[0, 2]) - max(c1[3, 2], c2[3, 2]) > 1e-9)


def test_all_options_doors_curtain_wall_overhang_fascia(tmp_path):
    import ifcopenshell

    spec = HouseSpec(seed=3, storeys=2, rotation_deg=30.0, roof_overhang=0.6, fascia_height=0.35,
                     glazed_doors=2, curtain_walls=1)
    house = make_house(spec, tmp_path / "house.ifc")
    poly = rotate_xy(check_footprint(spec.footprint), spec.rotation_deg)
    edges = _edges(poly)
    cw = {c.wall_index for c in house.curtain_walls}
    door_walls = {d.wall_index for d in house.doors}
    assert len(cw) == 1 and len(house.curtain_walls) == spec.storeys and len(house.doors) == 2
    assert not cw & door_walls
    # expected windows: the unchanged plan minus the curtain wall's and the doors' (W{i}-0-0)
    plain = plan_windows(HouseSpec(seed=3, storeys=2, rotation_deg=30.0), poly)
    expected = [w for w in plain if w.wall_index not in cw
                and w.name not in {f"W{i}-0-0" for i in door_walls}]
    assert len(expected) == len(plain) - spec.storeys - 2
    made = {w.name: w for w in house.windows}  # make_house lists them storey by storey
    assert sorted(made) == sorted(w.name for w in expected)
    for e in expected:
        assert np.array_equal(e.corners_world, made[e.name].corners_world)

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = load_scene(tmp_path / "house.ifc", cache_dir=tmp_path / "cache")
    assert scene.skipped == () and len(scene.windows) == len(expected)
    by_id = {w.id: w for w in scene.windows}
    for e in house.windows:
        assert np.abs(by_id[e.window_id].corners_world - e.corners_world).max() \
            <= TOL.generator_roundtrip_m
    for g in scene.windows:  # no GT on the curtain wall, none over a door
        wall = [i for i, edge in enumerate(edges) if _on_wall(g.corners_world, edge)]
        assert len(wall) == 1 and wall[0] not in cw
        for d in house.doors:
            assert not (d.wall_index == wall[0] and _overlap(g.corners_world, d.corners_world,
                                                             edges[wall[0]][1]))

    # doors: on storey 0 from the floor, 0.8-2.0 m wide, 2.0-2.4 m high, glazed, in the j=0 slot
    f = ifcopenshell.open(tmp_path / "house.ifc")
    meshes = {m.global_id: m for m in scene.meshes}
    for d in house.doors:
        a, u, n, length = edges[d.wall_index]
        assert d.storey == 0 and 0.8 <= d.width <= 2.0 and 2.0 <= d.height <= 2.4
        assert _on_wall(d.corners_world, edges[d.wall_index])
        assert d.corners_world[3, 2] == 0.0 and d.corners_world[0, 2] == pytest.approx(d.height)
        m = meshes[d.element_id]
        assert m.ifc_class == "IfcDoor" and m.rgba[3] < 0.9  # rendered as glass
        depth = (m.vertices[:, :2] - a) @ n
        assert -depth.min() == pytest.approx(spec.reveal_depth + spec.frame_depth)
        assert m.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-9)
        assert m.vertices[:, 2].max() == pytest.approx(d.height)
    # curtain wall: per storey a void from margin+0.2 m, 0.1 m above the floor to 0.1 m below
    # the top, tiled by 0.02 m glass plates flush with the exterior face, members in front
    assert len(f.by_type("IfcDoor")) == 2 and len(f.by_type("IfcWindow")) == len(expected)
    plates = [m for m in scene.meshes if m.ifc_class == "IfcPlate"]
    members = [m for m in scene.meshes if m.ifc_class == "IfcMember"]
    assert len(plates) == len(f.by_type("IfcPlate")) and len(members) == len(f.by_type("IfcMember"))
    n_cols, rem = divmod(len(plates), 2 * spec.storeys)
    assert rem == 0 and n_cols >= 1
    assert len(members) == spec.storeys * (n_cols + 1 + 3) + len(poly)  # + one fascia per edge
    a, u, n, length = edges[next(iter(cw))]
    for c in house.curtain_walls:
        assert c.width < length - 0.4 and c.height == pytest.approx(spec.storey_height - 0.2)
        assert c.corners_world[3, 2] == pytest.approx(c.storey * spec.storey_height + 0.1)
        mine = [p for p in plates if c.storey * spec.storey_height
                < p.vertices[:, 2].mean() < (c.storey + 1) * spec.storey_height]
        assert len(mine) == 2 * n_cols
        v = np.concatenate([p.vertices for p in mine])
        x0 = (c.corners_world[3, :2] - a) @ u
        assert ((v[:, :2] - a) @ u).min() == pytest.approx(x0)
        assert ((v[:, :2] - a) @ u).max() == pytest.approx(x0 + c.width)
        assert v[:, 2].min() == pytest.approx(c.corners_world[3, 2])
        assert v[:, 2].max() == pytest.approx(c.corners_world[0, 2])
        assert ((v[:, :2] - a) @ n).max() == pytest.approx(0.0, abs=1e-9)
        assert ((v[:, :2] - a) @ n).min() == pytest.approx(-0.02)
        assert sum(np.ptp(p.vertices @ np.append(u, 0)) * np.ptp(p.vertices[:, 2]) for p in mine) \
            == pytest.approx(c.width * c.height)
        assert all(p.rgba[3] < 0.9 for p in mine)
    mull = np.concatenate([m.vertices for m in members if not m.name.startswith("Fascia")])
    assert ((mull[:, :2] - a) @ n).max() == pytest.approx(0.03)

    # roof overhang and fascia, measured on the loaded meshes
    roof = next(m for m in scene.meshes if m.name == "Roof")
    fascia = np.concatenate([m.vertices for m in members if m.name.startswith("Fascia")])
    top = spec.storeys * spec.storey_height + spec.slab_thickness
    for a, u, n, length in edges:
        assert ((roof.vertices[:, :2] - a) @ n).max() == pytest.approx(spec.roof_overhang,
                                                                        abs=1e-6)
        assert ((fascia[:, :2] - a) @ n).max() == pytest.approx(spec.roof_overhang + 0.04,
                                                                 abs=1e-6)
    assert fascia[:, 2].min() == pytest.approx(top - spec.fascia_height)
    assert fascia[:, 2].max() == pytest.approx(top)
    assert all(max(m.rgba[:3]) <= 0.35 for m in members if m.name.startswith("Fascia"))
    data = house.to_json()
    assert len(data["doors"]) == 2 and len(data["curtain_walls"]) == spec.storeys
    assert data["doors"][0]["id"] == house.doors[0].element_id


def test_options_off_change_nothing(tmp_path):
    spec = HouseSpec(seed=5, storeys=2, windows_per_wall=2, rotation_deg=12.0)
    explicit = HouseSpec(seed=5, storeys=2, windows_per_wall=2, rotation_deg=12.0,
                         roof_overhang=0.0, fascia_height=0.0, glazed_doors=0, curtain_walls=0)
    poly = rotate_xy(check_footprint(spec.footprint), spec.rotation_deg)
    plan = plan_windows(spec, poly)
    assert [(w.name, w.corners_world.tolist()) for w in plan] \
        == [(w.name, w.corners_world.tolist()) for w in plan_windows(explicit, poly)]
    house = make_house(explicit, tmp_path / "h.ifc")
    assert house.doors == () and house.curtain_walls == ()
    assert sorted((w.name, w.corners_world.tolist()) for w in house.windows) \
        == sorted((w.name, w.corners_world.tolist()) for w in plan)
    # the window stream is the same with every option on: only removed windows differ
    on = make_house(HouseSpec(seed=5, storeys=2, windows_per_wall=2, rotation_deg=12.0,
                              glazed_doors=1, curtain_walls=2, roof_overhang=0.3),
                    tmp_path / "on.ifc")
    same = {w.name: w.corners_world.tolist() for w in plan}
    assert 0 < len(on.windows) < len(plan)
    assert all(same[w.name] == w.corners_world.tolist() for w in on.windows)


def test_offset_polygon_moves_every_edge_outward():
    square = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    assert np.allclose(offset_polygon(square, 0.5),
                       [[-0.5, -0.5], [4.5, -0.5], [4.5, 4.5], [-0.5, 4.5]])
    poly = rotate_xy(check_footprint(DEFAULT_FOOTPRINT), 30.0)
    off = offset_polygon(poly, 0.7)
    for (a, u, n, _), (b, v, m, _) in zip(_edges(poly), _edges(off)):
        assert np.allclose(u, v) and (b - a) @ n == pytest.approx(0.7)


@pytest.mark.parametrize("kw, word", [
    ({"roof_overhang": -0.1}, "roof_overhang.*-0.1"),
    ({"roof_overhang": 2.5}, "roof_overhang.*2.5"),
    ({"fascia_height": -0.2}, "fascia_height.*-0.2"),
    ({"glazed_doors": -1}, "glazed_doors.*-1"),
    ({"glazed_doors": 6}, "glazed_doors=6"),
    ({"glazed_doors": 1, "storey_height": 2.0}, "glazed_doors=1.*storey_height"),
    ({"curtain_walls": 6}, "curtain_walls.*6"),
    ({"curtain_walls": -1}, "curtain_walls.*-1"),
    ({"curtain_walls": 1, "curtain_wall_rows": 0}, "curtain_wall_rows.*0"),
    ({"curtain_walls": 1, "curtain_wall_width": 0.2}, "curtain_wall_width.*0.2"),
])
def test_bad_options_are_rejected(kw, word, tmp_path):
    with pytest.raises(ValueError, match=word):
        make_house(HouseSpec(**kw), tmp_path / "x.ifc")


def test_curtain_wall_strip_keeps_other_windows(tmp_path):
    """A 1.6 m curtain-wall strip with 3 panel rows: on its wall, inside the free length, only the
    windows overlapping it (0.3 m clearance) dropped; the loaded ground truth has no window on it."""
    spec = HouseSpec(seed=11, storeys=2, windows_per_wall=3, width_range=(0.4, 0.8),
                     curtain_walls=1, curtain_wall_width=1.6, curtain_wall_rows=3)
    house = make_house(spec, tmp_path / "strip.ifc")
    poly = rotate_xy(check_footprint(spec.footprint), spec.rotation_deg)
    edges = _edges(poly)
    (i,) = {c.wall_index for c in house.curtain_walls}
    a, u, n, length = edges[i]
    margin = corner_margins(poly, spec.wall_thickness)[i]
    plain = plan_windows(HouseSpec(seed=11, storeys=2, windows_per_wall=3, width_range=(0.4, 0.8)),
                         poly)
    made = {w.name for w in house.windows}
    c = house.curtain_walls[0]
    x0 = float((c.corners_world[3, :2] - a) @ u)
    assert c.width == pytest.approx(1.6)
    assert margin[0] + 0.2 - 1e-9 <= x0 and x0 + c.width <= length - margin[1] - 0.2 + 1e-9
    kept_on_wall = 0
    for w in plain:  # independent interval test along the wall
        xs = sorted(float((p[:2] - a) @ u) for p in w.corners_world[:2])
        hit = w.wall_index == i and xs[0] < x0 + c.width + 0.3 and x0 < xs[1] + 0.3
        assert (w.name in made) == (not hit), w.name
        kept_on_wall += w.wall_index == i and not hit
    assert kept_on_wall > 0  # a strip, not the whole wall
    scene = load_scene(tmp_path / "strip.ifc", cache_dir=tmp_path / "cache")
    assert len(scene.windows) == len(made)
    plates = [m for m in scene.meshes if m.ifc_class == "IfcPlate"]
    assert len(plates) % (3 * spec.storeys) == 0  # 3 rows per storey
    for g in scene.windows:
        if _on_wall(g.corners_world, edges[i]):
            assert not _overlap(g.corners_world, c.corners_world, u)


def test_same_spec_same_global_ids(tmp_path):
    """GlobalIds are drawn from the spec's seed: two generations give the same window ids."""
    import ifcopenshell

    spec = HouseSpec(seed=4, storeys=1, windows_per_wall=1)
    a, b = make_house(spec, tmp_path / "a.ifc"), make_house(spec, tmp_path / "b.ifc")
    assert [w.element_id for w in a.windows] == [w.element_id for w in b.windows]
    ids = [sorted(e.GlobalId for e in ifcopenshell.open(str(p)).by_type("IfcRoot")) for p in (a.path, b.path)]
    assert ids[0] == ids[1] and len(set(ids[0])) == len(ids[0]) > 10
    other = make_house(HouseSpec(seed=5, storeys=1, windows_per_wall=1), tmp_path / "c.ifc")
    assert not set(w.element_id for w in other.windows) & set(w.element_id for w in a.windows)
