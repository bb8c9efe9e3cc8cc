"""Facade ornament (sills, architraves, shutters) on procedural windows: read back from the IFC
file with ifcopenshell's own geometry, checked against the openings' voids in the facade plane."""
from __future__ import annotations

import ifcopenshell
import ifcopenshell.geom
import numpy as np
import pytest

from fenestra.scenes.generate import HouseSpec, make_house
from fenestra.scenes.loader import load_scene

SQUARE = ((0.0, 0.0), (6.0, 0.0), (6.0, 5.0), (0.0, 5.0))  # axis-aligned: walls known here
ORNATE = dict(seed=4, footprint=SQUARE, storeys=2, windows_per_wall=3, glazed_doors=1,
              curtain_walls=1, curtain_wall_width=1.2)


def _world_vertices(f) -> dict[str, tuple[str, str, np.ndarray]]:
    settings = ifcopenshell.geom.settings()
    settings.set(settings.USE_WORLD_COORDS, True)
    out = {}
    for el in list(f.by_type("IfcMember")) + list(f.by_type("IfcOpeningElement")):
        shape = ifcopenshell.geom.create_shape(settings, el)
        out[el.GlobalId] = (el.is_a(), el.Name, np.array(shape.geometry.verts).reshape(-1, 3))
    return out


def _on_wall(v: np.ndarray, a, b, lo: float, hi: float):
    """(x range along the wall, z range, outward distances) if all of v lies in the wall's slab
    lo..hi m outside its exterior face line a->b (CCW footprint: outward = right), else None."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    u = (b - a) / np.linalg.norm(b - a)
    n = np.array([u[1], -u[0]])
    d = (v[:, :2] - a) @ n
    x = (v[:, :2] - a) @ u
    if d.min() < lo - 1e-6 or d.max() > hi + 1e-6:
        return None
    return (x.min(), x.max()), (v[:, 2].min(), v[:, 2].max()), d


def _overlap(r, s) -> float:
    """Area (m^2) of the intersection of two (x range, z range) rectangles."""
    dx = min(r[0][1], s[0][1]) - max(r[0][0], s[0][0])
    dz = min(r[1][1], s[1][1]) - max(r[1][0], s[1][0])
    return max(dx, 0.0) * max(dz, 0.0)


def test_ornament_members_never_cover_a_void_and_keep_the_windows(tmp_path):
    spec = HouseSpec(**ORNATE, sill_depth=0.15, surround_width=0.1, shutters=True)
    house = make_house(spec, tmp_path / "ornate.ifc")
    plain = make_house(HouseSpec(**ORNATE), tmp_path / "plain.ifc")
    key = lambda h: [(w.name, w.element_id, w.corners_world.tolist()) for w in h.windows]  # noqa: E731
    assert key(house) == key(plain) and len(house.windows) >= 6
    assert [d.element_id for d in house.doors] == [d.element_id for d in plain.doors]

    f = ifcopenshell.open(house.path)
    geo = _world_vertices(f)
    t = spec.wall_thickness
    kinds = {"sill": 0, "surround": 0, "shutter": 0}
    n_voids = 0
    for i in range(len(SQUARE)):
        a, b = SQUARE[i], SQUARE[(i + 1) % len(SQUARE)]
        length = float(np.hypot(b[0] - a[0], b[1] - a[1]))
        voids, parts = [], []
        for cls, name, v in geo.values():
            if cls == "IfcOpeningElement":
                r = _on_wall(v, a, b, -t - 0.1, 0.1)
                if r is not None and -0.01 < r[0][0] and r[0][1] < length + 0.01:
                    voids.append(r)
            elif not name.startswith("CW"):
                r = _on_wall(v, a, b, 0.0, 0.5)
                if r is not None and -0.01 < r[0][0] and r[0][1] < length + 0.01:
                    parts.append((name, r))
        n_voids += len(voids)
        for name, (xr, zr, d) in parts:
            kinds[name.split()[1]] += 1
            assert d.min() == pytest.approx(0.0, abs=1e-6)  # on the face, proud of it
            assert 0.3 < xr[0] and xr[1] < length - 0.3, (name, xr)  # inside the corner margins
            for vr in voids:
                assert _overlap((xr, zr), vr[:2]) < 1e-9, (name, xr, zr, vr[:2])
            if name.split()[1] == "sill":
                assert d.max() == pytest.approx(spec.sill_depth, abs=1e-6)
    members = [m for m in f.by_type("IfcMember") if not m.Name.startswith("CW")]
    assert sum(kinds.values()) == len(members)  # every ornament member was found on a wall
    assert n_voids == len(f.by_type("IfcOpeningElement"))
    assert kinds["sill"] >= len(house.windows) - 1 and kinds["surround"] >= 4 * 4
    assert kinds["shutter"] >= 2
    # the loader's ground truth (IfcWindow fillings) is that of the house without ornament
    gt = lambda p: sorted((w.id, np.round(w.corners_world, 9).tolist())  # noqa: E731
                          for w in load_scene(p, cache_dir=tmp_path / "cache").windows)
    assert gt(house.path) == gt(plain.path)


def test_ornament_off_by_default_writes_nothing_extra(tmp_path):
    default = make_house(HouseSpec(seed=6, storeys=2), tmp_path / "d.ifc")
    explicit = make_house(HouseSpec(seed=6, storeys=2, sill_depth=0.0, surround_width=0.0,
                                    shutters=False), tmp_path / "e.ifc")
    fd, fe = ifcopenshell.open(default.path), ifcopenshell.open(explicit.path)
    assert len(list(fd)) == len(list(fe)) and fd.by_type("IfcMember") == ()
    assert sorted(e.GlobalId for e in fd.by_type("IfcRoot")) \
        == sorted(e.GlobalId for e in fe.by_type("IfcRoot"))


@pytest.mark.parametrize("kw, word", [({"sill_depth": -0.1}, "sill_depth.*-0.1"),
                                      ({"surround_width": 0.5}, "surround_width.*0.5")])
def test_bad_ornament_options_are_rejected(kw, word, tmp_path):
    with pytest.raises(ValueError, match=word):
        make_house(HouseSpec(**kw), tmp_path / "x.ifc")
