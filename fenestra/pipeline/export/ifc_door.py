"""model.ifc's doors: each detection the box verifier calls a door, placed on its wall's plane, as an
IfcDoor in its own opening.

Per door (pipeline.export.geometry.PlacedWindow: x along the wall, y up, z outward; its bottom on
its floor: pipeline.export.floors.on_floor)

    IfcOpeningElement  "Door void <d>": the door's rectangle extruded through cladding and wall (as
                       a window's opening), voiding its wall (IfcRelVoidsElement), in no storey
    IfcDoor            PredefinedType DOOR, OverallWidth / OverallHeight the measured size, filling
                       the opening (IfcRelFillsElement), contained in its floor's storey, typed by
                       the file's one IfcDoorType "Door" (PredefinedType DOOR, OperationType
                       NOTDEFINED: a photo does not show which way a door swings); body: lining and
                       panel as swept solids (ifcopenshell.api.geometry.add_door_representation)
                       in the door's own frame (x along the wall, y into it, z up);
                       Qto_DoorBaseQuantities (Width, Height, Area, Perimeter), Pset_DoorCommon
                       (IsExternal) and Fenestra_Door (the detection's score, its wall, ...)

A door whose wall holds no exported window has no IfcWall to void: it is left out with that reason.
"""
from __future__ import annotations

import ifcopenshell
import ifcopenshell.api.feature
import ifcopenshell.api.geometry
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import ifcopenshell.api.type
import numpy as np

from fenestra.pipeline.export.geometry import COVERING_THICKNESS_M, PlacedWindow

# The door's own frame (x along, y into the wall, z up: ifcopenshell's door geometry) in the window
# frame of its placement (x along, y up, z outward).
DOOR_AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def door_matrix(door: PlacedWindow) -> np.ndarray:
    """4x4 door-frame -> export-world placement of ``door`` (origin at its bottom-left corner on
    the photographed plane; :data:`DOOR_AXES`)."""
    local = np.eye(4)
    local[:3, :3] = DOOR_AXES
    return door.export_matrix() @ local


def door_type(f: ifcopenshell.file):
    """The file's IfcDoorType "Door" (made on first use)."""
    for t in f.by_type("IfcDoorType"):
        if t.Name == "Door":
            return t
    dtype = ifcopenshell.api.root.create_entity(f, ifc_class="IfcDoorType", predefined_type="DOOR", name="Door")
    dtype.OperationType = "NOTDEFINED"
    return dtype


def write_door(f: ifcopenshell.file, body, storey, wall, door: PlacedWindow, thickness_m: float,
               props: dict | None, overshoot_m: float) -> dict:
    """The opening voiding ``wall`` and the IfcDoor filling it, in ``storey`` (see the module
    docstring); {"opening", "door": GlobalId, "storey": name, "door_type": name}."""
    from fenestra.pipeline.export.ifc import _add_pset, _add_qto, _rectangle_solid  # noqa: PLC0415 (fenestra.pipeline.export.ifc loads IfcOpenShell: imported when first used)

    T, e = door.export_matrix(), overshoot_m
    w, h = float(door.width_m), float(door.height_m)
    opening = ifcopenshell.api.root.create_entity(f, ifc_class="IfcOpeningElement", name=f"Door void {door.index}")
    ifcopenshell.api.feature.add_feature(f, feature=opening, element=wall)
    ifcopenshell.api.geometry.edit_object_placement(f, product=opening, matrix=T)
    box = _rectangle_solid(f, 0.0, 0.0, w, h, e, (0.0, 0.0, -1.0), COVERING_THICKNESS_M + thickness_m + 2 * e)
    ifcopenshell.api.geometry.assign_representation(
        f, product=opening, representation=f.createIfcShapeRepresentation(body, "Body", "SweptSolid", [box]))
    ifc_door = ifcopenshell.api.root.create_entity(f, ifc_class="IfcDoor", predefined_type="DOOR",
                                                   name=f"Door {door.index}")
    ifc_door.OverallWidth, ifc_door.OverallHeight = w, h
    ifcopenshell.api.feature.add_filling(f, opening=opening, element=ifc_door)
    ifcopenshell.api.spatial.assign_container(f, products=[ifc_door], relating_structure=storey)
    ifcopenshell.api.geometry.edit_object_placement(f, product=ifc_door, matrix=door_matrix(door))
    rep = ifcopenshell.api.geometry.add_door_representation(
        f, context=body, overall_width=w, overall_height=h, operation_type="SINGLE_SWING_LEFT",
        lining_properties={"LiningDepth": min(0.05, float(thickness_m)), "LiningThickness": min(0.05, w / 10)},
        unit_scale=1.0)
    ifcopenshell.api.geometry.assign_representation(f, product=ifc_door, representation=rep)
    dtype = door_type(f)
    ifcopenshell.api.type.assign_type(f, related_objects=[ifc_door], relating_type=dtype)
    ifc_door.PredefinedType = "DOOR"  # assign_type clears it (its type says so too); the occurrence says it as well
    _add_qto(f, ifc_door, "Qto_DoorBaseQuantities", {"Width": w, "Height": h, "Area": w * h, "Perimeter": 2.0 * (w + h)})
    _add_pset(f, ifc_door, "Pset_DoorCommon", {"IsExternal": True})
    if props:
        _add_pset(f, ifc_door, "Fenestra_Door", props)
    return {"opening": opening.GlobalId, "door": ifc_door.GlobalId, "storey": storey.Name, "door_type": dtype.Name}


def write_doors(f: ifcopenshell.file, body, storeys: list, wall_of: dict, doors: list[PlacedWindow],
                door_walls: dict[int, int], floor_of: dict[int, int], thickness_m: float,
                properties: dict[int, dict] | None, overshoot_m: float) -> tuple[dict[int, dict], list[dict]]:
    """Every door of ``doors`` in the IfcWall of its wall id (``door_walls`` {door index: wall id},
    ``wall_of`` {wall id: IfcWall}), contained in ``storeys[floor_of[index]]``: ({door index: ids}
    (:func:`write_door`), skipped [{"index", "reason"}])."""
    ids, skipped = {}, []
    for door in doors:
        wall = wall_of.get(door_walls.get(door.index))
        if wall is None:
            skipped.append({"index": door.index, "reason": "its wall holds no exported window, so the model has no "
                                                          "wall to put the door in"})
            continue
        ids[door.index] = write_door(f, body, storeys[floor_of.get(door.index, 0)], wall, door, thickness_m,
                                     (properties or {}).get(door.index), overshoot_m)
    return ids, skipped
