"""model.ifc as BIM a user can edit (issue 35): storeys by floor, the ground at z = 0, extruded
walls voided by their openings, the photo on a cladding covering, window types, materials, base
quantities, a georeference -- read back with ifcopenshell and checked against this file's own numbers.

Ground truth: a flat façade (x along, y up, z outward) with three rows of windows whose sills are
jittered within a row, photographed by a known camera; every window's pose is exact (as in
tests/pipeline/test_pipeline_export.py). Expected rows, elevations, areas and corners are computed here from
the VOIDS table, never with the exporter's helpers.
"""
from __future__ import annotations

import dataclasses

import json
import math

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.element
import ifcopenshell.util.placement
import ifcopenshell.validate
import numpy as np
import pytest
import trimesh

from fenestra.conventions import K_from_fov, look_at
from fenestra.pipeline.export import write_outputs
from fenestra.pipeline.export.geometry import SILL_HEIGHT_M, PlacedWindow, storey_levels, storey_rows
from fenestra.pipeline.export.ifc import size_class, union_area, utm
from fenestra.pipeline.types import WindowResult

IMG_W, IMG_H = 640, 480
K = K_from_fov(IMG_W, IMG_H, 65.0)
EYE = np.array([7.0, 4.0, 18.0])  # the camera in the façade frame (m)
R_F, T_F = look_at(EYE, [3.5, 4.2, 0.0], up=(0.0, 1.0, 0.0))
# (x0, sill, w, h) m on the façade, and the row each is in (by construction)
VOIDS = [(0.0, 1.00, 1.2, 1.5), (2.0, 1.05, 2.4, 1.5), (5.2, 0.95, 1.2, 1.5),    # row 0 (a large shop window)
         (0.0, 4.10, 1.2, 1.5), (2.0, 4.00, 0.8, 1.0), (5.2, 3.95, 1.2, 1.5),    # row 1 (a small window)
         (0.0, 7.00, 1.2, 1.5), (2.6, 7.08, 1.2, 1.5), (5.2, 6.92, 1.2, 1.5),    # row 2
         (9.0, 7.02, 1.2, 1.5)]                                                  # row 2, a wall of its own
ROWS = [0, 0, 0, 1, 1, 1, 2, 2, 2, 2]
WALLS = {i: 7 for i in range(9)}  # the first nine on one fitted wall (id 7); window 9 on its own fragment
GPS = (59.9343, 30.3351, 12.0)  # St Petersburg: UTM zone 36N
Z_TO_Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])


def window_results() -> list[WindowResult]:
    """Each void's exact reconstruction at the true scale."""
    out = []
    for i, (x0, y0, w, h) in enumerate(VOIDS):
        t = T_F + R_F @ np.array([x0, y0, 0.0])
        X = np.array([[0, h, 0], [w, h, 0], [w, 0, 0], [0, 0, 0]], dtype=np.float64) @ R_F.T + t
        q = (X @ K.T)[:, :2] / (X @ K.T)[:, 2:]
        out.append(WindowResult(i, 0.9, q, q, w / h, "general", None, R_F, t, h, q, None))
    return out


def row_elevations() -> list[float]:
    """Floor r's elevation: the main wall's (wall 7's) row r's median sill minus its lowest row's
    (the ground is SILL_HEIGHT_M below row 0's sill, each floor SILL_HEIGHT_M below its row's sill;
    the rows are 3 m apart, above the 2.2 m a storey needs)."""
    sills = [np.median([VOIDS[i][1] for i in WALLS if ROWS[i] == r]) for r in range(3)]
    return [s - sills[0] for s in sills]


def facade_points(manifest: dict, X: np.ndarray) -> np.ndarray:
    """Export-world points (N, 3) -> the true façade frame, through export.json's world_frame."""
    M = np.asarray(manifest["world_frame"]["camera_to_export"])
    cam = (np.asarray(X, dtype=np.float64).reshape(-1, 3) - manifest["world_frame"]["offset_m"]) @ M
    return (cam - T_F) @ R_F


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    out = tmp_path_factory.mktemp("bim")
    photo = np.random.default_rng(0).integers(60, 200, (IMG_H, IMG_W, 3), dtype=np.uint8)
    paths = write_outputs(out, photo, K, window_results(), walls=WALLS, gps=GPS,
                          wall_properties={7: {"windows": 9}}, source="IMG_0042 façade.jpg")
    return paths, json.loads(paths["manifest"].read_text()), ifcopenshell.open(str(paths["ifc"]))


def _abs_placement(product) -> np.ndarray:
    return ifcopenshell.util.placement.get_local_placement(product.ObjectPlacement)


def _storey_of(element) -> str:
    return element.ContainedInStructure[0].RelatingStructure.Name


def _window(ifc, i: int):
    return next(w for w in ifc.by_type("IfcWindow") if w.Name.split()[1] == str(i))


# --- the pure functions --------------------------------------------------------------------------

def test_storey_rows_groups_jittered_sills_bottom_up():
    rng = np.random.default_rng(1)
    sills = np.concatenate([r * 3.2 + 0.9 + rng.uniform(-0.15, 0.15, 6) for r in (2, 0, 1)])  # rows out of order
    heights = rng.uniform(1.3, 1.7, len(sills))
    order = rng.permutation(len(sills))
    rows = storey_rows(sills[order], heights[order])
    assert np.array_equal(rows, np.repeat([2, 0, 1], 6)[order])
    # the tolerance is tied to the window height: the same façade at 1:25 groups alike
    assert np.array_equal(storey_rows(sills[order] / 25, heights[order] / 25), rows)
    # sills 0.8 m apart are one row for 2 m windows (tol 1 m), two rows for 1 m windows (tol 0.5 m)
    assert storey_rows([0.0, 0.8], [2.0, 2.0]).tolist() == [0, 0]
    assert storey_rows([0.8, 0.0], [1.0, 1.0]).tolist() == [1, 0]
    assert storey_rows([], []).shape == (0,)
    # a row is anchored at its lowest sill: a staircase of sills 0.4 m apart (each gap under the 0.5 m
    # tolerance) does not chain into one row
    assert storey_rows([0.0, 0.4, 0.8, 1.2, 1.6], [1.0] * 5).tolist() == [0, 0, 1, 1, 2]


def test_storey_rows_and_levels_reject_bad_values():
    with pytest.raises(ValueError, match=r"shapes \(3,\) and \(2,\)"):
        storey_rows([0.0, 1.0, 2.0], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"heights must be finite and positive, got \[1.0, -1.0\]"):
        storey_rows([0.0, 1.0], [1.0, -1.0])
    with pytest.raises(ValueError, match=r"sills must be finite, got \[0.0, nan\]"):
        storey_rows([0.0, float("nan")], [1.0, 1.0])
    with pytest.raises(ValueError, match=r"tol_fraction must be finite and positive, got 0"):
        storey_rows([0.0], [1.0], tol_fraction=0)
    with pytest.raises(ValueError, match=r"sill_height_m must be finite and non-negative, got -1"):
        storey_levels([], sill_height_m=-1)


def test_the_sill_offset_is_at_most_the_typical_window_height():
    """A 1:25 model's 6 cm windows get a 6 cm sill offset, not 0.9 m; full-size ones get SILL_HEIGHT_M."""
    level = np.diag([1.0, -1.0, -1.0])  # window y up = camera -y: export z = window y
    for h, expected in ((0.06, 0.06), (1.5, SILL_HEIGHT_M)):
        placed = [PlacedWindow(i, h, h, level, np.array([2.0 * h * i, -y, 10.0]))
                  for i, y in enumerate((0.0, 0.0, 4.0 * h))]
        lv = storey_levels(placed)
        assert lv.sill_height_m == pytest.approx(expected)
        assert lv.row_of == {0: 0, 1: 0, 2: 1}
        assert lv.elevations_m[1] - lv.elevations_m[0] == pytest.approx(4.0 * h)


def test_a_partial_window_joins_a_row_and_never_starts_one():
    """A window cut at the photo's bottom edge has a false sill (the edge): counted as a whole
    window it would start a third storey row; as a partial one it joins the row its visible part
    lies in, and the rows' sills come from the whole windows alone."""
    level = np.diag([1.0, -1.0, -1.0])  # export z = window y: sill_z = y below
    whole = [PlacedWindow(i, 1.0, 1.5, level, np.array([2.0 * i, -y, 10.0])) for i, y in enumerate((0.0, 0.1, 3.2, 3.3))]
    cut = PlacedWindow(9, 1.0, 0.7, level, np.array([9.0, -4.0, 10.0]), partial=True)  # visible 4.0-4.7 m
    as_whole = storey_levels(whole + [dataclasses.replace(cut, partial=False)])
    assert as_whole.row_of[9] == 2 and len(as_whole.sills_m) == 3
    lv = storey_levels(whole + [cut])
    assert lv.row_of == {0: 0, 1: 0, 2: 1, 3: 1, 9: 1}
    assert lv.sills_m == pytest.approx((0.05, 3.25))


def test_size_class_and_union_area():
    assert [size_class(a) for a in (0.5, 0.999, 1.0, 2.49, 2.5, 40.0)] == \
        ["small", "small", "medium", "medium", "large", "large"]
    with pytest.raises(ValueError, match="got -1"):
        size_class(-1)
    assert union_area([]) == 0.0
    assert union_area([(0, 0, 2, 1), (1, 0, 3, 1)]) == pytest.approx(3.0)  # overlap counted once
    assert union_area([(0, 0, 1, 1), (5, 5, 6, 7)]) == pytest.approx(3.0)
    assert union_area([(0, 0, 2, 2), (0.5, 0.5, 1, 1), (2, 0, 3, 1)]) == pytest.approx(5.0)  # inside, touching


def test_utm_matches_an_independent_series():
    """utm (Krüger's series) against Snyder's USGS formulas (PP 1395 p. 61), cm-level near the
    central meridian, and a zone's central meridian on the equator (500 km E, 0 N) exactly."""
    assert utm(0.0, 3.0) == (32631, pytest.approx(500000.0, abs=1e-6), pytest.approx(0.0, abs=1e-6))
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    ep2 = e2 / (1 - e2)
    for lat, lon, epsg in ((59.9343, 30.3351, 32636), (-33.8568, 151.2153, 32756), (40.7, -74.0, 32618)):
        phi = math.radians(lat)
        lon0 = math.radians((epsg % 100) * 6 - 183)
        N = a / math.sqrt(1 - e2 * math.sin(phi) ** 2)
        T, C, A = math.tan(phi) ** 2, ep2 * math.cos(phi) ** 2, (math.radians(lon) - lon0) * math.cos(phi)
        M = a * ((1 - e2 / 4 - 3 * e2 ** 2 / 64 - 5 * e2 ** 3 / 256) * phi
                 - (3 * e2 / 8 + 3 * e2 ** 2 / 32 + 45 * e2 ** 3 / 1024) * math.sin(2 * phi)
                 + (15 * e2 ** 2 / 256 + 45 * e2 ** 3 / 1024) * math.sin(4 * phi)
                 - (35 * e2 ** 3 / 3072) * math.sin(6 * phi))
        x = 0.9996 * N * (A + (1 - T + C) * A ** 3 / 6 + (5 - 18 * T + T * T + 72 * C - 58 * ep2) * A ** 5 / 120)
        y = 0.9996 * (M + N * math.tan(phi) * (A * A / 2 + (5 - T + 9 * C + 4 * C * C) * A ** 4 / 24
                                                + (61 - 58 * T + T * T + 600 * C - 330 * ep2) * A ** 6 / 720))
        code, easting, northing = utm(lat, lon)
        assert code == epsg
        assert easting == pytest.approx(500000.0 + x, abs=0.05)
        assert northing == pytest.approx(y + (0.0 if lat >= 0 else 1e7), abs=0.05)


# --- the written model ---------------------------------------------------------------------------

def test_ifc_is_schema_valid(model):
    logger = ifcopenshell.validate.json_logger()
    ifcopenshell.validate.validate(model[2], logger, express_rules=True)
    assert logger.statements == []


def test_the_header_names_the_file_and_what_wrote_it(model):
    """FILE_NAME: the file's own name, Fenestra and its version, IfcOpenShell's; no 'Nobody'."""
    import fenestra

    h = model[2].header.file_name
    assert h.name == model[0]["ifc"].name and h.originating_system == f"Fenestra {fenestra.__version__}"
    assert h.preprocessor_version == f"IfcOpenShell {ifcopenshell.version}" and h.authorization == ""
    text = model[0]["ifc"].read_text()
    assert "/dev/null" not in text.split("ENDSEC;")[0] and "Nobody" not in text.split("ENDSEC;")[0]


def test_an_application_owns_the_model_and_the_photo_is_named(model):
    """One IfcOwnerHistory, created within the last minute by the IfcApplication Fenestra (its
    version), owns every rooted entity; the header's description and the project name the photo."""
    import time

    import fenestra

    ifc = model[2]
    (app,) = ifc.by_type("IfcApplication")
    assert app.ApplicationDeveloper.Name == "Fenestra" and app.Version == str(fenestra.__version__)
    (history,) = ifc.by_type("IfcOwnerHistory")
    assert history.OwningApplication == app and 0 <= time.time() - history.CreationDate < 600
    assert all(e.OwnerHistory == history for e in ifc.by_type("IfcRoot"))
    said = "reconstructed by Fenestra from the photo IMG_0042 façade.jpg"
    assert said in ifc.header.file_description.description and ifc.by_type("IfcProject")[0].Description == said


def test_one_storey_per_floor_at_its_elevation(model):
    _, manifest, ifc = model
    storeys = sorted(ifc.by_type("IfcBuildingStorey"), key=lambda s: s.Elevation)
    assert [s.Name for s in storeys] == ["Ground floor", "Floor 1", "Floor 2"]
    for storey, elevation in zip(storeys, row_elevations()):
        assert storey.Elevation == pytest.approx(elevation, abs=1e-9)
        M = _abs_placement(storey)
        assert np.allclose(M[:3, :3], np.eye(3)) and np.allclose(M[:3, 3], [0, 0, elevation], atol=1e-9)
        assert storey.Decomposes[0].RelatingObject.is_a("IfcBuilding")
    assert [r["elevation_m"] for r in manifest["storeys"]["floors"]] == pytest.approx(row_elevations(), abs=1e-9)
    assert manifest["storeys"]["storey_source"] == "measured" and manifest["storeys"]["main_wall"] == 7
    ground = ifcopenshell.util.element.get_psets(ifc.by_type("IfcBuilding")[0])["Fenestra_Ground"]
    assert ground["SillHeightAssumed"] == pytest.approx(SILL_HEIGHT_M)


def test_ground_is_z0_sill_height_below_the_lowest_row_and_the_camera_above_the_origin(model):
    """Every window's sill (its placement's z) is its façade sill minus row 0's median sill plus
    SILL_HEIGHT_M; the camera stands above the origin at its height above that ground."""
    _, manifest, ifc = model
    row0 = np.median([VOIDS[i][1] for i in range(len(VOIDS)) if ROWS[i] == 0])
    for i, (_, sill, _, _) in enumerate(VOIDS):
        assert _abs_placement(_window(ifc, i))[2, 3] == pytest.approx(sill - row0 + SILL_HEIGHT_M, abs=1e-9)
    offset = np.asarray(manifest["world_frame"]["offset_m"])
    assert offset[:2] == pytest.approx([0, 0]) and offset[2] == pytest.approx(EYE[1] - row0 + SILL_HEIGHT_M, abs=1e-9)


def test_every_window_is_in_its_rows_storey_and_walls_in_their_lowest(model):
    _, _, ifc = model
    names = ["Ground floor", "Floor 1", "Floor 2"]
    for i, row in enumerate(ROWS):
        window = _window(ifc, i)
        assert _storey_of(window) == names[row], i
        opening = window.FillsVoids[0].RelatingOpeningElement
        assert not getattr(opening, "ContainedInStructure", None)  # IFC4: openings are never contained
    walls = {w.Name: w for w in ifc.by_type("IfcWall")}
    assert set(walls) == {"Wall 7", "Wall 9"}
    assert _storey_of(walls["Wall 7"]) == "Ground floor" and _storey_of(walls["Wall 9"]) == "Floor 2"
    for wall in walls.values():
        coverings = [c for rel in wall.HasCoverings for c in rel.RelatedCoverings]
        assert len(coverings) == 1 and _storey_of(coverings[0]) == _storey_of(wall)


def test_walls_are_extrusions_voided_by_extruded_openings(model):
    _, _, ifc = model
    members = {"Wall 7": list(range(9)), "Wall 9": [9]}
    for wall in ifc.by_type("IfcWall"):
        reps = {r.RepresentationIdentifier: r for r in wall.Representation.Representations}
        assert set(reps) == {"Axis", "Body"} and reps["Body"].RepresentationType == "SweptSolid"
        (solid,) = reps["Body"].Items
        assert solid.is_a("IfcExtrudedAreaSolid") and solid.SweptArea.is_a("IfcRectangleProfileDef")
        assert solid.SweptArea.YDim == pytest.approx(0.30)
        assert tuple(solid.ExtrudedDirection.DirectionRatios) == (0, 0, 1)
        M = _abs_placement(wall)
        assert M[2, 2] == pytest.approx(1.0, abs=1e-9)  # extruded straight up
        openings = [rel.RelatedOpeningElement for rel in wall.HasOpenings]
        filled = sorted(int(o.HasFillings[0].RelatedBuildingElement.Name.split()[1]) for o in openings)
        assert filled == members[wall.Name]
        for o in openings:
            (box,) = o.Representation.Representations[0].Items
            assert box.is_a("IfcExtrudedAreaSolid") and box.Depth > 0.31
        usage = ifcopenshell.util.element.get_material(wall)
        assert usage.is_a("IfcMaterialLayerSetUsage")
        assert [(la.Material.Name, la.LayerThickness) for la in usage.ForLayerSet.MaterialLayers] == [("Wall", 0.30)]
        assert ifcopenshell.util.element.get_type(wall).is_a("IfcWallType")


def test_the_photo_is_on_a_textured_cladding_covering(model):
    _, _, ifc = model
    coverings = ifc.by_type("IfcCovering")
    assert len(coverings) == 2
    for c in coverings:
        assert c.PredefinedType == "CLADDING" and c.Name.startswith("Photo façade")
        (item,) = c.Representation.Representations[0].Items
        assert item.is_a("IfcTriangulatedFaceSet") and item.HasTextures[0].is_a("IfcIndexedTriangleTextureMap")
        assert c.CoversElements[0].RelatingBuildingElement.is_a("IfcWall")


def photo_on_facade() -> np.ndarray:
    """Where the rays through the photo's four corners (pixel edges -0.5, W - 0.5, H - 0.5) meet the
    façade plane z = 0, (4, 2) m in the façade frame: this file's own ray casting."""
    corners = np.array([[-0.5, -0.5, 1], [IMG_W - 0.5, -0.5, 1], [IMG_W - 0.5, IMG_H - 0.5, 1], [-0.5, IMG_H - 0.5, 1]])
    d = (np.linalg.inv(K) @ corners.T).T @ R_F  # ray directions in the façade frame
    s = -EYE[2] / d[:, 2]
    assert np.all(s > 0)  # every corner's ray meets the wall
    return (EYE + s[:, None] * d)[:, :2]


def _expected_wall_quantities() -> dict[str, dict]:
    """Length, height and areas of both walls from VOIDS: the fitted wall spans the photo's view of
    its plane (photo_on_facade's bounding box) from the ground (SILL_HEIGHT_M below row 0's median
    sill) up; the own fragment its void + 1 m."""
    out = {}
    row0 = np.median([VOIDS[i][1] for i in range(len(VOIDS)) if ROWS[i] == 0])
    seen = photo_on_facade()
    for name, idx in (("Wall 7", range(9)), ("Wall 9", [9])):
        v = np.array([VOIDS[i] for i in idx])
        if name == "Wall 7":
            length = seen[:, 0].max() - seen[:, 0].min()
            height = seen[:, 1].max() - (row0 - SILL_HEIGHT_M)
        else:
            length = (v[:, 0] + v[:, 2]).max() - v[:, 0].min() + 2.0
            height = (v[:, 1] + v[:, 3]).max() - v[:, 1].min() + 2.0
        out[name] = {"Length": length, "Height": height, "Width": 0.30, "GrossSideArea": length * height,
                     "NetSideArea": length * height - (v[:, 2] * v[:, 3]).sum()}
    return out


def test_quantities_equal_the_hand_computed_ones(model):
    _, _, ifc = model
    for wall in ifc.by_type("IfcWall"):
        q = ifcopenshell.util.element.get_psets(wall)["Qto_WallBaseQuantities"]
        for key, value in _expected_wall_quantities()[wall.Name].items():
            assert q[key] == pytest.approx(value, abs=1e-6), (wall.Name, key)
    for i, (_, _, w, h) in enumerate(VOIDS):
        q = ifcopenshell.util.element.get_psets(_window(ifc, i))["Qto_WindowBaseQuantities"]
        assert (q["Width"], q["Height"], q["Area"]) == pytest.approx((w, h, w * h), abs=1e-9)


def test_window_types_by_size_with_glass_and_frame(model):
    """One IfcWindowType per window size (VOIDS has three: 1.2 x 1.5, 2.4 x 1.5, 0.8 x 1.0 m)."""
    _, manifest, ifc = model
    types = {}
    for i, (_, _, w, h) in enumerate(VOIDS):
        wtype = ifcopenshell.util.element.get_type(_window(ifc, i))
        assert wtype.is_a("IfcWindowType") and wtype.Name == f"casement-white {w:.2f} x {h:.2f} m", i
        types.setdefault((w, h), set()).add(wtype.id())
        constituents = ifcopenshell.util.element.get_material(wtype)
        assert constituents.is_a("IfcMaterialConstituentSet")
        assert {(c.Name, c.Material.Name) for c in constituents.MaterialConstituents} == \
            {("Framing", "Frame"), ("Glazing", "Glass")}
    assert {k: len(v) for k, v in types.items()} == {(1.2, 1.5): 1, (2.4, 1.5): 1, (0.8, 1.0): 1}
    assert len(ifc.by_type("IfcWindowType")) == 3
    assert {e["index"]: e["window_type"] for e in manifest["exported"]}[1] == "casement-white 2.40 x 1.50 m"


def test_site_georeference_from_gps(model):
    _, _, ifc = model
    site = ifc.by_type("IfcSite")[0]
    lat = sum(v / d for v, d in zip(site.RefLatitude, (1, 60, 3600, 3.6e9)))
    lon = sum(v / d for v, d in zip(site.RefLongitude, (1, 60, 3600, 3.6e9)))
    assert (lat, lon, site.RefElevation) == pytest.approx(GPS, abs=1e-6)
    (conversion,) = ifc.by_type("IfcMapConversion")
    assert conversion.TargetCRS.Name == "EPSG:32636"
    code, e, n = utm(*GPS[:2])
    assert (conversion.Eastings, conversion.Northings, conversion.OrthogonalHeight) == pytest.approx((e, n, GPS[2]))
    with pytest.raises(ValueError, match=r"gps must be .* got \(95.0, 10.0\)"):
        write_outputs("/nonexistent/never-written", np.zeros((8, 8, 3), np.uint8), K, [], gps=(95.0, 10.0))


def _tri_area(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def test_the_wall_tessellates_with_its_holes(model):
    """ifcopenshell.geom builds each wall: its exterior face (0.01 m behind the photographed plane,
    under the cladding) has the net side area, and no triangle of it lies inside a void."""
    _, manifest, ifc = model
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    expected = _expected_wall_quantities()
    for wall in ifc.by_type("IfcWall"):
        shape = ifcopenshell.geom.create_shape(settings, wall)
        V = facade_points(manifest, np.asarray(shape.geometry.verts).reshape(-1, 3))
        F = np.asarray(shape.geometry.faces).reshape(-1, 3)
        assert V[:, 2].min() == pytest.approx(-0.31, abs=1e-6) and V[:, 2].max() == pytest.approx(-0.01, abs=1e-6)
        front = np.all(np.abs(V[F][:, :, 2] + 0.01) < 1e-6, axis=1)
        assert _tri_area(V, F)[front].sum() == pytest.approx(expected[wall.Name]["NetSideArea"], rel=1e-6)
        centroids = V[F[front]].mean(axis=1)
        for x0, y0, w, h in VOIDS:
            inside = ((centroids[:, 0] > x0) & (centroids[:, 0] < x0 + w)
                      & (centroids[:, 1] > y0) & (centroids[:, 1] < y0 + h))
            assert not inside.any()


def test_ifc_obj_and_glb_share_one_world(model):
    """A window's void corners (bottom-left: its IFC placement's origin; top-right: that placement,
    x along the wall, y into it, z up, applied to (w, 0, h)) are vertices of its frame in model.obj and, y-up turned back, in model.glb."""
    paths, _, ifc = model
    obj, name = {}, None
    for line in paths["obj"].read_text().splitlines():
        if line.startswith("o "):
            name = line.split()[1]
        elif line.startswith("v "):
            obj.setdefault(name, []).append(list(map(float, line.split()[1:])))
    glb = {m.metadata.get("name"): m for m in trimesh.load(str(paths["glb"]), force="scene").dump(concatenate=False)}
    for i, (_, _, w, h) in enumerate(VOIDS):
        M = _abs_placement(_window(ifc, i))
        corners = (M @ np.array([[0, 0, 0, 1], [w, 0, h, 1]], dtype=np.float64).T).T[:, :3]
        V_obj = np.asarray(obj[f"frame_{i}"])
        V_glb = np.asarray(glb[f"frame_{i}"].vertices) @ Z_TO_Y_UP  # (x, z, -y) -> (x, y, z)
        for c in corners:
            assert np.linalg.norm(V_obj - c, axis=1).min() < 2e-6, (i, c)
            assert np.linalg.norm(V_glb - c, axis=1).min() < 1e-5, (i, c)


def test_a_stated_wall_thickness_reaches_the_ifc_the_meshes_and_the_manifest(tmp_path):
    """--wall-thickness 0.12: the layer, the extrusion, the quantities, export.json and the OBJ slab
    (its depth along the wall's normal: 0.12 m of wall + COVERING_THICKNESS_M of cladding)."""
    from fenestra.pipeline.export.geometry import COVERING_THICKNESS_M

    photo = np.random.default_rng(0).integers(60, 200, (IMG_H, IMG_W, 3), dtype=np.uint8)
    paths = write_outputs(tmp_path, photo, K, window_results(), walls=WALLS, thickness_m=0.12)
    assert json.loads(paths["manifest"].read_text())["wall_thickness_m"] == 0.12
    ifc = ifcopenshell.open(str(paths["ifc"]))
    for wall in ifc.by_type("IfcWall"):
        (solid,) = {r.RepresentationIdentifier: r for r in wall.Representation.Representations}["Body"].Items
        assert solid.SweptArea.YDim == pytest.approx(0.12)
        layers = ifcopenshell.util.element.get_material(wall).ForLayerSet.MaterialLayers
        assert [la.LayerThickness for la in layers] == [pytest.approx(0.12)]
        assert ifcopenshell.util.element.get_psets(wall)["Qto_WallBaseQuantities"]["Width"] == pytest.approx(0.12)
    manifest = json.loads(paths["manifest"].read_text())
    lines = paths["obj"].read_text().splitlines()
    start = next(i for i, s in enumerate(lines) if s.startswith("o wall_w7"))
    verts = []
    for s in lines[start + 1:]:
        if s.startswith("o "):
            break
        if s.startswith("v "):
            verts.append([float(x) for x in s.split()[1:4]])
    depth = facade_points(manifest, np.array(verts))[:, 2]  # the true façade frame: z along the wall's normal
    assert np.ptp(depth) == pytest.approx(0.12 + COVERING_THICKNESS_M, abs=1e-6)


def test_window_types_say_their_panels_and_windows_their_perimeter(model):
    from fenestra.pipeline.catalogue import CATALOGUE
    from fenestra.pipeline.export.ifc import partitioning

    assert partitioning(CATALOGUE["two-by-two-mullion"]) == ("USERDEFINED", "2 x 2 panels")
    for wtype in model[2].by_type("IfcWindowType"):
        assert wtype.PartitioningType != "NOTDEFINED" and wtype.PredefinedType == "WINDOW"
    for window in model[2].by_type("IfcWindow"):
        q = ifcopenshell.util.element.get_psets(window)["Qto_WindowBaseQuantities"]
        assert q["Perimeter"] == pytest.approx(2 * (q["Width"] + q["Height"]))
        assert q["Area"] == pytest.approx(q["Width"] * q["Height"])
