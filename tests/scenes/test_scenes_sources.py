"""Every source of a window's void (model.SOURCES) against a house whose truth is known by
construction (scenes.generate): the same house written with the fill relation, without it, with the
holes built into the wall shapes and no openings, and with solid walls; each must give the
generator's rectangles within 1 mm. Plus schemas, tolerant reading and class membership."""
from __future__ import annotations

from pathlib import Path

import ifcopenshell
import ifcopenshell.api
import numpy as np
import pytest

from fenestra.errors import SceneError
from fenestra.scenes.generate import HouseSpec, make_house
from fenestra.scenes.ifc_read import spf_arguments
from fenestra.scenes.loader import load_scene

SPEC = HouseSpec(seed=1, storeys=1, windows_per_wall=1)


@pytest.fixture(scope="module")
def house(tmp_path_factory):
    d = tmp_path_factory.mktemp("sources")
    return make_house(SPEC, d / "with_fill.ifc"), d


def _truth(house) -> dict[str, np.ndarray]:
    return {w.element_id: w.corners_world for w in house.windows}


def _check(scene, house, source: str) -> None:
    truth = _truth(house)
    assert scene.skipped == () and {w.id for w in scene.windows} == set(truth)
    for w in scene.windows:
        assert w.source == source, (w.id, w.source)
        assert np.abs(w.corners_world - truth[w.id]).max() < 1e-3, (source, w.id, w.corners_world, truth[w.id])
        assert abs(w.width - np.linalg.norm(truth[w.id][1] - truth[w.id][0])) < 1e-3


def _without(f, *classes: str) -> None:
    """Remove every relation/element of ``classes`` from an open file."""
    for c in classes:
        for e in list(f.by_type(c)):
            f.remove(e)


def test_fill_and_no_fill_give_the_same_rectangles(house, tmp_path):
    h, d = house
    _check(load_scene(h.path, use_cache=False), h, "fill")
    f = ifcopenshell.open(h.path)
    _without(f, "IfcRelFillsElement")
    f.write(str(tmp_path / "no_fill.ifc"))
    _check(load_scene(tmp_path / "no_fill.ifc", use_cache=False), h, "opening")


def test_hole_built_into_the_wall_shape(house, tmp_path):
    """No openings at all (FreeCAD 0.15): each wall's body is its cut mesh, the hole built in."""
    h, d = house
    cut = {m.global_id: m for m in load_scene(h.path, use_cache=False).meshes}
    f = ifcopenshell.open(h.path)
    body = next(c for c in f.by_type("IfcGeometricRepresentationSubContext") if c.ContextIdentifier == "Body")
    for wall in f.by_type("IfcWall"):
        m = cut[wall.GlobalId]
        rep = ifcopenshell.api.run("geometry.add_mesh_representation", f, context=body,
                                   vertices=[m.vertices.tolist()], faces=[m.faces.tolist()])
        for old in list(wall.Representation.Representations):
            ifcopenshell.api.run("geometry.unassign_representation", f, product=wall, representation=old)
        ifcopenshell.api.run("geometry.assign_representation", f, product=wall, representation=rep)
        ifcopenshell.api.run("geometry.edit_object_placement", f, product=wall, matrix=np.eye(4))
    _without(f, "IfcRelFillsElement", "IfcRelVoidsElement", "IfcOpeningElement")
    f.write(str(tmp_path / "holes.ifc"))
    _check(load_scene(tmp_path / "holes.ifc", use_cache=False), h, "wall_hole")


def test_window_body_in_a_solid_wall(house, tmp_path):
    """No opening and no hole: the window's own body, OverallWidth/Height, on the wall's exterior face."""
    h, d = house
    f = ifcopenshell.open(h.path)
    _without(f, "IfcRelFillsElement", "IfcRelVoidsElement", "IfcOpeningElement")
    f.write(str(tmp_path / "solid.ifc"))
    _check(load_scene(tmp_path / "solid.ifc", use_cache=False), h, "window_body")


def test_ifc4x3_house_gives_the_same_rectangles(tmp_path):
    h = make_house(SPEC, tmp_path / "h4x3.ifc", schema="IFC4X3")
    s = load_scene(h.path, use_cache=False)
    assert s.schema == "IFC4X3"
    _check(s, h, "fill")


def test_older_schema_is_refused_in_one_line(tmp_path):
    p = tmp_path / "old.ifc"
    p.write_text("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('old.ifc','',(''),(''),'','','');\n"
                 "FILE_SCHEMA(('IFC2X_FINAL'));\nENDSEC;\nDATA;\n#1=IFCWINDOW('0abc',$,$,$,$,$,$,$,$,$);\nENDSEC;\n"
                 "END-ISO-10303-21;\n")
    with pytest.raises(SceneError) as e:
        load_scene(p, use_cache=False)
    msg = str(e.value)
    assert "\n" not in msg and "old.ifc" in msg and "IFC2X_FINAL" in msg and "IFC4X3" in msg


def test_derived_star_for_a_name_is_read_as_unset(house, tmp_path):
    """Renga writes `*` for its openings' Name: ifcopenshell's kernel refuses such an opening
    ('Requested type <string> does not match actual type <derived>'); the loader unsets it."""
    h, d = house
    text = Path(h.path).read_text()
    lines = []
    n = 0
    for line in text.splitlines():
        if "=IFCOPENINGELEMENT(" in line:
            args = spf_arguments(line)
            args[2] = "*"  # Name
            line = line[: line.index("(") + 1] + ",".join(args) + ");"
            n += 1
        lines.append(line)
    assert n == len(h.windows)
    p = tmp_path / "star.ifc"
    p.write_text("\n".join(lines) + "\n")
    import ifcopenshell.geom
    raw = ifcopenshell.open(str(p))
    with pytest.raises(RuntimeError, match="derived"):  # what a plain reader meets
        ifcopenshell.geom.create_shape(ifcopenshell.geom.settings(), raw.by_type("IfcOpeningElement")[0])
    _check(load_scene(p, use_cache=False), h, "fill")


def test_spf_arguments_keeps_nested_lists_and_quoted_commas():
    assert spf_arguments("#1=IFCX(a,(b,c),'d,e',*);") == ["a", "(b,c)", "'d,e'", "*"]
