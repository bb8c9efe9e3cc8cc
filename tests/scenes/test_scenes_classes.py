"""Every subclass like its parent (issue 47, item 5): StandardCase windows and walls load, and take
materials, as IfcWindow / IfcWall; spatial, virtual and annotation elements are never meshed."""
from __future__ import annotations

import ifcopenshell
import ifcopenshell.api
import ifcopenshell.util.schema
import numpy as np

from fenestra.renders.materials import group_scene, material_key, sample_look
from fenestra.scenes.generate import HouseSpec, make_house
from fenestra.scenes.loader import load_scene

API = ifcopenshell.api.run


def _box(f, body, ifc_class: str, origin):
    el = API("root.create_entity", f, ifc_class=ifc_class, name=f"a {ifc_class}")
    rep = API("geometry.add_wall_representation", f, context=body, length=2.0, height=2.0, thickness=0.5)
    API("geometry.assign_representation", f, product=el, representation=rep)
    m = np.eye(4)
    m[:3, 3] = origin
    API("geometry.edit_object_placement", f, product=el, matrix=m)
    return el


def test_standard_case_and_spatial_classes(tmp_path):
    h = make_house(HouseSpec(seed=2, windows_per_wall=1, window_styles=("mullion",)), tmp_path / "h.ifc")
    f = ifcopenshell.open(h.path)
    body = next(c for c in f.by_type("IfcGeometricRepresentationSubContext") if c.ContextIdentifier == "Body")
    win = f.by_type("IfcWindow")[0]
    win_id = win.GlobalId
    ifcopenshell.util.schema.reassign_class(f, win, "IfcWindowStandardCase")
    wall = f.by_type("IfcWall")[0]
    ifcopenshell.util.schema.reassign_class(f, wall, "IfcWallStandardCase")
    hidden = [_box(f, body, c, (3.0, 3.0, 0.5)).GlobalId
              for c in ("IfcVirtualElement", "IfcExternalSpatialElement", "IfcSpace", "IfcAnnotation")]
    f.write(str(tmp_path / "classes.ifc"))
    plain = load_scene(h.path, use_cache=False)
    s = load_scene(tmp_path / "classes.ifc", use_cache=False)
    meshes = {m.global_id: m for m in s.meshes}
    assert not set(hidden) & set(meshes)  # never meshed, never occluders
    assert meshes[win_id].ifc_class == "IfcWindowStandardCase" and meshes[win_id].kind == "IfcWindow"
    assert meshes[wall.GlobalId].kind == "IfcWall"
    # the same windows, the same rectangles, as with the parent classes
    assert {w.id: w.corners_world.round(9).tolist() for w in s.windows} == \
        {w.id: w.corners_world.round(9).tolist() for w in plain.windows}
    # materials: the StandardCase window is frame and glass like an IfcWindow, the wall a wall
    by_key = {m.global_id: material_key(m) for m in plain.meshes}
    assert {m.global_id: material_key(m) for m in s.meshes} == by_key
    groups = group_scene(s, sample_look(np.random.default_rng(0)), np.random.default_rng(0))
    # split into frame and glass panes as an IfcWindow is (a StandardCase one was one glass lump)
    assert {g.material.name for g in groups if win_id in g.element_ids} == {"frame", "glass"}
    assert all(g.is_window for g in groups if win_id in g.element_ids)
