"""IFC4 export: per fitted wall one photo-textured IfcWall, per window its opening and an IfcWindow.

World frame and units: see fenestra/pipeline/export/geometry.py (metres; camera at the origin, z up,
looking along +y). Per fitted wall (``walls``; else per window) the file holds

    IfcWall            closed, gridded IfcTriangulatedFaceSet slab (its voids' extent + margin, 0.30 m thick) with an
                       IfcIndexedTriangleTextureMap into texture.png (IfcImageTexture, relative URL),
                       styled by an IfcSurfaceStyle with IfcSurfaceStyleWithTextures
    IfcOpeningElement  the void box, voiding the wall (IfcRelVoidsElement)
    IfcWindow          OverallWidth/OverallHeight = void size, frame + glass body from the
                       catalogue (scaled down to fit a small void), filling the opening
                       (IfcRelFillsElement); Pset_WindowCommon (IsExternal) and Fenestra_Window
                       (confidence, aspect interval, K source, scale source, ...) when given

all placed by the window-frame -> world matrix, inside project / site / building / storey.
"""
from __future__ import annotations

from pathlib import Path

import ifcopenshell
import ifcopenshell.api.aggregate
import ifcopenshell.api.context
import ifcopenshell.api.feature
import ifcopenshell.api.geometry
import ifcopenshell.api.project
import ifcopenshell.api.pset
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import ifcopenshell.api.style
import ifcopenshell.api.unit
import numpy as np

from fenestra.pipeline.catalogue import WindowStyle, box_mesh, get_style, window_mesh
from fenestra.pipeline.export.geometry import (WALL_MARGIN_M, WALL_THICKNESS_M, PlacedWindow, TextureLayout,
                                      facade_pixels, hole_in, void_hole, wall_groups, wall_margin_m,
                                      wall_mesh)

OPENING_OVERSHOOT_M = 0.01  # the opening box pokes out of both wall faces (clean booleans)


def _faceset(f: ifcopenshell.file, vertices: np.ndarray, faces: np.ndarray):
    """Closed IfcTriangulatedFaceSet from (N, 3) m vertices and (M, 3) 0-based faces."""
    pts = f.createIfcCartesianPointList3D([tuple(map(float, v)) for v in vertices])
    idx = [tuple(int(i) + 1 for i in tri) for tri in faces]
    return f.createIfcTriangulatedFaceSet(pts, None, True, idx, None)


def _colour_style(f: ifcopenshell.file, name: str, rgb, transparency: float = 0.0):
    colour = f.createIfcColourRgb(None, *map(float, rgb))
    rendering = f.createIfcSurfaceStyleRendering(colour, float(transparency), None, None, None, None,
                                                 None, None, "NOTDEFINED")
    return f.createIfcSurfaceStyle(name, "BOTH", [rendering])


def _body(f, context, items):
    return f.createIfcShapeRepresentation(context, "Body", "Tessellation", items)


def _new_file(name: str):
    """An IFC4 file with project (metres), site, building, storey; returns (file, body context, storey)."""
    f = ifcopenshell.api.project.create_file(version="IFC4")
    project = ifcopenshell.api.root.create_entity(f, ifc_class="IfcProject", name=name)
    units = [ifcopenshell.api.unit.add_si_unit(f, unit_type=u) for u in ("LENGTHUNIT", "AREAUNIT", "VOLUMEUNIT")]
    units.append(ifcopenshell.api.unit.add_si_unit(f, unit_type="PLANEANGLEUNIT"))
    ifcopenshell.api.unit.assign_unit(f, units=units)
    model = ifcopenshell.api.context.add_context(f, context_type="Model")
    body = ifcopenshell.api.context.add_context(f, context_type="Model", context_identifier="Body",
                                                target_view="MODEL_VIEW", parent=model)
    site = ifcopenshell.api.root.create_entity(f, ifc_class="IfcSite", name="Site")
    building = ifcopenshell.api.root.create_entity(f, ifc_class="IfcBuilding", name="Photographed building")
    storey = ifcopenshell.api.root.create_entity(f, ifc_class="IfcBuildingStorey", name="Facade")
    ifcopenshell.api.aggregate.assign_object(f, products=[site], relating_object=project)
    ifcopenshell.api.aggregate.assign_object(f, products=[building], relating_object=site)
    ifcopenshell.api.aggregate.assign_object(f, products=[storey], relating_object=building)
    for spatial in (site, building, storey):
        ifcopenshell.api.geometry.edit_object_placement(f, product=spatial, matrix=np.eye(4))
    return f, body, storey


def _add_pset(f: ifcopenshell.file, product, name: str, values: dict) -> None:
    """A property set on ``product`` with the values that are not None (bool, int, float, str)."""
    values = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in values.items() if v is not None}
    if values:
        pset = ifcopenshell.api.pset.add_pset(f, product=product, name=name)
        ifcopenshell.api.pset.edit_pset(f, pset=pset, properties=values)


def _textured_wall(f, body, storey, K, wall_pw: PlacedWindow, voids: list, name: str, layout: TextureLayout,
                   texture, wall_style, margin_m: float, thickness_m: float):
    """One IfcWall: a closed gridded slab (wall_pw's rectangle + margin_m, its windows' ``voids``
    on grid lines for the openings' booleans) textured from the photo."""
    V, F = wall_mesh(wall_pw, voids, False, margin_m, thickness_m)
    wall_items = _faceset(f, V, F)
    uv = layout.uv(facade_pixels(K, wall_pw, V[:, :2]))
    tex_vertices = f.createIfcTextureVertexList([tuple(map(float, p)) for p in uv])
    f.createIfcIndexedTriangleTextureMap([texture], wall_items, tex_vertices,
                                         [tuple(int(i) + 1 for i in tri) for tri in F])
    ifcopenshell.api.style.assign_item_style(f, item=wall_items, style=wall_style)
    wall = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWall", name=name)
    ifcopenshell.api.spatial.assign_container(f, products=[wall], relating_structure=storey)
    ifcopenshell.api.geometry.edit_object_placement(f, product=wall, matrix=wall_pw.export_matrix())
    ifcopenshell.api.geometry.assign_representation(f, product=wall, representation=_body(f, body, [wall_items]))
    return wall


def write_ifc(path: str | Path, K: np.ndarray, placed: list[PlacedWindow], layout: TextureLayout,
              texture_file: str = "texture.png", style: str | WindowStyle = "casement-white",
              margin_m: float = WALL_MARGIN_M, thickness_m: float = WALL_THICKNESS_M,
              walls: dict[int, int] | None = None, properties: dict[int, dict] | None = None,
              wall_properties: dict[int, dict] | None = None) -> dict[int, dict]:
    """Write model.ifc for the placed windows; return {window index: {"wall", "opening", "window": GlobalId}}.

    ``texture_file`` is the texture's path relative to the IFC file (written by the caller).
    walls: {window index: wall id}: one IfcWall per wall id spanning its windows (margin: see
    geometry.wall_margin_m), each window's opening voiding it; None (or a window without an id):
    a wall fragment per window. properties: {window index: {name: value}}, written as the
    window's property set "Fenestra_Window" (with Pset_WindowCommon IsExternal); wall_properties:
    {wall id: {name: value}} as "Fenestra_Wall".
    """
    style = get_style(style)
    f, body, storey = _new_file("Fenestra reconstruction")
    texture = f.createIfcImageTexture(False, False, "DIFFUSE", None, None, str(texture_file))
    wall_style = f.createIfcSurfaceStyle(
        "Photo texture", "BOTH",
        [f.createIfcSurfaceStyleShading(f.createIfcColourRgb(None, 0.8, 0.8, 0.8), 0.0),
         f.createIfcSurfaceStyleWithTextures([texture])])
    frame_style = _colour_style(f, f"{style.name} frame", style.frame_rgb)
    glass_style = _colour_style(f, f"{style.name} glass", style.glass_rgb, 1.0 - style.glass_alpha)

    ids: dict[int, dict] = {}
    for wall_pw, members in wall_groups(placed, walls):
        own = len(members) == 1 and wall_pw is members[0]
        voids = [void_hole(wall_pw)] if own else [hole_in(wall_pw, pw) for pw in members]
        wall = _textured_wall(f, body, storey, K, wall_pw, voids, f"Wall {wall_pw.index}", layout, texture, wall_style,
                              margin_m if own else wall_margin_m(members, margin_m), thickness_m)
        if not own and wall_properties and wall_pw.index in wall_properties:
            _add_pset(f, wall, "Fenestra_Wall", wall_properties[wall_pw.index])
        for pw in members:
            ids[pw.index] = _window_in_wall(f, body, storey, wall, pw, style, frame_style, glass_style, thickness_m,
                                            (properties or {}).get(pw.index))
    f.write(str(path))
    return ids


def _window_in_wall(f, body, storey, wall, pw: PlacedWindow, style: WindowStyle, frame_style, glass_style,
                    thickness_m: float, props: dict | None) -> dict:
    """The opening voiding ``wall`` (IfcRelVoidsElement) and the IfcWindow filling it
    (IfcRelFillsElement), catalogue frame + glass (scaled to fit a small void), with its psets."""
    T = pw.export_matrix()
    e = OPENING_OVERSHOOT_M
    OV, OF = box_mesh([0.0, 0.0, -thickness_m - e], [pw.width_m, pw.height_m, e])
    opening = ifcopenshell.api.root.create_entity(f, ifc_class="IfcOpeningElement", name=f"Void {pw.index}")
    ifcopenshell.api.feature.add_feature(f, feature=opening, element=wall)
    ifcopenshell.api.geometry.edit_object_placement(f, product=opening, matrix=T)
    ifcopenshell.api.geometry.assign_representation(f, product=opening,
                                                    representation=_body(f, body, [_faceset(f, OV, OF)]))
    mesh = window_mesh(style, pw.width_m, pw.height_m)
    items = []
    for part, part_style in (("frame", frame_style), ("glass", glass_style)):
        item = _faceset(f, *mesh.select(part))
        ifcopenshell.api.style.assign_item_style(f, item=item, style=part_style)
        items.append(item)
    window = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWindow", predefined_type="WINDOW",
                                                 name=f"Window {pw.index} ({style.name})")
    window.OverallWidth, window.OverallHeight = float(pw.width_m), float(pw.height_m)
    ifcopenshell.api.feature.add_filling(f, opening=opening, element=window)
    ifcopenshell.api.spatial.assign_container(f, products=[window], relating_structure=storey)
    ifcopenshell.api.geometry.edit_object_placement(f, product=window, matrix=T)
    ifcopenshell.api.geometry.assign_representation(f, product=window, representation=_body(f, body, items))
    if props is not None:
        _add_pset(f, window, "Pset_WindowCommon", {"IsExternal": True})
        _add_pset(f, window, "Fenestra_Window", props)
    return {"wall": wall.GlobalId, "opening": opening.GlobalId, "window": window.GlobalId}
