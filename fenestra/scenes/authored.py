"""Hand-authored IFC4 houses: the held-out building families of the learned-detector figures.

    >>> from fenestra.scenes.authored import terrace_house
    >>> windows = terrace_house("out/authored-terrace.ifc")   # tuple of generate.ExpectedOpening
    >>> windows[0].corners_world                              # (4, 3) m, TL TR BR BL from outside

Why (docs DESIGN.md, "held out means held out by family"): ``fenestra.scenes.generate``
made the procedural training houses, so its outputs are "same generator", not unseen families.
Every element of these two houses is placed here by hand (``ifcopenshell.api``), with construction
the generator never makes, and no training script renders them (tests/scenes/test_scenes_authored.py
reads the scripts). ``fenestra scenes author OUT_DIR`` writes both; the committed copies are
``fenestra/scenes/ifc/authored-*.ifc`` (registry names ``authored-terrace``, ``authored-studio``).

- :func:`terrace_house`: a row of three terraced units, 16.8 x 8.4 m, 0.45 m brick walls, storeys
  3.05 m and 2.65 m and an attic under a 40 deg gable roof. Glass recessed 0.19-0.26 m behind the
  wall face in deep reveals, deep projecting stone sills (0.12-0.30 m), thin tall windows,
  mullioned bay windows, a dormer per unit (a window in a small gabled roof on the front slope),
  gable-end attic windows, party-wall piers, solid doors. 33 windows.
- :func:`studio_house`: an L-shaped studio (non-convex), 13 x 11 m, 0.3 m walls, storeys 3.45 m
  and 3.1 m, a flat roof overhanging 0.6 m. Ribbon windows (aspect 5.1-7.3), two corner windows
  (each two windows meeting at a convex corner, one in each wall), thin tall windows (aspect
  4.5-5.5), mullioned and recessed windows. 27 windows.

Construction (metres, world z up):
- A wall: its exterior face line a -> b in plan with the outside on the right of a -> b
  (counter-clockwise footprints); its body is an IfcExtrudedAreaSolid of its face profile
  (s along a -> b from a, world z) extruded inward by its thickness. Walls meet at convex corners
  by overlapping (both cover the corner square); at a reflex corner the arriving wall runs on by
  its thickness to close the inner corner.
- A window's void: an IfcOpeningElement prism through its wall (0.1 m beyond both faces),
  s from ``off`` to ``off + width``, z from ``sill`` to ``sill + height`` (world). Its ground truth,
  which the loader must give: that rectangle on the exterior face line, the reveal included.
  The IfcWindow (``generate.window_parts``: a frame ring, bars, 12 mm glass panes; or a ribbon's
  frame and mullions) is FRAME_DEPTH deep, ``setback`` behind the face; OverallWidth/Height = the
  void's size.
- Corner windows: the void of the window that ends a wall runs to the wall's end (the corner on
  the exterior face), that of the next wall's first window from its start, so both cut the corner
  square. Their bodies do not overlap: the first stops at the second's outer plane, the second
  starts behind the first's inner plane (both have the same setback).
- GlobalIds come from ``generate._seeded_guids(seed)`` and the header time stamp is fixed, so a
  house's entities, geometry and ids are the same on every run (like generate.make_house, only
  the order inside unordered IFC SETs could differ between processes).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fenestra.files import write_ifc_file
from fenestra.scenes.generate import (IFC_TIMESTAMP, PANE_THICKNESS, ExpectedOpening, _bars,
                                      _placement, _seeded_guids, box_mesh, offset_polygon,
                                      window_parts)

EZ = np.array([0.0, 0.0, 1.0])
FRAME_DEPTH = 0.07  # m, every IfcWindow body
OPENING_MARGIN = 0.1  # m, an opening prism reaches beyond both wall faces
SILL_HEIGHT = 0.07  # m, a projecting sill's thickness; its top is the void's bottom
SILL_OVERHANG = 0.08  # m, a sill's reach beyond each side of the void
SLAB_INSET = 0.01  # m, floor slabs stop short of the wall faces (no coplanar faces)
RIBBON_BAY = 1.2  # m, a ribbon window's bay (mullion spacing, rounded to fit)
RIBBON_BAR = 0.06  # m, a ribbon window's frame and mullion width

Point = tuple[float, float]
Poly = tuple[Point, ...]
Vec3 = tuple[float, float, float]


def rect(x0: float, z0: float, w: float, h: float) -> Poly:
    """Counter-clockwise rectangle (4 points) with its lower left at (x0, z0), w x h."""
    return ((x0, z0), (x0 + w, z0), (x0 + w, z0 + h), (x0, z0 + h))


# --------------------------------------------------------------------------- plan records
@dataclass(frozen=True)
class Wall:
    """A wall: exterior face line a -> b (plan, m; outside on the right), thickness inward, and its
    face profile (K, 2): (s m along a -> b from a, world z m), counter-clockwise."""

    name: str
    storey: int
    a: Point
    b: Point
    thickness: float
    profile: Poly

    @property
    def length(self) -> float:
        return float(np.hypot(self.b[0] - self.a[0], self.b[1] - self.a[1]))

    @property
    def u(self) -> np.ndarray:
        """(3,) unit vector along a -> b."""
        return np.array([self.b[0] - self.a[0], self.b[1] - self.a[1], 0.0]) / self.length

    @property
    def inward(self) -> np.ndarray:
        """(3,) unit horizontal normal into the wall (left of a -> b)."""
        return np.cross(EZ, self.u)

    def at(self, s: float, z: float = 0.0) -> np.ndarray:
        """(3,) world point on the exterior face, s m along a -> b, at world height z."""
        return np.array([self.a[0], self.a[1], 0.0]) + s * self.u + z * EZ


def box_wall(name: str, storey: int, a: Point, b: Point, thickness: float, z0: float,
             height: float, run_on: float = 0.0) -> Wall:
    """A rectangular wall from z0 up by height; run_on m past b (a reflex corner)."""
    length = float(np.hypot(b[0] - a[0], b[1] - a[1]))
    return Wall(name, storey, a, b, thickness, rect(0.0, z0, length + run_on, height))


@dataclass(frozen=True)
class Win:
    """A window: its void on wall ``wall`` (s from off, world z from sill, width x height m), the
    body ``setback`` m behind the face in ``style`` (generate.WINDOW_STYLES or "ribbon"),
    ``features`` (names of FEATURES), a projecting sill ``sill_depth`` m deep (0: none), and
    ``corner``: "end" / "start" when the void reaches the wall's end / start (corner windows)."""

    name: str
    wall: str
    off: float
    sill: float
    width: float
    height: float
    setback: float
    style: str
    features: tuple[str, ...]
    sill_depth: float = 0.0
    corner: str = ""


@dataclass(frozen=True)
class Door:
    """A solid door in wall ``wall``: void s from off, world z from z0, width x height m."""

    name: str
    wall: str
    off: float
    z0: float
    width: float
    height: float
    setback: float = 0.15


@dataclass(frozen=True)
class Prism:
    """A planar polygon (K, 2) m in the frame (origin (3,), unit x_dir, unit y_dir orthogonal to
    it) extruded by depth m along x_dir x y_dir: one IfcExtrudedAreaSolid element."""

    name: str
    ifc_class: str
    storey: int
    origin: Vec3
    x_dir: Vec3
    y_dir: Vec3
    polygon: Poly
    depth: float
    style: str
    predefined: str | None = None


@dataclass(frozen=True)
class Plan:
    """Everything a house is made of: storeys (name, elevation m), walls, windows, doors, other
    parts (slabs, roofs, piers), surface styles name -> (rgb, transparency), the GlobalId seed."""

    name: str
    seed: int
    storeys: tuple[tuple[str, float], ...]
    walls: tuple[Wall, ...]
    windows: tuple[Win, ...]
    doors: tuple[Door, ...]
    parts: tuple[Prism, ...]
    styles: tuple[tuple[str, Vec3, float], ...]


FEATURES = ("recessed", "deep_sill", "ribbon", "corner", "thin_tall", "dormer", "mullioned", "gable")


# --------------------------------------------------------------------------- pure geometry
def wall_prism(w: Wall) -> Prism:
    """A wall's body: its face profile in (u, z) extruded from the inner face outward (u x z is
    the outward normal), so it spans the thickness behind the exterior face."""
    origin = w.at(0.0) + w.thickness * w.inward
    return Prism(w.name, "IfcWall", w.storey, tuple(origin), tuple(w.u), tuple(EZ), w.profile,
                 w.thickness, "wall")


def facade_prism(w: Wall, name: str, ifc_class: str, outline: Poly, inset: float, depth: float,
                 style: str) -> Prism:
    """outline (s, z) on wall w's face frame, from ``inset`` m behind the face out by depth m
    (inset 0: a part standing proud of the face, e.g. a sill or a pier)."""
    origin = w.at(0.0) + inset * w.inward
    return Prism(name, ifc_class, w.storey, tuple(origin), tuple(w.u), tuple(EZ), outline, depth,
                 style)


def opening_prism(w: Wall, name: str, off: float, z0: float, width: float, height: float) -> Prism:
    """The IfcOpeningElement of a void: through w and OPENING_MARGIN beyond both faces."""
    return facade_prism(w, name, "IfcOpeningElement", rect(off, z0, width, height),
                        w.thickness + OPENING_MARGIN, w.thickness + 2 * OPENING_MARGIN, "")


def sill_prism(w: Wall, win: Win) -> Prism:
    """A window's projecting sill: SILL_OVERHANG wider each side, top at the void's bottom."""
    outline = rect(win.off - SILL_OVERHANG, win.sill - SILL_HEIGHT, win.width + 2 * SILL_OVERHANG,
                   SILL_HEIGHT)
    return facade_prism(w, f"{win.name} sill", "IfcMember", outline, 0.0, win.sill_depth, "sill")


def body_span(win: Win) -> tuple[float, float]:
    """(x0, x1) m of the window body inside its void (x from the void's left edge): the whole
    width, except at a corner (see the module doc)."""
    if win.corner == "end":
        return 0.0, win.width - win.setback
    if win.corner == "start":
        return win.setback + FRAME_DEPTH, win.width
    return 0.0, win.width


def ribbon_parts(width: float, height: float, depth: float) -> tuple[list, list]:
    """A ribbon window's boxes (generate.Box3, window-local: x along the wall, y inward, z up):
    (frame ring + mullions every ~RIBBON_BAY m, glass panes between them)."""
    f = RIBBON_BAR
    n = max(1, int(round(width / RIBBON_BAY)))
    frame = [(0.0, 0.0, 0.0, width, depth, f), (0.0, 0.0, height - f, width, depth, height),
             (0.0, 0.0, f, f, depth, height - f), (width - f, 0.0, f, width, depth, height - f)]
    starts, spans = _bars(f, width - f, n - 1, f)
    frame += [(x, 0.0, f, x + f, depth, height - f) for x in starts]
    py = depth / 2 - PANE_THICKNESS / 2
    return frame, [(x0, py, f, x1, py + PANE_THICKNESS, height - f) for x0, x1 in spans]


def window_boxes(win: Win, rng: np.random.Generator) -> list:
    """Every box of the window body (generate.Box3 in the body's frame, x from body_span's x0)."""
    x0, x1 = body_span(win)
    if win.style == "ribbon":
        frame, panes = ribbon_parts(x1 - x0, win.height, FRAME_DEPTH)
    else:
        frame, panes = window_parts(x1 - x0, win.height, FRAME_DEPTH, win.style, rng)
    return frame + panes


def expected_window(w: Wall, win: Win, global_id: str, wall_index: int) -> ExpectedOpening:
    """The window's ground truth by construction: its void on the exterior face (TL TR BR BL);
    wall_index: its wall's place in Plan.walls."""
    bl = w.at(win.off, win.sill)
    du, dz = win.width * w.u, win.height * EZ
    return ExpectedOpening(name=win.name, wall_index=wall_index, storey=w.storey, width=win.width,
                           height=win.height, sill=win.sill, corners_world=np.stack(
                               [bl + dz, bl + du + dz, bl + du, bl]), normal=-w.inward,
                           element_id=global_id)


def prism_matrix(p: Prism) -> np.ndarray:
    """4x4 placement of a prism's frame: columns x_dir, y_dir, x_dir x y_dir, origin."""
    m = np.eye(4)
    x, y = np.asarray(p.x_dir, float), np.asarray(p.y_dir, float)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, np.cross(x, y), p.origin
    return m


# --------------------------------------------------------------------------- IFC writing
@dataclass
class _Ifc:
    """An IFC file being written: the file, its body context, storeys and styles by name."""

    f: object
    body: object
    storeys: list
    styles: dict


def _api(*args, **kwargs):
    import ifcopenshell.api  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    return ifcopenshell.api.run(*args, **kwargs)


def _new_file(plan: Plan) -> _Ifc:
    """Project, units, contexts, site/building, the plan's storeys and styles."""
    import ifcopenshell  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    f = ifcopenshell.file(schema="IFC4")
    project = _api("root.create_entity", f, ifc_class="IfcProject", name=plan.name)
    _api("unit.assign_unit", f, length={"is_metric": True, "raw": "METERS"})
    model = _api("context.add_context", f, context_type="Model")
    body = _api("context.add_context", f, context_type="Model", context_identifier="Body",
                target_view="MODEL_VIEW", parent=model)
    site = _api("root.create_entity", f, ifc_class="IfcSite", name="Site")
    building = _api("root.create_entity", f, ifc_class="IfcBuilding", name=plan.name)
    _api("aggregate.assign_object", f, products=[site], relating_object=project)
    _api("aggregate.assign_object", f, products=[building], relating_object=site)
    storeys = []
    for name, elevation in plan.storeys:
        st = _api("root.create_entity", f, ifc_class="IfcBuildingStorey", name=name)
        st.Elevation = elevation
        _api("aggregate.assign_object", f, products=[st], relating_object=building)
        storeys.append(st)
    styles = {}
    for name, rgb, transparency in plan.styles:
        st = _api("style.add_style", f, name=name)
        _api("style.add_surface_style", f, style=st, ifc_class="IfcSurfaceStyleShading", attributes={
            "SurfaceColour": {"Name": None, "Red": rgb[0], "Green": rgb[1], "Blue": rgb[2]},
            "Transparency": transparency})
        styles[name] = st
    return _Ifc(f, body, storeys, styles)


def _element(ifc: _Ifc, ifc_class: str, name: str, storey: int | None, matrix: np.ndarray, rep,
             style: str = ""):
    """A product with placement, representation, style and (storey given) spatial container."""
    el = _api("root.create_entity", ifc.f, ifc_class=ifc_class, name=name)
    _api("geometry.edit_object_placement", ifc.f, product=el, matrix=matrix)
    _api("geometry.assign_representation", ifc.f, product=el, representation=rep)
    if style:
        _api("style.assign_representation_styles", ifc.f, shape_representation=rep,
             styles=[ifc.styles[style]])
    if storey is not None:
        _api("spatial.assign_container", ifc.f, products=[el], relating_structure=ifc.storeys[storey])
    return el


def _add_prism(ifc: _Ifc, p: Prism, contained: bool = True):
    """One element whose body is the prism (an IfcExtrudedAreaSolid of an arbitrary profile)."""
    rep = _api("geometry.add_slab_representation", ifc.f, context=ifc.body, depth=p.depth,
               polyline=[tuple(map(float, q)) for q in p.polygon])
    el = _element(ifc, p.ifc_class, p.name, p.storey if contained else None, prism_matrix(p), rep,
                  p.style)
    if p.predefined:
        el.PredefinedType = p.predefined
    return el


def _add_window(ifc: _Ifc, wall_index: int, wall: Wall, wall_el, win: Win,
                rng: np.random.Generator) -> ExpectedOpening:
    """Opening voiding wall_el, IfcWindow filling it (body setback behind the face), its sill."""
    opening = _add_prism(ifc, opening_prism(wall, f"Opening {win.name}", win.off, win.sill,
                                            win.width, win.height), contained=False)
    _api("feature.add_feature", ifc.f, feature=opening, element=wall_el)
    verts, faces = box_mesh(window_boxes(win, rng))
    rep = _api("geometry.add_mesh_representation", ifc.f, context=ifc.body, vertices=verts,
               faces=faces)
    origin = wall.at(win.off + body_span(win)[0], win.sill) + win.setback * wall.inward
    el = _element(ifc, "IfcWindow", win.name, wall.storey, _placement(origin, wall.u), rep, "glass")
    el.OverallWidth, el.OverallHeight = win.width, win.height
    _api("feature.add_filling", ifc.f, opening=opening, element=el)
    if win.sill_depth > 0:
        _add_prism(ifc, sill_prism(wall, win))
    return expected_window(wall, win, el.GlobalId, wall_index)


def _add_door(ifc: _Ifc, _wall_index: int, wall: Wall, wall_el, d: Door) -> None:
    """Opening voiding wall_el, filled by a solid IfcDoor FRAME_DEPTH deep, setback behind."""
    opening = _add_prism(ifc, opening_prism(wall, f"Opening {d.name}", d.off, d.z0, d.width,
                                            d.height), contained=False)
    _api("feature.add_feature", ifc.f, feature=opening, element=wall_el)
    el = _add_prism(ifc, facade_prism(wall, d.name, "IfcDoor", rect(d.off, d.z0, d.width, d.height),
                                      d.setback + FRAME_DEPTH, FRAME_DEPTH, "door"))
    el.OverallWidth, el.OverallHeight = d.width, d.height
    _api("feature.add_filling", ifc.f, opening=opening, element=el)


def write_plan(plan: Plan, path: str | Path) -> tuple[ExpectedOpening, ...]:
    """Write the IFC4 file of ``plan`` to path; return each window's ground truth by construction
    (GlobalIds seeded by plan.seed; window bar widths drawn from default_rng([seed, 13]))."""
    with _seeded_guids(plan.seed):
        ifc = _new_file(plan)
        walls = {w.name: (i, w, _add_prism(ifc, wall_prism(w))) for i, w in enumerate(plan.walls)}
        rng = np.random.default_rng([plan.seed, 13])
        out = tuple(_add_window(ifc, *walls[win.wall], win, rng) for win in plan.windows)
        for d in plan.doors:
            _add_door(ifc, *walls[d.wall], d)
        for p in plan.parts:
            _add_prism(ifc, p)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    ifc.f.header.file_name.time_stamp = IFC_TIMESTAMP
    write_ifc_file(ifc.f, path)
    return out


# --------------------------------------------------------------------------- shared parts
def floor_slab(name: str, storey: int, footprint: Poly, z_top: float, thickness: float) -> Prism:
    """A floor slab: the footprint inset by SLAB_INSET, from z_top down by thickness."""
    poly = offset_polygon(np.asarray(footprint, float), -SLAB_INSET)
    return Prism(name, "IfcSlab", storey, (0.0, 0.0, z_top - thickness), (1.0, 0.0, 0.0),
                 (0.0, 1.0, 0.0), tuple(map(tuple, poly)), thickness, "slab", "FLOOR")


def ring_walls(prefix: str, storey: int, footprint: Poly, thickness: float, z0: float,
               height: float, run_on: tuple[float, ...]) -> list[Wall]:
    """One box wall per footprint edge (counter-clockwise), named f"{prefix}{i}"; run_on[i] m past
    the edge's end (the thickness at a reflex corner, else 0)."""
    n = len(footprint)
    return [box_wall(f"{prefix}{i}", storey, footprint[i], footprint[(i + 1) % n], thickness, z0,
                     height, run_on[i]) for i in range(n)]


# --------------------------------------------------------------------------- the terrace
TERRACE_SEED = 3601
T_LEN, T_DEPTH, T_WALL = 16.8, 8.4, 0.45  # footprint (x along the street, y deep), wall thickness
T_UNIT = 5.6  # m, one unit's frontage (three units)
T_H0, T_H1 = 3.05, 2.65  # storey heights; the attic floor is at T_H0 + T_H1
T_PITCH = np.radians(40.0)
T_ROOF, T_EAVE, T_VERGE = 0.22, 0.4, 0.3  # roof thickness, overhangs at the eaves / the gables
T_FOOTPRINT: Poly = ((0.0, 0.0), (T_LEN, 0.0), (T_LEN, T_DEPTH), (0.0, T_DEPTH))
# dormer: front wall at T_DORMER_Y from the front face, half width, eave height, roof pitch
T_DORMER_Y, T_DORMER_HALF, T_DORMER_EAVE, T_DORMER_PITCH = 1.0, 0.95, 8.3, np.radians(35.0)
T_DORMER_WALL, T_DORMER_ROOF = 0.15, 0.15
T_DORMER_SILL = 7.1  # m, world: 0.15 m above the main roof's top behind the dormer wall


def terrace_roof_z(y: float) -> float:
    """World z (m) of the front roof slope's underside at y m behind the front face."""
    return T_H0 + T_H1 + y * np.tan(T_PITCH)


def slope_length(run: float, pitch: float, thickness: float) -> float:
    """Length (m) of a roof plane's underside over a horizontal run at pitch (rad), plus
    thickness * tan(pitch) so that it closes against its mirror image at the ridge (pitch < 45 deg:
    the overshoot stays inside the mirror plane)."""
    return run / np.cos(pitch) + thickness * np.tan(pitch)


def roof_plane(name: str, origin: Vec3, x_dir: Vec3, y_dir: Vec3, x_len: float, y_len: float,
               thickness: float) -> Prism:
    """A flat plate x_len x y_len m from origin along x_dir, y_dir (unit), thickness m along
    x_dir x y_dir (which must point up and out): an IfcSlab ROOF in the attic (storey 2)."""
    return Prism(name, "IfcSlab", 2, origin, x_dir, y_dir, rect(0.0, 0.0, x_len, y_len), thickness,
                 "roof", "ROOF")


def terrace_roof() -> list[Prism]:
    """The two main roof planes (eave overhang T_EAVE, verge overhang T_VERGE)."""
    c, s = np.cos(T_PITCH), np.sin(T_PITCH)
    z = T_H0 + T_H1 - T_EAVE * np.tan(T_PITCH)
    length, run = T_LEN + 2 * T_VERGE, T_DEPTH / 2 + T_EAVE
    slope = slope_length(run, T_PITCH, T_ROOF)
    return [roof_plane("Roof front", (-T_VERGE, -T_EAVE, z), (1.0, 0.0, 0.0), (0.0, c, s), length,
                       slope, T_ROOF),
            roof_plane("Roof back", (T_LEN + T_VERGE, T_DEPTH + T_EAVE, z), (-1.0, 0.0, 0.0),
                       (0.0, -c, s), length, slope, T_ROOF)]


def terrace_walls() -> list[Wall]:
    """Storey walls (front, east, back, west per storey) and the two attic gables."""
    z2 = T_H0 + T_H1
    walls = (ring_walls("G", 0, T_FOOTPRINT, T_WALL, 0.0, T_H0, (0.0,) * 4)
             + ring_walls("F", 1, T_FOOTPRINT, T_WALL, T_H0, T_H1, (0.0,) * 4))
    gable = ((0.0, z2), (T_DEPTH, z2), (T_DEPTH / 2, terrace_roof_z(T_DEPTH / 2)))
    walls += [Wall("gable-east", 2, (T_LEN, 0.0), (T_LEN, T_DEPTH), T_WALL, gable),
              Wall("gable-west", 2, (0.0, T_DEPTH), (0.0, 0.0), T_WALL, gable)]
    return walls


def dormer(k: int, xc: float) -> tuple[list[Wall], list[Prism], Win]:
    """Dormer k centred at x = xc on the front slope: a pentagonal front wall (its window: 1.0 x
    1.0 m, two lights), two triangular cheeks, two small roof planes; all in the attic (storey 2)."""
    y0, hw, ze = T_DORMER_Y, T_DORMER_HALF, T_DORMER_EAVE
    zb, zr = terrace_roof_z(y0), ze + hw * np.tan(T_DORMER_PITCH)
    yc = (ze - T_H0 - T_H1) / np.tan(T_PITCH)  # where the main roof's underside reaches ze
    d = yc - y0
    front = Wall(f"dormer-{k}", 2, (xc - hw, y0), (xc + hw, y0), T_DORMER_WALL,
                 ((0.0, zb), (2 * hw, zb), (2 * hw, ze), (hw, zr), (0.0, ze)))
    cheeks = [Wall(f"dormer-{k} cheek L", 2, (xc - hw, yc), (xc - hw, y0), 0.12,
                   ((0.0, ze), (d, zb), (d, ze))),
              Wall(f"dormer-{k} cheek R", 2, (xc + hw, y0), (xc + hw, yc), 0.12,
                   ((0.0, zb), (d, ze), (0.0, ze)))]
    c, s, ov = np.cos(T_DORMER_PITCH), np.sin(T_DORMER_PITCH), 0.12  # ov: overhang
    z_top = zr + T_DORMER_ROOF / c  # the dormer roof's top at its ridge
    # back end: 0.3 m past where the main roof's top surface rises above the dormer's ridge
    y_back = (z_top - T_H0 - T_H1 - T_ROOF / np.cos(T_PITCH)) / np.tan(T_PITCH) + 0.3
    z, run = ze - ov * np.tan(T_DORMER_PITCH), hw + ov
    slope, depth = slope_length(run, T_DORMER_PITCH, T_DORMER_ROOF), y_back - (y0 - ov)
    roofs = [roof_plane(f"dormer-{k} roof L", (xc - run, y0 - ov, z), (c, 0.0, s), (0.0, 1.0, 0.0),
                        slope, depth, T_DORMER_ROOF),
             roof_plane(f"dormer-{k} roof R", (xc + run, y_back, z), (-c, 0.0, s), (0.0, -1.0, 0.0),
                        slope, depth, T_DORMER_ROOF)]
    win = Win(f"T dormer {k}", front.name, hw - 0.5, T_DORMER_SILL, 1.0, 1.0, 0.04, "mullion",
              ("dormer", "mullioned"))
    return [front] + cheeks, roofs, win


def terrace_unit(k: int) -> tuple[list[Win], list[Door]]:
    """Unit k's front and back windows and its two doors.

    Front (wall G0/F0, s from x = 0): ground: a mullioned bay 2.0 x 1.6 (sill 0.30 m deep), a thin
    tall 0.45 x 1.9, the door; first floor: two 1.1 x 1.5 (sills 0.25) around a thin tall
    0.4 x 1.8 (sill 0.18); glass 0.22 m behind the face. Back (G2/F2, s from x = T_LEN): a
    transom window 1.8 x 1.4 and a door; above, two 0.9 x 1.2 windows; setback 0.15, sills 0.12."""
    x, z1 = k * T_UNIT, T_H0  # the back wall runs from x = T_LEN, so s = x there too
    wins = [Win(f"T{k} bay", "G0", x + 0.8, 0.75, 2.0, 1.6, 0.22, "grid",
                ("recessed", "deep_sill", "mullioned"), 0.30),
            Win(f"T{k} tall G", "G0", x + 3.1, 0.45, 0.45, 1.9, 0.22, "frame",
                ("recessed", "deep_sill", "thin_tall"), 0.18),
            Win(f"T{k} front F left", "F0", x + 1.25, z1 + 0.7, 1.1, 1.5, 0.22, "transom",
                ("recessed", "deep_sill"), 0.25),
            Win(f"T{k} tall F", "F0", x + 3.125, z1 + 0.45, 0.4, 1.8, 0.22, "frame",
                ("recessed", "deep_sill", "thin_tall"), 0.18),
            Win(f"T{k} front F right", "F0", x + 3.85, z1 + 0.7, 1.1, 1.5, 0.22, "transom",
                ("recessed", "deep_sill"), 0.25),
            Win(f"T{k} back G", "G2", x + 1.4, 0.9, 1.8, 1.4, 0.15, "transom",
                ("recessed", "mullioned"), 0.12),
            Win(f"T{k} back F left", "F2", x + 1.0, z1 + 0.9, 0.9, 1.2, 0.15, "frame",
                ("recessed",), 0.12),
            Win(f"T{k} back F right", "F2", x + 3.4, z1 + 0.9, 0.9, 1.2, 0.15, "frame",
                ("recessed",), 0.12)]
    doors = [Door(f"T{k} door", "G0", x + 3.9, 0.0, 1.0, 2.35, 0.22),
             Door(f"T{k} back door", "G2", x + 3.8, 0.0, 0.9, 2.2)]
    return wins, doors


def terrace_gables() -> list[Win]:
    """Each end wall: a 0.9 x 1.3 window below, a thin tall 0.45 x 1.7 above, a 0.8 x 0.9 attic
    window in the gable; centred on the wall, glass 0.2 m behind the face."""
    z1, z2, c = T_H0, T_H0 + T_H1, T_DEPTH / 2
    out = []
    for side, (g, f, a) in {"east": ("G1", "F1", "gable-east"),
                            "west": ("G3", "F3", "gable-west")}.items():
        out += [Win(f"T {side} G", g, c - 0.45, 0.8, 0.9, 1.3, 0.2, "frame", ("recessed",)),
                Win(f"T {side} F", f, c - 0.225, z1 + 0.5, 0.45, 1.7, 0.2, "frame",
                    ("recessed", "thin_tall")),
                Win(f"T {side} attic", a, c - 0.4, z2 + 1.1, 0.8, 0.9, 0.2, "frame",
                    ("recessed", "gable"))]
    return out


def pier(wall: Wall, x: float, name: str) -> Prism:
    """A stone party-wall pier 0.36 m wide, 0.12 m proud, over both storeys, centred at s = x."""
    return facade_prism(wall, name, "IfcMember", rect(x - 0.18, 0.0, 0.36, T_H0 + T_H1), 0.0, 0.12,
                        "sill")


def terrace_plan() -> Plan:
    """The terrace of three units (see the module doc and terrace_unit / terrace_gables)."""
    walls, wins, doors, parts = terrace_walls(), [], [], []
    for k in range(3):
        w, d = terrace_unit(k)
        wins, doors = wins + w, doors + d
    wins += terrace_gables()
    for k in range(3):
        dw, dr, win = dormer(k, (k + 0.5) * T_UNIT)
        walls, parts, wins = walls + dw, parts + dr, wins + [win]
    g0 = next(w for w in walls if w.name == "G0")
    parts += [pier(g0, k * T_UNIT, f"Pier {k}") for k in (1, 2)]
    z2 = T_H0 + T_H1
    parts += [floor_slab("Floor 0", 0, T_FOOTPRINT, 0.0, 0.25),
              floor_slab("Floor 1", 1, T_FOOTPRINT, T_H0, 0.25),
              floor_slab("Attic floor", 2, T_FOOTPRINT, z2, 0.25)] + terrace_roof()
    return Plan("Fenestra authored terrace", TERRACE_SEED,
                (("Ground", 0.0), ("First", T_H0), ("Attic", z2)), tuple(walls), tuple(wins),
                tuple(doors), tuple(parts), STYLES_TERRACE)


STYLES_TERRACE: tuple[tuple[str, Vec3, float], ...] = (
    ("wall", (0.62, 0.34, 0.26), 0.0), ("slab", (0.6, 0.6, 0.6), 0.0),
    ("roof", (0.30, 0.30, 0.33), 0.0), ("glass", (0.3, 0.5, 0.7), 0.6),
    ("sill", (0.82, 0.80, 0.74), 0.0), ("door", (0.15, 0.22, 0.35), 0.0))


def terrace_house(path: str | Path) -> tuple[ExpectedOpening, ...]:
    """Write the authored terrace (IFC4) to path; return its windows' ground truth."""
    return write_plan(terrace_plan(), path)


# --------------------------------------------------------------------------- the studio
STUDIO_SEED = 3602
S_WALL, S_H0, S_H1, S_ROOF, S_OVERHANG = 0.3, 3.45, 3.1, 0.3, 0.6
S_FOOTPRINT: Poly = ((0.0, 0.0), (13.0, 0.0), (13.0, 7.0), (8.0, 7.0), (8.0, 11.0), (0.0, 11.0))
S_RUN_ON = (0.0, 0.0, S_WALL, 0.0, 0.0, 0.0)  # wall 2 ends at the reflex corner (8, 7)
# (wall, off, sill above the storey floor, width, height, setback, style, features, corner);
# walls G<i> (ground) and U<i> (upper) stand on footprint edge i
S_WINDOWS: tuple[tuple, ...] = (
    ("G0", 0.9, 2.3, 5.0, 0.75, 0.08, "ribbon", ("ribbon",), ""),
    ("G0", 6.6, 0.6, 1.6, 2.0, 0.15, "frame", ("recessed",), ""),
    ("G0", 8.8, 0.4, 0.4, 2.2, 0.1, "frame", ("thin_tall",), ""),
    ("G0", 9.6, 0.4, 0.4, 2.2, 0.1, "frame", ("thin_tall",), ""),
    ("G0", 10.4, 0.4, 0.4, 2.2, 0.1, "frame", ("thin_tall",), ""),
    ("U0", 1.0, 0.8, 1.2, 1.5, 0.15, "frame", ("recessed",), ""),
    ("U0", 3.4, 0.8, 1.2, 1.5, 0.15, "frame", ("recessed",), ""),
    ("U0", 5.8, 0.8, 1.8, 1.5, 0.1, "mullion", ("mullioned",), ""),
    ("U0", 10.6, 0.8, 2.4, 1.5, 0.1, "frame", ("corner",), "end"),
    ("U1", 0.0, 0.8, 1.8, 1.5, 0.1, "frame", ("corner",), "start"),
    ("U1", 3.0, 0.6, 0.4, 1.8, 0.1, "frame", ("thin_tall",), ""),
    ("U1", 4.0, 0.6, 0.4, 1.8, 0.1, "frame", ("thin_tall",), ""),
    ("G1", 1.8, 0.7, 2.4, 1.8, 0.1, "grid", ("mullioned",), ""),
    ("G2", 1.0, 0.3, 1.8, 2.4, 0.1, "transom", ("mullioned",), ""),
    ("G2", 3.7, 0.4, 0.45, 2.2, 0.1, "frame", ("thin_tall",), ""),
    ("U2", 0.6, 1.1, 3.6, 0.7, 0.08, "ribbon", ("ribbon",), ""),
    ("G3", 2.1, 0.7, 1.2, 1.6, 0.15, "frame", ("recessed",), ""),
    ("U3", 0.5, 1.2, 2.8, 0.55, 0.08, "ribbon", ("ribbon",), ""),
    ("G4", 1.5, 0.7, 1.2, 1.6, 0.15, "frame", ("recessed",), ""),
    ("G4", 5.6, 0.3, 2.4, 2.4, 0.1, "frame", ("corner",), "end"),
    ("U4", 1.5, 0.6, 0.35, 1.8, 0.1, "frame", ("thin_tall",), ""),
    ("U4", 2.3, 0.6, 0.35, 1.8, 0.1, "frame", ("thin_tall",), ""),
    ("U4", 4.2, 0.8, 1.6, 1.4, 0.1, "grid", ("mullioned",), ""),
    ("G5", 0.0, 0.3, 2.0, 2.4, 0.1, "frame", ("corner",), "start"),
    ("G5", 4.0, 0.8, 2.0, 1.6, 0.1, "grid", ("mullioned",), ""),
    ("G5", 7.6, 0.8, 1.2, 1.6, 0.15, "frame", ("recessed",), ""),
    ("U5", 1.8, 1.0, 6.6, 0.9, 0.08, "ribbon", ("ribbon",), ""),
)
STYLES_STUDIO: tuple[tuple[str, Vec3, float], ...] = (
    ("wall", (0.92, 0.91, 0.88), 0.0), ("slab", (0.6, 0.6, 0.6), 0.0),
    ("roof", (0.22, 0.22, 0.24), 0.0), ("glass", (0.3, 0.5, 0.7), 0.6),
    ("door", (0.28, 0.28, 0.30), 0.0))


def studio_windows() -> list[Win]:
    """S_WINDOWS as Win records, named "S <wall> <n>"; sills made world heights."""
    base = {"G": 0.0, "U": S_H0}
    return [Win(f"S {wall} {n}", wall, off, base[wall[0]] + sill, w, h, setback, style, feats,
                corner=corner)
            for n, (wall, off, sill, w, h, setback, style, feats, corner) in enumerate(S_WINDOWS)]


def studio_plan() -> Plan:
    """The L-shaped studio (see the module doc): ground and upper walls on the six footprint
    edges, S_WINDOWS, a door into the inner corner, floor slabs and an overhanging flat roof."""
    walls = (ring_walls("G", 0, S_FOOTPRINT, S_WALL, 0.0, S_H0, S_RUN_ON)
             + ring_walls("U", 1, S_FOOTPRINT, S_WALL, S_H0, S_H1, S_RUN_ON))
    top = S_H0 + S_H1
    roof = offset_polygon(np.asarray(S_FOOTPRINT, float), S_OVERHANG)
    parts = (floor_slab("Floor 0", 0, S_FOOTPRINT, 0.0, 0.25),
             floor_slab("Floor 1", 1, S_FOOTPRINT, S_H0, 0.25),
             Prism("Roof", "IfcSlab", 1, (0.0, 0.0, top), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0),
                   tuple(map(tuple, roof)), S_ROOF, "roof", "ROOF"))
    return Plan("Fenestra authored studio", STUDIO_SEED, (("Ground", 0.0), ("Upper", S_H0)),
                tuple(walls), tuple(studio_windows()), (Door("S door", "G3", 0.6, 0.0, 1.0, 2.3),),
                parts, STYLES_STUDIO)


def studio_house(path: str | Path) -> tuple[ExpectedOpening, ...]:
    """Write the authored studio (IFC4) to path; return its windows' ground truth."""
    return write_plan(studio_plan(), path)


# Registry name -> (file name, writer): `fenestra scenes author` writes these.
AUTHORED: dict[str, tuple[str, object]] = {
    "authored-terrace": ("authored-terrace.ifc", terrace_house),
    "authored-studio": ("authored-studio.ifc", studio_house),
}


def author_all(out_dir: str | Path) -> dict[str, tuple[ExpectedOpening, ...]]:
    """Write every authored house into out_dir (created); name -> its windows' ground truth."""
    out_dir = Path(out_dir)
    return {name: writer(out_dir / file) for name, (file, writer) in AUTHORED.items()}
