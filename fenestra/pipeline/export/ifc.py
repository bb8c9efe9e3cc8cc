"""IFC4 export: a façade model a BIM user can edit, in storeys, with the photo as its walls' cladding.

World frame and units: see fenestra/pipeline/export/geometry.py (metres, z up, the ground plane at
z = 0, the camera above the origin looking along +y). The file holds

    IfcProject / IfcSite / IfcBuilding   the building carries Fenestra_Ground (SillHeightAssumed: the
                       ground plane lies this far below the lowest row of sills, geometry.SILL_HEIGHT_M
                       at most the typical window height; StoreyRowTolerance; the rule in words);
                       with ``gps`` the site's RefLatitude/RefLongitude/RefElevation (the camera's
                       position, which is the world's origin on the ground) and an IfcMapConversion
                       to the UTM zone's IfcProjectedCRS (EPSG 326xx / 327xx)
    IfcBuildingStorey  one per floor ("Ground floor", "Floor 1", ... from the bottom; floors.py: the
                       main wall's rows a storey apart, the doors on the ground floor), Elevation its
                       level, placed at (0, 0, Elevation) in the building; Fenestra_Storey (its
                       windows and doors)
    IfcWall            per façade plane (walls_plan.facade_walls: the fitted walls of ``walls``
                       merged only when one plane; each as far as the photo shows its plane, from
                       the ground up, two walls meeting at their corner line where the photo shows
                       it; a window without a wall: a fragment, its void + margin), contained in
                       the lowest floor its windows are in: a standard wall a BIM tool edits as one: placement on
                       its bottom-left exterior corner (x along the wall, z its up axis), Axis
                       (IfcPolyline along x) and Body = IfcExtrudedAreaSolid of an
                       IfcRectangleProfileDef footprint (length x thickness) extruded up by its
                       height (not the façade rectangle extruded through the thickness: a wall's
                       IfcMaterialLayerSetUsage lays its layers along the footprint's y, AXIS2, the
                       form BIM tools take as a parametric wall); IfcWallType "Photographed wall"
                       with an IfcMaterialLayerSet (one "Wall" layer, WALL_THICKNESS_M) ->
                       IfcMaterialLayerSetUsage on the wall;
                       Qto_WallBaseQuantities (Length, Height, Width, GrossSideArea, NetSideArea =
                       gross - the openings' union, GrossVolume, NetVolume); Fenestra_Wall (the
                       given properties, MergedWalls, CornerWith); two walls meeting at a corner
                       are joined by an IfcRelConnectsPathElements (the ends that meet there)
    IfcCovering        CLADDING "Photo façade <wall>", COVERING_THICKNESS_M thick in front of the
                       wall (its outer face is the photographed plane), related to its wall by
                       IfcRelCoversBldgElements, in the wall's storey: the closed, gridded
                       IfcTriangulatedFaceSet with the windows' voids cut out, carrying the
                       IfcIndexedTriangleTextureMap into texture.png (IfcImageTexture, relative URL)
                       and an IfcSurfaceStyle with IfcSurfaceStyleWithTextures. Why a covering: a
                       texture map needs a tessellated item, an editable wall an extrusion; the
                       photo is the façade's finish, which is what IFC's cladding covering is.
    IfcOpeningElement  per window: IfcExtrudedAreaSolid of the void's rectangle through covering and
                       wall (+ OPENING_OVERSHOOT_M each side), voiding the wall (IfcRelVoidsElement);
                       in the wall's axes (the window's measured size about its centre on the
                       wall's plane: walls_plan.aligned), so square to the wall; placed relative to the wall, and not in a storey itself (IFC4: an opening is
                       never spatially contained; it belongs to its window's storey through the
                       window it holds)
    IfcWindow          OverallWidth/OverallHeight = void size, PredefinedType WINDOW, placed in its
                       wall's axes (x along, y into the wall, z up) at the void's bottom-left,
                       filling the opening (IfcRelFillsElement), contained in its floor's storey;
                       Body: its type's parametric body (ifc_window: SweptSolid lining, frames and
                       glass) mapped and scaled to its measured size; typed by an IfcWindowType per
                       window size (ifc_window.type_sizes; PredefinedType WINDOW, PartitioningType
                       from the catalogue style: :func:`partitioning`, RepresentationMaps its body,
                       Fenestra_WindowType with :func:`size_class`) with an
                       IfcMaterialConstituentSet (Framing: IfcMaterial "Frame", Glazing:
                       IfcMaterial "Glass", each styled in the style's colours);
                       Qto_WindowBaseQuantities (Width, Height, Area, Perimeter); Pset_WindowCommon
                       (IsExternal) and Fenestra_Window (confidence, aspect interval, K source,
                       scale source, ...) when given
    IfcDoor            per door, in its own opening in its wall, in its floor (ifc_door.py)

Every element is placed by the window-frame -> world matrix (geometry.PlacedWindow.export_matrix),
relative to its container (storey, wall or opening), so moving a storey moves its contents.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import ifcopenshell
import ifcopenshell.api.aggregate
import ifcopenshell.api.context
import ifcopenshell.api.feature
import ifcopenshell.api.geometry
import ifcopenshell.api.material
import ifcopenshell.api.project
import ifcopenshell.api.pset
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import ifcopenshell.api.style
import ifcopenshell.api.type
import ifcopenshell.api.unit
import ifcopenshell.guid
import ifcopenshell.util.geolocation
import numpy as np

from fenestra.files import write_ifc_file
from fenestra.pipeline.catalogue import WindowStyle, get_style
from fenestra.pipeline.export.floors import Floors, floor_levels
from fenestra.pipeline.export.geometry import (COVERING_THICKNESS_M, WALL_MARGIN_M, WALL_THICKNESS_M, PlacedWindow,
                                               TextureLayout, facade_pixels, wall_mesh, wall_outline)
from fenestra.pipeline.export.ifc_window import TypeSize, mapped_body, type_sizes, window_body
from fenestra.pipeline.export.walls_plan import facade_walls

OPENING_OVERSHOOT_M = 0.01  # the opening box pokes out of both faces (covering's and wall's: clean booleans)
# Window types by void area (m², at the model's scale): (name, upper bound), the first bound above the area wins.
WINDOW_SIZE_CLASSES = (("small", 1.0), ("medium", 2.5), ("large", math.inf))
# The wall's local frame in the window frame of its placement (x along, y up, z outward): x stays,
# the local y points into the wall (-z), the local z up (y): the extrusion axis of a standard wall.
_WALL_AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def size_class(area_m2: float) -> str:
    """The size class ("small", "medium", "large") of a window of void area ``area_m2`` (m²):
    WINDOW_SIZE_CLASSES' first class whose upper bound exceeds it. ValueError for a non-positive
    or non-finite area."""
    if not (np.isfinite(area_m2) and area_m2 > 0):
        raise ValueError(f"window area must be finite and positive, got {area_m2!r}")
    return next(name for name, upper in WINDOW_SIZE_CLASSES if area_m2 < upper)


# IfcWindowTypePartitioningEnum of a style's (mullions, transoms): its panels side by side (split by
# vertical mullions) or stacked (split by transoms); any other grid is USERDEFINED, named
PARTITIONING = {(0, 0): "SINGLE_PANEL", (1, 0): "DOUBLE_PANEL_VERTICAL", (0, 1): "DOUBLE_PANEL_HORIZONTAL",
                (2, 0): "TRIPLE_PANEL_VERTICAL", (0, 2): "TRIPLE_PANEL_HORIZONTAL"}


def partitioning(style: WindowStyle) -> tuple[str, str | None]:
    """(IfcWindowType.PartitioningType, UserDefinedPartitioningType or None) of a catalogue style."""
    key = (style.mullions, style.transoms)
    if key in PARTITIONING:
        return PARTITIONING[key], None
    return "USERDEFINED", f"{style.mullions + 1} x {style.transoms + 1} panels"


def union_area(rects) -> float:
    """Area (m²) of the union of axis-aligned rectangles (x0, y0, x1, y1) m, (N, 4): overlapping
    openings are not subtracted twice from a wall's side area. O(N²) on the grid of their edges
    (a 2-D difference array, cumulated: each cell's cover count)."""
    r = np.asarray(list(rects), dtype=np.float64).reshape(-1, 4)
    if len(r) == 0:
        return 0.0
    xs, ys = np.unique(r[:, [0, 2]]), np.unique(r[:, [1, 3]])
    i0, i1 = np.searchsorted(xs, r[:, 0]), np.searchsorted(xs, r[:, 2])
    j0, j1 = np.searchsorted(ys, r[:, 1]), np.searchsorted(ys, r[:, 3])
    count = np.zeros((len(xs), len(ys)), dtype=np.int64)
    for di, dj, sign in ((i0, j0, 1), (i1, j0, -1), (i0, j1, -1), (i1, j1, 1)):
        np.add.at(count, (di, dj), sign)
    covered = count.cumsum(axis=0).cumsum(axis=1)[:-1, :-1] > 0
    return float((np.diff(xs)[:, None] * np.diff(ys)[None, :])[covered].sum())


def _faceset(f: ifcopenshell.file, vertices: np.ndarray, faces: np.ndarray):
    """Closed IfcTriangulatedFaceSet from (N, 3) m vertices and (M, 3) 0-based faces."""
    pts = f.createIfcCartesianPointList3D([tuple(map(float, v)) for v in vertices])
    idx = [tuple(int(i) + 1 for i in tri) for tri in faces]
    return f.createIfcTriangulatedFaceSet(pts, None, True, idx, None)


def _rectangle_solid(f, x0: float, y0: float, x1: float, y1: float, z0: float, direction, depth: float):
    """IfcExtrudedAreaSolid: the rectangle [x0, x1] x [y0, y1] (IfcRectangleProfileDef) in the plane
    z = z0, extruded along ``direction`` (a unit (3,)) by ``depth`` m."""
    centre = f.createIfcAxis2Placement2D(f.createIfcCartesianPoint(((x0 + x1) / 2, (y0 + y1) / 2)), None)
    profile = f.createIfcRectangleProfileDef("AREA", None, centre, float(x1 - x0), float(y1 - y0))
    position = f.createIfcAxis2Placement3D(f.createIfcCartesianPoint((0.0, 0.0, float(z0))), None, None)
    return f.createIfcExtrudedAreaSolid(profile, position, f.createIfcDirection(tuple(map(float, direction))),
                                        float(depth))


def _colour_style(f: ifcopenshell.file, name: str, rgb, transparency: float = 0.0):
    colour = f.createIfcColourRgb(None, *map(float, rgb))
    rendering = f.createIfcSurfaceStyleRendering(colour, float(transparency), None, None, None, None,
                                                 None, None, "NOTDEFINED")
    return f.createIfcSurfaceStyle(name, "BOTH", [rendering])


def _add_pset(f: ifcopenshell.file, product, name: str, values: dict) -> None:
    """A property set on ``product`` with the values that are not None (bool, int, float, str)."""
    values = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in values.items() if v is not None}
    if values:
        pset = ifcopenshell.api.pset.add_pset(f, product=product, name=name)
        ifcopenshell.api.pset.edit_pset(f, pset=pset, properties=values)


def _add_qto(f: ifcopenshell.file, product, name: str, values: dict) -> None:
    """A quantity set (IfcElementQuantity) on ``product``: {name: float} in project units (m, m², m³)."""
    qto = ifcopenshell.api.pset.add_qto(f, product=product, name=name)
    ifcopenshell.api.pset.edit_qto(f, qto=qto, properties={k: float(v) for k, v in values.items()})


def _storeys(f, building, floors: Floors) -> list:
    """One IfcBuildingStorey per floor of ``floors`` ("Ground floor", "Floor 1", ...; one at 0 m
    when there is none), bottom-up, with Fenestra_Storey (the windows and doors it holds)."""
    elevations = floors.elevations_m or (0.0,)
    storeys = []
    for r, (name, elevation) in enumerate(zip(floors.names, elevations)):
        storey = ifcopenshell.api.root.create_entity(f, ifc_class="IfcBuildingStorey", name=name)
        storey.Elevation = float(elevation)
        ifcopenshell.api.aggregate.assign_object(f, products=[storey], relating_object=building)
        T = np.eye(4)
        T[2, 3] = elevation
        ifcopenshell.api.geometry.edit_object_placement(f, product=storey, matrix=T)
        if floors.elevations_m:
            _add_pset(f, storey, "Fenestra_Storey", {
                "Windows": sum(k == r for k in floors.floor_of.values()),
                "Doors": sum(k == r for k in floors.door_floor_of.values())})
        storeys.append(storey)
    return storeys


def _new_file(name: str, levels: Floors, gps=None):
    """An IFC4 file with project (metres), site, building and the storeys of ``levels`` (its
    floors); returns (file, {"body", "axis"} contexts, [storey per floor])."""
    f = ifcopenshell.api.project.create_file(version="IFC4")
    project = ifcopenshell.api.root.create_entity(f, ifc_class="IfcProject", name=name)
    units = [ifcopenshell.api.unit.add_si_unit(f, unit_type=u) for u in ("LENGTHUNIT", "AREAUNIT", "VOLUMEUNIT")]
    units.append(ifcopenshell.api.unit.add_si_unit(f, unit_type="PLANEANGLEUNIT"))
    ifcopenshell.api.unit.assign_unit(f, units=units)
    model = ifcopenshell.api.context.add_context(f, context_type="Model")
    contexts = {
        "body": ifcopenshell.api.context.add_context(f, context_type="Model", context_identifier="Body",
                                                     target_view="MODEL_VIEW", parent=model),
        "axis": ifcopenshell.api.context.add_context(f, context_type="Model", context_identifier="Axis",
                                                     target_view="GRAPH_VIEW", parent=model)}
    site = ifcopenshell.api.root.create_entity(f, ifc_class="IfcSite", name="Site")
    building = ifcopenshell.api.root.create_entity(f, ifc_class="IfcBuilding", name="Photographed building")
    ifcopenshell.api.aggregate.assign_object(f, products=[site], relating_object=project)
    ifcopenshell.api.aggregate.assign_object(f, products=[building], relating_object=site)
    for spatial in (site, building):
        ifcopenshell.api.geometry.edit_object_placement(f, product=spatial, matrix=np.eye(4))
    _add_pset(f, building, "Fenestra_Ground", {
        "SillHeightAssumed": levels.sill_height_m, "StoreyRowTolerance": levels.tol_m,
        "StoreyHeight": levels.storey_m, "StoreyHeightSource": "measured" if levels.storey_measured else "assumed",
        "GroundPlane": "z = 0 is the ground floor's level: the doors' bottom where doors stand below the main "
                       "wall's lowest row of windows, else SillHeightAssumed below that row's sill; each floor's "
                       "Elevation is its row's sill minus SillHeightAssumed"})
    if gps is not None:
        _georeference(f, site, model, gps)
    return f, contexts, _storeys(f, building, levels)


def _check_gps(gps) -> tuple[float, float, float, float | None]:
    """(latitude deg, longitude deg, elevation m, heading deg or None) from a (lat, lon),
    (lat, lon, elevation) or (lat, lon, elevation, heading) tuple, heading the camera's view
    direction in degrees clockwise from true north; ValueError naming it when out of range."""
    try:
        values = [float(v) for v in gps]
    except (TypeError, ValueError):
        values = []
    if len(values) not in (2, 3, 4) or not all(np.isfinite(values)) or abs(values[0]) > 90 or abs(values[1]) > 180:
        raise ValueError(f"gps must be (latitude deg, longitude deg[, elevation m[, heading deg]]) within +-90 / "
                         f"+-180, got {gps!r}")
    return (values[0], values[1], values[2] if len(values) > 2 else 0.0,
            values[3] % 360.0 if len(values) > 3 else None)


def grid_convergence_deg(lat_deg: float, lon_deg: float) -> float:
    """UTM grid convergence (deg): the angle from true north to grid north at a WGS84 point, to
    first order atan(tan(lon - lon0) sin(lat)) with lon0 its zone's central meridian."""
    zone = int((lon_deg + 180.0) // 6.0) % 60 + 1
    dlon = math.radians(lon_deg - (-183.0 + 6.0 * zone))
    return math.degrees(math.atan(math.tan(dlon) * math.sin(math.radians(lat_deg))))


def utm(lat_deg: float, lon_deg: float) -> tuple[int, float, float]:
    """(EPSG code, easting m, northing m) of a WGS84 point in its UTM zone (EPSG 326zz north,
    327zz south): Krüger's series to the third order (mm-level within the zone)."""
    a, f_ = 6378137.0, 1 / 298.257223563
    zone = int((lon_deg + 180.0) // 6.0) % 60 + 1
    lon0 = math.radians(-183.0 + 6.0 * zone)
    n = f_ / (2 - f_)
    A = a / (1 + n) * (1 + n ** 2 / 4 + n ** 4 / 64)
    alpha = (n / 2 - 2 * n ** 2 / 3 + 5 * n ** 3 / 16, 13 * n ** 2 / 48 - 3 * n ** 3 / 5, 61 * n ** 3 / 240)
    phi, lam = math.radians(lat_deg), math.radians(lon_deg) - lon0
    e = 2 * math.sqrt(n) / (1 + n)
    t = math.sinh(math.atanh(math.sin(phi)) - e * math.atanh(e * math.sin(phi)))
    xi, eta = math.atan2(t, math.cos(lam)), math.atanh(math.sin(lam) / math.sqrt(1 + t * t))
    E = eta + sum(al * math.cos(2 * j * xi) * math.sinh(2 * j * eta) for j, al in enumerate(alpha, 1))
    N = xi + sum(al * math.sin(2 * j * xi) * math.cosh(2 * j * eta) for j, al in enumerate(alpha, 1))
    k0 = 0.9996
    return (32600 if lat_deg >= 0 else 32700) + zone, 500000.0 + k0 * A * E, \
        k0 * A * N + (0.0 if lat_deg >= 0 else 10000000.0)


def _georeference(f, site, model_context, gps) -> None:
    """The site's RefLatitude/RefLongitude/RefElevation and an IfcMapConversion of the model's
    origin to its UTM coordinates. The model's +y is the camera's heading: with a heading (degrees
    clockwise from true north, e.g. EXIF GPSImgDirection) the context's TrueNorth is
    (-sin h, cos h) and the map conversion's x axis is the model's x in grid coordinates (h less
    the grid convergence, plus 90 degrees); without one, +y is taken as grid north (XAxisAbscissa
    1, XAxisOrdinate 0) and no TrueNorth is written."""
    lat, lon, elevation, heading = _check_gps(gps)
    site.RefLatitude = ifcopenshell.util.geolocation.dd2dms(lat, use_us=True)
    site.RefLongitude = ifcopenshell.util.geolocation.dd2dms(lon, use_us=True)
    site.RefElevation = float(elevation)
    epsg, easting, northing = utm(lat, lon)
    zone = f"{epsg % 100}{'N' if lat >= 0 else 'S'}"
    crs = f.createIfcProjectedCRS(f"EPSG:{epsg}", f"WGS 84 / UTM zone {zone}", "WGS84", None, "UTM", zone, None)
    x_axis = (1.0, 0.0)
    if heading is not None:
        h = math.radians(heading)
        model_context.TrueNorth = f.createIfcDirection((-math.sin(h), math.cos(h)))
        g = math.radians(heading - grid_convergence_deg(lat, lon))  # the heading's grid bearing
        x_axis = (math.cos(g), -math.sin(g))  # the model's x (heading + 90 deg) as (easting, northing)
    f.createIfcMapConversion(model_context, crs, easting, northing, float(elevation), *x_axis, None)


def _photo_covering(f, body, storey, K, wall, wall_pw: PlacedWindow, voids: list, layout: TextureLayout, texture,
                    wall_style, margin_m: float):
    """The IfcCovering (CLADDING) "Photo façade" of ``wall``: a closed, gridded slab from the
    photographed plane (z = 0 of wall_pw's frame) to z = -COVERING_THICKNESS_M, the ``voids``
    (wall_pw's frame) cut out, textured from the photo; IfcRelCoversBldgElements to ``wall``."""
    V, F = wall_mesh(wall_pw, voids, True, margin_m, COVERING_THICKNESS_M)
    items = _faceset(f, V, F)
    uv = layout.uv(facade_pixels(K, wall_pw, V[:, :2]))
    tex_vertices = f.createIfcTextureVertexList([tuple(map(float, p)) for p in uv])
    f.createIfcIndexedTriangleTextureMap([texture], items, tex_vertices,
                                         [tuple(int(i) + 1 for i in tri) for tri in F])
    ifcopenshell.api.style.assign_item_style(f, item=items, style=wall_style)
    covering = ifcopenshell.api.root.create_entity(f, ifc_class="IfcCovering", predefined_type="CLADDING",
                                                   name=f"Photo façade {wall.Name}")
    ifcopenshell.api.spatial.assign_container(f, products=[covering], relating_structure=storey)
    ifcopenshell.api.geometry.edit_object_placement(f, product=covering, matrix=wall_pw.export_matrix())
    rep = f.createIfcShapeRepresentation(body, "Body", "Tessellation", [items])
    ifcopenshell.api.geometry.assign_representation(f, product=covering, representation=rep)
    f.createIfcRelCoversBldgElements(ifcopenshell.guid.new(), None, None, None, wall, [covering])
    return covering


def wall_box(wall_pw: PlacedWindow, margin_m: float) -> tuple[np.ndarray, float, float]:
    """A wall's standard-case frame and size: (4x4 placement in the export world, length m, height m).
    The placement's origin is the wall outline's bottom-left corner (wall_pw's frame, ``margin_m``
    beyond it) on the wall solid's exterior face (COVERING_THICKNESS_M behind the photographed
    plane); its x runs along the wall, its y into it (the layer direction), its z up the wall."""
    outline = wall_outline(wall_pw, margin_m)
    (x0, y0), (x1, y1) = outline[0], outline[2]
    local = np.eye(4)
    local[:3, :3] = _WALL_AXES
    local[:3, 3] = (x0, y0, -COVERING_THICKNESS_M)
    return wall_pw.export_matrix() @ local, float(x1 - x0), float(y1 - y0)


def _wall(f, contexts, storey, wall_pw: PlacedWindow, voids: list, name: str, wall_type, margin_m: float,
          thickness_m: float):
    """One IfcWall (see the module docstring): footprint length x thickness extruded up by its
    height, typed ``wall_type`` (its layer set's usage), Axis + Body, Qto_WallBaseQuantities
    (``voids``: its openings' rectangles in wall_pw's frame)."""
    T, length, height = wall_box(wall_pw, margin_m)
    wall = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWall", name=name)
    ifcopenshell.api.spatial.assign_container(f, products=[wall], relating_structure=storey)
    ifcopenshell.api.geometry.edit_object_placement(f, product=wall, matrix=T)
    ifcopenshell.api.type.assign_type(f, related_objects=[wall], relating_type=wall_type)
    axis = f.createIfcPolyline([f.createIfcCartesianPoint((0.0, 0.0)), f.createIfcCartesianPoint((length, 0.0))])
    ifcopenshell.api.geometry.assign_representation(
        f, product=wall, representation=f.createIfcShapeRepresentation(contexts["axis"], "Axis", "Curve2D", [axis]))
    solid = _rectangle_solid(f, 0.0, 0.0, length, thickness_m, 0.0, (0.0, 0.0, 1.0), height)
    ifcopenshell.api.geometry.assign_representation(
        f, product=wall, representation=f.createIfcShapeRepresentation(contexts["body"], "Body", "SweptSolid", [solid]))
    gross, opened = length * height, union_area(voids)
    _add_qto(f, wall, "Qto_WallBaseQuantities", {
        "Length": length, "Height": height, "Width": thickness_m, "GrossSideArea": gross,
        "NetSideArea": gross - opened, "GrossVolume": gross * thickness_m, "NetVolume": (gross - opened) * thickness_m})
    return wall


class _Library:
    """The file's shared definitions: materials, styles, the wall type and the window types (made
    on first use, one per window size: ifc_window.type_sizes)."""

    def __init__(self, f, body, style: WindowStyle, texture_file: str, thickness_m: float):
        self.f, self.style = f, style
        self.texture = f.createIfcImageTexture(False, False, "DIFFUSE", None, None, str(texture_file))
        self.wall_style = f.createIfcSurfaceStyle(
            "Photo texture", "BOTH",
            [f.createIfcSurfaceStyleShading(f.createIfcColourRgb(None, 0.8, 0.8, 0.8), 0.0),
             f.createIfcSurfaceStyleWithTextures([self.texture])])
        self.frame_style = _colour_style(f, f"{style.name} frame", style.frame_rgb)
        self.glass_style = _colour_style(f, f"{style.name} glass", style.glass_rgb, 1.0 - style.glass_alpha)
        mat = ifcopenshell.api.material
        self.frame = mat.add_material(f, name="Frame", description=f"window frame ({style.name})")
        self.glass = mat.add_material(f, name="Glass", category="glass")
        for material, s in ((self.frame, self.frame_style), (self.glass, self.glass_style)):
            ifcopenshell.api.style.assign_material_style(f, material=material, style=s, context=body)
        wall_material = mat.add_material(f, name="Wall", description="the photographed wall (material unknown)")
        layers = mat.add_material_set(f, name=f"Wall {thickness_m * 1000:.0f} mm", set_type="IfcMaterialLayerSet")
        layer = mat.add_layer(f, layer_set=layers, material=wall_material)
        mat.edit_layer(f, layer=layer, attributes={"LayerThickness": float(thickness_m)})
        self.wall_type = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWallType", predefined_type="STANDARD",
                                                             name=f"Photographed wall {thickness_m * 1000:.0f} mm")
        mat.assign_material(f, products=[self.wall_type], type="IfcMaterialLayerSet", material=layers)
        self.window_types: dict[str, object] = {}

    def window_type(self, size: TypeSize, context):
        """The IfcWindowType of this style for windows of ``size`` (ifc_window.type_sizes): "<style>
        <w> x <h> m", its body (ifc_window.window_body, in ``context``) as its RepresentationMap."""
        if size.key not in self.window_types:
            f, mat = self.f, ifcopenshell.api.material
            cls = size_class(size.width_m * size.height_m)
            wtype = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWindowType", predefined_type="WINDOW",
                                                        name=f"{self.style.name} {size.width_m:.2f} x "
                                                             f"{size.height_m:.2f} m")
            wtype.PartitioningType, user_defined = partitioning(self.style)
            if user_defined is not None:
                wtype.UserDefinedPartitioningType = user_defined
            wtype.RepresentationMaps = (window_body(f, context, size, wtype.PartitioningType, self.frame_style,
                                                    self.glass_style),)
            constituents = mat.add_material_set(f, name=f"Window {self.style.name}",
                                                set_type="IfcMaterialConstituentSet")
            mat.add_constituent(f, constituent_set=constituents, material=self.frame, name="Framing")
            mat.add_constituent(f, constituent_set=constituents, material=self.glass, name="Glazing")
            mat.assign_material(f, products=[wtype], type="IfcMaterialConstituentSet", material=constituents)
            bounds = dict(WINDOW_SIZE_CLASSES)
            lower = max([0.0] + [b for _, b in WINDOW_SIZE_CLASSES if b < bounds[cls]])
            _add_pset(f, wtype, "Fenestra_WindowType", {
                "Style": self.style.name, "SizeClass": cls, "Width": size.width_m, "Height": size.height_m,
                "AreaRange": f"{lower:g} to {bounds[cls]:g} m2 (void area at the model's scale)"})
            self.window_types[size.key] = wtype
        return self.window_types[size.key]


def write_ifc(path: str | Path, K: np.ndarray, placed: list[PlacedWindow], layout: TextureLayout,
              texture_file: str = "texture.png", style: str | WindowStyle = "casement-white",
              margin_m: float = WALL_MARGIN_M, thickness_m: float = WALL_THICKNESS_M,
              walls: dict[int, int] | None = None, properties: dict[int, dict] | None = None,
              wall_properties: dict[int, dict] | None = None, levels: Floors | None = None,
              gps: tuple | None = None, source: str | None = None, doors: list[PlacedWindow] = (),
              door_walls: dict[int, int] | None = None,
              door_properties: dict[int, dict] | None = None) -> tuple[dict[int, dict], dict[int, dict], list[dict]]:
    """Write model.ifc for the placed windows and doors; return ({window index: {"wall", "covering",
    "opening", "window": GlobalId, "storey": name, "window_type": name}}, {door index: {"opening",
    "door", "storey", "door_type"}}, doors skipped [{"index", "reason"}]).

    ``placed`` in the export world the OBJ/GLB use (geometry.grounded: ground at z = 0).
    ``texture_file`` is the texture's path relative to the IFC file (written by the caller).
    walls: {window index: wall id}: one IfcWall per façade plane (walls_plan.facade_walls: wall ids
    on one plane merged; the extent the photo shows, from the ground up; cut at a corner with
    another wall), each window's opening voiding it; None (or a window without an id): a wall
    fragment per window (its void + ``margin_m``). K (3, 3): the texture's photo region's. properties: {window index: {name: value}}, written as the
    window's property set "Fenestra_Window" (with Pset_WindowCommon IsExternal); wall_properties:
    {wall id: {name: value}} as "Fenestra_Wall". levels: the floors, one IfcBuildingStorey each
    (pipeline.export.floors.Floors; default floors.floor_levels of ``placed``, ``walls`` and ``doors``):
    every window, door, wall (its lowest window's) and covering is contained in one. doors: placed
    doors (indices of their own), each in the IfcWall of its wall id ``door_walls`` (ifc_door.py),
    ``door_properties`` {door index: {name: value}} their Fenestra_Door property sets. gps: (latitude deg, longitude deg[, elevation m]) of the
    camera (the world's origin): the site's reference and an IfcMapConversion (see _georeference).
    source: the photo's file name, which the file's provenance names (:func:`stamp_provenance`).
    """
    style = get_style(style)
    if gps is not None:
        _check_gps(gps)
    from fenestra.pipeline.export.ifc_door import write_doors  # noqa: PLC0415  (it reads this module's helpers)

    levels = floor_levels(placed, walls, list(doors)) if levels is None else levels
    f, contexts, storeys = _new_file("Fenestra reconstruction", levels, gps)
    lib = _Library(f, contexts["body"], style, texture_file, thickness_m)
    ids: dict[int, dict] = {}
    sizes = type_sizes(placed)
    built: dict[int, tuple] = {}  # wall id: (IfcWall, {the id of a wall it meets at a corner: its end there})
    wall_of: dict = {}  # façade model wall id (merged ones included) -> its IfcWall (the doors' walls)
    for fw in facade_walls(placed, walls, K, (layout.photo_width, layout.photo_height), margin_m):
        storey = storeys[min(levels.floor_of.get(pw.index, 0) for pw in fw.members)]
        wall = _wall(f, contexts, storey, fw.frame, list(fw.holes), f"Wall {fw.id}", lib.wall_type, fw.margin_m,
                     thickness_m)
        covering = _photo_covering(f, contexts["body"], storey, K, wall, fw.frame, list(fw.holes), layout,
                                   lib.texture, lib.wall_style, fw.margin_m)
        if not fw.own:
            _add_pset(f, wall, "Fenestra_Wall", {**(wall_properties or {}).get(fw.id, {}),
                                                 "MergedWalls": ", ".join(map(str, fw.merged_from)),
                                                 "CornerWith": ", ".join(f"Wall {c}" for c, _ in fw.corners) or None})
            built[fw.id] = (wall, dict(fw.corners))
            wall_of.update({w: wall for w in (fw.id, *fw.merged_from)})
        for pw in fw.members:
            ids[pw.index] = {"wall": wall.GlobalId, "covering": covering.GlobalId,
                             **_window_in_wall(f, contexts["body"], storeys[levels.floor_of.get(pw.index, 0)], wall, pw,
                                               lib, sizes[pw.index], thickness_m, (properties or {}).get(pw.index))}
    for a, (wall_a, ends_a) in built.items():  # each corner once, as IFC's path connection of two walls
        for b, end_a in ends_a.items():
            if a < b:
                f.createIfcRelConnectsPathElements(
                    GlobalId=ifcopenshell.guid.new(), Name="Corner", RelatingElement=wall_a, RelatedElement=built[b][0],
                    RelatingPriorities=(), RelatedPriorities=(), RelatingConnectionType=end_a,
                    RelatedConnectionType=built[b][1][a])
    door_ids, doors_skipped = write_doors(f, contexts["body"], storeys, wall_of, list(doors), door_walls or {},
                                          levels.door_floor_of, thickness_m, door_properties, OPENING_OVERSHOOT_M)
    stamp_provenance(f, Path(path).name, source)
    write_ifc_file(f, path)
    return ids, door_ids, doors_skipped


def stamp_provenance(f: ifcopenshell.file, file_name: str, source: str | None = None,
                     when: float | None = None) -> None:
    """Say what the file is, what wrote it, from what and when.

    The STEP header: FILE_NAME with the file's own name (not ``/dev/null``), Fenestra and its
    version as the originating system, IfcOpenShell's as the preprocessor, author and organization
    empty (the photographer is not known), no ``Nobody``; FILE_DESCRIPTION adds the photo's name.
    In the model: an IfcApplication (Fenestra, its version) owning every rooted entity through one
    IfcOwnerHistory (created ``when``, seconds since the epoch, default now), and the project's
    Description naming the photo. Args: f, the file; file_name, its name; source, the photo's
    file name (None: not said); when, the creation time (s)."""

    import fenestra  # noqa: PLC0415  (the version, read from the package metadata on first use)

    h = f.header.file_name
    h.name = file_name
    h.author, h.organization, h.authorization = ("",), ("",), ""
    h.preprocessor_version = f"IfcOpenShell {ifcopenshell.version}"
    h.originating_system = f"Fenestra {fenestra.__version__}"
    org = f.createIfcOrganization(Name="Fenestra")
    app = f.createIfcApplication(ApplicationDeveloper=org, Version=str(fenestra.__version__),
                                 ApplicationFullName="Fenestra: single-photo façade reconstruction",
                                 ApplicationIdentifier="fenestra")
    user = f.createIfcPersonAndOrganization(ThePerson=f.createIfcPerson(Identification="fenestra"), TheOrganization=org)
    history = f.createIfcOwnerHistory(OwningUser=user, OwningApplication=app,
                                      CreationDate=int(time.time() if when is None else when))
    for e in f.by_type("IfcRoot"):
        e.OwnerHistory = history
    if source:  # a name that is not UTF-8 (surrogate-escaped bytes) is written with its bytes escaped
        words = "reconstructed by Fenestra from the photo " + source.encode("utf-8", "backslashreplace").decode("utf-8")
        f.header.file_description.description = (*f.header.file_description.description, words)
        for project in f.by_type("IfcProject"):
            project.Description = words


def _window_in_wall(f, body, storey, wall, pw: PlacedWindow, lib: _Library, size: TypeSize, thickness_m: float,
                    props: dict | None) -> dict:
    """The opening voiding ``wall`` (IfcRelVoidsElement) and the IfcWindow filling it
    (IfcRelFillsElement) in ``storey``: ``pw`` in its wall's axes (walls_plan.aligned), so the
    opening's box runs square through the wall; the window placed in the wall's axes (x along,
    y into the wall, z up) at the void's bottom-left, its Body its type's (``size``) mapped and
    scaled to its measured width and height; with its quantities and psets."""
    T = pw.export_matrix()
    e = OPENING_OVERSHOOT_M
    opening = ifcopenshell.api.root.create_entity(f, ifc_class="IfcOpeningElement", name=f"Void {pw.index}")
    ifcopenshell.api.feature.add_feature(f, feature=opening, element=wall)
    ifcopenshell.api.geometry.edit_object_placement(f, product=opening, matrix=T)
    box = _rectangle_solid(f, 0.0, 0.0, pw.width_m, pw.height_m, e, (0.0, 0.0, -1.0),
                           COVERING_THICKNESS_M + thickness_m + 2 * e)
    ifcopenshell.api.geometry.assign_representation(
        f, product=opening, representation=f.createIfcShapeRepresentation(body, "Body", "SweptSolid", [box]))
    window = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWindow", predefined_type="WINDOW",
                                                 name=f"Window {pw.index} ({lib.style.name})")
    window.OverallWidth, window.OverallHeight = float(pw.width_m), float(pw.height_m)
    ifcopenshell.api.feature.add_filling(f, opening=opening, element=window)
    ifcopenshell.api.spatial.assign_container(f, products=[window], relating_structure=storey)
    axes = np.eye(4)
    axes[:3, :3] = _WALL_AXES
    ifcopenshell.api.geometry.edit_object_placement(f, product=window, matrix=T @ axes)
    wtype = lib.window_type(size, body)
    window.PartitioningType = wtype.PartitioningType
    if wtype.UserDefinedPartitioningType is not None:
        window.UserDefinedPartitioningType = wtype.UserDefinedPartitioningType
    if wtype.Types:  # one IfcRelDefinesByType per type (not assign_type: it would map the body unscaled)
        wtype.Types[0].RelatedObjects += (window,)
    else:
        f.createIfcRelDefinesByType(ifcopenshell.guid.new(), None, None, None, [window], wtype)
    ifcopenshell.api.geometry.assign_representation(
        f, product=window, representation=mapped_body(f, body, wtype.RepresentationMaps[0], size, pw.width_m,
                                                      pw.height_m))
    _add_qto(f, window, "Qto_WindowBaseQuantities",
             {"Width": pw.width_m, "Height": pw.height_m, "Area": pw.width_m * pw.height_m,
              "Perimeter": 2.0 * (pw.width_m + pw.height_m)})
    if props is not None:
        _add_pset(f, window, "Pset_WindowCommon", {"IsExternal": True})
        _add_pset(f, window, "Fenestra_Window", props)
    return {"opening": opening.GlobalId, "window": window.GlobalId, "storey": storey.Name, "window_type": wtype.Name}
