"""Floors and doors of model.ifc: storeys are the main wall's floors (not every row of windows), doors
are IfcDoors in their own openings on the ground floor, signboards stay out.

Ground truth: a level camera looking at façades whose windows sit at known sills (the export world's
z is the façade's height: a window frame with y up maps to camera -y, and CAMERA_TO_EXPORT maps that
to z), so every floor's elevation, name and every window's floor are written down here from the
construction, never computed with the code under test. The IFC model is read back with ifcopenshell.
"""
from __future__ import annotations

import json

import ifcopenshell
import ifcopenshell.util.element
import ifcopenshell.util.placement
import ifcopenshell.validate
import numpy as np
import pytest

from fenestra.conventions import ASSUMED_STOREY_M, K_from_fov, MIN_STOREY_M, look_at
from fenestra.pipeline.export import write_outputs
from fenestra.pipeline.export.floors import filled, floor_levels, floor_rows, grounded_floors
from fenestra.pipeline.export.geometry import SILL_HEIGHT_M, PlacedWindow, sill_z, storey_levels
from fenestra.pipeline.types import Detection, WindowResult

LEVEL = np.diag([1.0, -1.0, -1.0])  # window frame -> camera of a level camera: export z = window y


def pw(index: int, x: float, sill: float, w: float = 1.2, h: float = 1.5, partial: bool = False) -> PlacedWindow:
    """A window (or door) of w x h m at x along the façade with its sill at ``sill`` m (export z)."""
    return PlacedWindow(index, w, h, LEVEL, np.array([x, -sill, 12.0]), partial=partial)


# A three-floor façade (wall 1, rows 3.2 m apart: sills 0.9, 4.1, 7.3), a signboard the verifier took
# for a window (wall 1, a flat 2 x 0.5 m box at 2.6 m), a neighbouring building's windows (wall 2,
# rows offset by 0.8 m) and a door (its foot 0.1 m up: a step), then the truth written out.
MAIN = [pw(4 * r + c, 1.6 * c, sill) for r, sill in enumerate((0.9, 4.1, 7.3)) for c in range(4)]
SIGN = pw(12, 1.0, 2.6, w=2.0, h=0.5)
NEIGHBOUR = [pw(13, 9.0, 1.7), pw(14, 10.5, 1.75), pw(15, 9.0, 5.0)]
DOOR = pw(0, 7.0, 0.1, w=1.1, h=2.3)
WALLS = {**{p.index: 1 for p in MAIN + [SIGN]}, **{p.index: 2 for p in NEIGHBOUR}}
GROUND = 0.1  # the door's foot: the ground floor's level
ELEVATIONS = (GROUND, 4.1 - SILL_HEIGHT_M, 7.3 - SILL_HEIGHT_M)
FLOOR_OF = {**{4 * r + c: r for r in range(3) for c in range(4)}, 12: 0, 13: 0, 14: 0, 15: 1}


def test_the_main_walls_rows_a_storey_apart_are_the_floors_and_nothing_else_makes_one():
    placed = MAIN + [SIGN] + NEIGHBOUR
    old = storey_levels(placed)  # rows of every window: the sign and the neighbour make storeys
    assert len(old.sills_m) > 3
    floors = floor_levels(placed, WALLS, [DOOR])
    assert floors.main_wall == 1 and floors.ground == "doors"
    assert floors.elevations_m == pytest.approx(ELEVATIONS, abs=1e-9)
    assert floors.names == ("Ground floor", "Floor 1", "Floor 2")
    assert floors.storey_measured and floors.storey_m == pytest.approx(3.2, abs=1e-9)
    assert floors.floor_of == FLOOR_OF and floors.door_floor_of == {0: 0}
    assert min(np.diff(floors.elevations_m)) >= MIN_STOREY_M


def test_grounding_puts_the_ground_floor_at_zero_and_the_door_on_it():
    """A door whose foot is 0.3 m up (the windows' sills at 0.9 m) is the ground line."""
    door = pw(0, 7.0, 0.3, w=1.1, h=2.1)
    placed, doors, floors = grounded_floors(MAIN, [door], floor_levels(MAIN, None, [door]))
    assert floors.elevations_m == pytest.approx((0.0, 3.2 - 0.3, 6.4 - 0.3), abs=1e-9)
    (door,) = doors
    assert sill_z(door) == pytest.approx(0.0, abs=1e-9)  # its foot on the ground floor
    top = door.to_export(door.void_corners()[:1])[0, 2]
    assert top == pytest.approx(2.1, abs=1e-9)  # its head where it was seen: 0.3 + 2.1, less the 0.3 shift
    assert sill_z(placed[0]) == pytest.approx(0.9 - 0.3, abs=1e-9)
    # a door whose foot is 0.6 m up is no ground line (its foot above half the sill height): it is
    # put on the ground floor (0.6 m within the 0.75 m reach), its head kept
    high = pw(0, 7.0, 0.6, w=1.1, h=2.1)
    _, (moved,), floors = grounded_floors(MAIN, [high], floor_levels(MAIN, None, [high]))
    assert floors.ground == "lowest row" and sill_z(moved) == pytest.approx(0.0, abs=1e-9)
    assert moved.height_m == pytest.approx(2.7, abs=1e-9)


def test_without_doors_the_lowest_floor_row_is_the_ground_floor():
    floors = floor_levels(MAIN, {p.index: 1 for p in MAIN})
    assert floors.ground == "lowest row"
    assert floors.elevations_m == pytest.approx((0.0, 3.2, 6.4), abs=1e-9)


def test_a_missing_row_is_a_floor_and_a_lone_row_gets_the_assumed_storey():
    two = [p for p in MAIN if p.index < 4 or p.index >= 8]  # the middle row unseen: 6.4 m between rows
    floors = floor_levels(two)
    assert not floors.storey_measured and floors.storey_m == ASSUMED_STOREY_M  # 6.4 m is no storey
    assert floors.elevations_m == pytest.approx((0.0, 3.2, 6.4), abs=1e-9)  # round(6.4 / 3) = 2 storeys
    lone = floor_levels(MAIN[:4])
    assert lone.elevations_m == pytest.approx((0.0,)) and lone.storey_m == ASSUMED_STOREY_M


def test_rows_closer_than_a_storey_are_one_floor():
    close = [pw(i, 1.6 * i, 0.9) for i in range(3)] + [pw(3 + i, 1.6 * i, 2.5) for i in range(2)]
    floors = floor_levels(close)  # 1.6 m between the rows: the three-window row is the floor
    assert floors.elevations_m == pytest.approx((0.0,)) and set(floors.floor_of.values()) == {0}
    assert floor_rows([0.9, 2.5, 4.1], [3, 5, 3]) == [0, 2]  # 3 + 3 > 5
    assert floor_rows([0.9, 2.5, 4.1], [1, 5, 1]) == [1]
    assert floor_rows([], []) == []
    assert filled([0.0, 9.0], 3.0) == pytest.approx([0.0, 3.0, 6.0, 9.0])
    assert filled([0.0, 4.0], 1.0) == pytest.approx([0.0, 4.0])  # never below MIN_STOREY_M apart


def test_a_partial_window_joins_the_floor_its_visible_part_stands_in():
    cut = pw(20, 3.0, -0.4, h=1.0, partial=True)  # cut by the photo's bottom: visible 0.6 m of row 0
    floors = floor_levels(MAIN + [cut])
    assert floors.floor_of[20] == 0 and len(floors.elevations_m) == 3


def test_floor_levels_rejects_bad_bounds():
    with pytest.raises(ValueError, match="sill_height_m"):
        floor_levels(MAIN, sill_height_m=-1.0)
    with pytest.raises(ValueError, match="storey bounds"):
        floor_levels(MAIN, min_storey_m=4.0, max_storey_m=3.0)


# --- model.ifc with a door ----------------------------------------------------------------------

IMG_W, IMG_H = 640, 480
K = K_from_fov(IMG_W, IMG_H, 65.0)
EYE = np.array([4.0, 3.0, 16.0])
R_F, T_F = look_at(EYE, [4.0, 3.5, 0.0], up=(0.0, 1.0, 0.0))
# (x0, sill, w, h) m on one façade: two floors of three windows, 3.1 m apart
VOIDS = [(0.0, 1.0, 1.2, 1.5), (3.0, 1.0, 1.2, 1.5), (6.0, 1.0, 1.2, 1.5),
         (0.0, 4.1, 1.2, 1.5), (3.0, 4.1, 1.2, 1.5), (6.0, 4.1, 1.2, 1.5)]
DOOR_VOID = (8.0, 0.0, 1.0, 2.2)


def result(i: int, x0: float, y0: float, w: float, h: float) -> WindowResult:
    t = T_F + R_F @ np.array([x0, y0, 0.0])
    X = np.array([[0, h, 0], [w, h, 0], [w, 0, 0], [0, 0, 0]], dtype=np.float64) @ R_F.T + t
    q = (X @ K.T)[:, :2] / (X @ K.T)[:, 2:]
    return WindowResult(i, 0.9, q, q, w / h, "general", None, R_F, t, h, q, None)


@pytest.fixture(scope="module")
def door_model(tmp_path_factory):
    out = tmp_path_factory.mktemp("door")
    photo = np.random.default_rng(0).integers(60, 200, (IMG_H, IMG_W, 3), dtype=np.uint8)
    paths = write_outputs(out, photo, K, [result(i, *v) for i, v in enumerate(VOIDS)],
                          walls={i: 3 for i in range(len(VOIDS))}, doors=[result(0, *DOOR_VOID)],
                          door_walls={0: 3}, door_properties={0: {"DetectionScore": 0.8}})
    return json.loads(paths["manifest"].read_text()), ifcopenshell.open(str(paths["ifc"]))


def test_a_door_is_an_ifcdoor_in_its_own_opening_in_its_wall_on_the_ground_floor(door_model):
    manifest, ifc = door_model
    (door,) = ifc.by_type("IfcDoor")
    assert door.PredefinedType == "DOOR" and ifc.by_type("IfcWindow") and len(ifc.by_type("IfcWindow")) == 6
    assert door.OverallWidth == pytest.approx(1.0) and door.OverallHeight == pytest.approx(2.2)
    dtype = ifcopenshell.util.element.get_type(door)
    assert dtype.is_a("IfcDoorType") and dtype.PredefinedType == "DOOR"
    opening = door.FillsVoids[0].RelatingOpeningElement
    wall = opening.VoidsElements[0].RelatingBuildingElement
    assert wall.is_a("IfcWall") and {o.RelatedOpeningElement for o in wall.HasOpenings} >= {opening}
    assert not any(o.HasFillings[0].RelatedBuildingElement.is_a("IfcWindow") for o in [opening])
    assert door.ContainedInStructure[0].RelatingStructure.Name == "Ground floor"
    qto = ifcopenshell.util.element.get_psets(door)["Qto_DoorBaseQuantities"]
    assert qto["Width"] == pytest.approx(1.0) and qto["Height"] == pytest.approx(2.2)
    assert qto["Area"] == pytest.approx(2.2) and qto["Perimeter"] == pytest.approx(6.4)
    M = ifcopenshell.util.placement.get_local_placement(door.ObjectPlacement)
    assert M[2, 3] == pytest.approx(0.0, abs=1e-9)  # the door's foot is the ground (z = 0)
    assert manifest["storeys"]["ground"] == "doors" and manifest["storeys"]["floors"][0]["doors"] == [0]
    assert [f["name"] for f in manifest["storeys"]["floors"]] == ["Ground floor", "Floor 1"]
    assert [f["elevation_m"] for f in manifest["storeys"]["floors"]] == pytest.approx([0.0, 4.1 - 0.9], abs=1e-9)
    assert manifest["doors"]["exported"][0]["door"] == door.GlobalId


def test_the_model_with_a_door_is_schema_valid(door_model):
    logger = ifcopenshell.validate.json_logger()
    ifcopenshell.validate.validate(door_model[1], logger, express_rules=True)
    assert logger.statements == []


# --- the verifier's classes ---------------------------------------------------------------------

def test_a_no_window_box_standing_upright_is_a_door_a_flat_one_a_signboard():
    from fenestra.pipeline.detectors.verifier import not_window_kind

    assert not_window_kind(np.array([0.0, 0.0, 40.0, 90.0])) == "door"
    assert not_window_kind(np.array([0.0, 0.0, 200.0, 40.0])) == "signboard"
    with pytest.raises(ValueError, match="Detection.kind"):
        Detection(np.zeros((2, 2), bool), np.zeros(4), 0.5, kind="shop")


def test_signboards_stay_out_with_their_reason_and_doors_need_a_wall():
    from fenestra.pipeline.doors import SIGNBOARD_REASON, place_openings
    from fenestra.pipeline.facade_model import FacadeModel

    mask = np.zeros((IMG_H, IMG_W), bool)
    mask[300:400, 100:150] = True
    dets = [Detection(mask, np.array([100.0, 300, 150, 400]), 0.8, kind="door"),
            Detection(mask, np.array([100.0, 300, 300, 340]), 0.7, kind="signboard")]
    door, sign = place_openings(dets, [None, None], {}, [], FacadeModel([], {}), set(), K, (IMG_W, IMG_H))
    assert sign.reason == SIGNBOARD_REASON and sign.placed is None and sign.to_json()["kind"] == "signboard"
    assert door.kind == "door" and not door.exported and "no wall" in door.reason
