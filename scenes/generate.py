"""Procedural IFC4 houses with ground truth known by construction (``fenestra scenes make``).

    >>> from scenes.generate import HouseSpec, make_house
    >>> house = make_house(HouseSpec(seed=1, rotation_deg=20), "out/house.ifc")
    >>> house.windows[0].corners_world       # (4, 3) m, TL TR BR BL seen from outside

Geometry (all boxes, written with ``ifcopenshell.api``):
- Footprint: a convex polygon (m, counter-clockwise seen from above; clockwise input is reversed),
  rotated by ``rotation_deg`` about the origin. The polygon is the walls' EXTERIOR face line; each
  wall is a box from its edge inward by ``wall_thickness``, ``storey_height`` high, per storey.
- Windows: per wall and storey ``windows_per_wall`` openings of random width/height/sill (seeded),
  each an IfcOpeningElement box through the wall (0.1 m beyond both faces) filled by an IfcWindow
  box ``frame_depth`` deep, set back ``reveal_depth`` from the exterior face.
- Floor slab per storey and a flat roof slab; surface styles on every element.
Expected ground truth of a window: its opening's rectangle on the exterior face line:
x from ``offset`` to ``offset + width`` along the wall edge, z from ``sill`` to ``sill + height``
above the storey's floor.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

DEFAULT_FOOTPRINT: tuple[tuple[float, float], ...] = (
    (0.0, 0.0), (9.0, 0.0), (11.5, 4.5), (7.0, 9.0), (-1.5, 6.5))  # 4 of 5 walls not axis-aligned


@dataclass(frozen=True)
class HouseSpec:
    """Parameters of a procedural house (metres, degrees)."""

    seed: int = 0
    footprint: tuple[tuple[float, float], ...] = DEFAULT_FOOTPRINT
    storeys: int = 1
    storey_height: float = 3.0
    wall_thickness: float = 0.3
    rotation_deg: float = 0.0
    windows_per_wall: int = 1
    reveal_depth: float = 0.1  # window set back from the exterior face
    frame_depth: float = 0.08
    width_range: tuple[float, float] = (0.5, 2.2)
    height_range: tuple[float, float] = (0.5, 1.8)
    slab_thickness: float = 0.2


@dataclass(frozen=True)
class ExpectedWindow:
    """Ground truth by construction: corners (4, 3) m TL TR BR BL on the exterior face."""

    name: str
    wall_index: int
    storey: int
    width: float
    height: float
    sill: float
    corners_world: np.ndarray
    normal: np.ndarray
    window_id: str = ""


@dataclass(frozen=True)
class GeneratedHouse:
    """What :func:`make_house` wrote: the spec, the file, and each window's expected void."""

    spec: HouseSpec
    path: str
    footprint_world: np.ndarray  # (N, 2) m, counter-clockwise, rotated
    windows: tuple[ExpectedWindow, ...] = field(default_factory=tuple)

    def to_json(self) -> dict:
        return {"path": self.path, "seed": self.spec.seed,
                "footprint": self.footprint_world.tolist(),
                "windows": [{"id": w.window_id, "name": w.name, "wall": w.wall_index,
                             "storey": w.storey, "width": w.width, "height": w.height,
                             "sill": w.sill, "normal": w.normal.tolist(),
                             "corners_world": w.corners_world.tolist()} for w in self.windows]}


# --------------------------------------------------------------------------- pure geometry
def check_footprint(points) -> np.ndarray:
    """Validate a footprint -> (N, 2) float counter-clockwise. ValueError naming the problem."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
        raise ValueError(f"footprint must be >= 3 points (x, y), got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"footprint has non-finite coordinates: {p.tolist()}")
    area2 = np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    if abs(area2) < 1e-9:
        raise ValueError(f"footprint {p.tolist()} has zero area")
    if area2 < 0:
        p = p[::-1].copy()
    e = np.roll(p, -1, axis=0) - p
    cross = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
    if np.any(cross <= 1e-12):
        raise ValueError(f"footprint {p.tolist()} must be convex with no repeated points")
    return p


def rotate_xy(points: np.ndarray, deg: float) -> np.ndarray:
    """Rotate (N, 2) points about the origin by deg (counter-clockwise)."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return points @ np.array([[c, s], [-s, c]])


def corner_margins(poly: np.ndarray, thickness: float) -> np.ndarray:
    """(N, 2) m at the start and end of each wall kept free of windows: the neighbour wall's
    overlap at a convex corner (thickness / tan(angle / 2)) plus 0.3 m."""
    e = np.roll(poly, -1, axis=0) - poly
    u = e / np.linalg.norm(e, axis=1, keepdims=True)
    cosang = np.clip(np.einsum("ij,ij->i", -np.roll(u, 1, axis=0), u), -1, 1)  # at vertex i
    interior = np.arccos(cosang)
    m = thickness / np.tan(interior / 2.0) + 0.3
    return np.stack([m, np.roll(m, -1)], axis=1)


def plan_windows(spec: HouseSpec, poly: np.ndarray) -> list[ExpectedWindow]:
    """Seeded window sizes/positions and their exterior-face corners (pure; no IFC)."""
    rng = np.random.default_rng(spec.seed)
    margins = corner_margins(poly, spec.wall_thickness)
    out: list[ExpectedWindow] = []
    ez = np.array([0.0, 0.0, 1.0])
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        length = float(np.linalg.norm(b - a))
        u = np.append((b - a) / length, 0.0)
        normal = np.array([u[1], -u[0], 0.0])  # right of a CCW edge = outward
        usable = length - margins[i].sum()
        slot = usable / max(spec.windows_per_wall, 1)
        for k in range(spec.storeys):
            z0 = k * spec.storey_height
            for j in range(spec.windows_per_wall):
                w_max = min(spec.width_range[1], slot - 0.3)
                if w_max < spec.width_range[0]:
                    continue  # wall too short for another window
                w = float(np.round(rng.uniform(spec.width_range[0], w_max), 3))
                h_max = min(spec.height_range[1], spec.storey_height - 0.6)
                h = float(np.round(rng.uniform(spec.height_range[0], h_max), 3))
                sill = float(np.round(rng.uniform(0.3, spec.storey_height - 0.3 - h), 3))
                off = margins[i, 0] + j * slot + float(np.round(rng.uniform(0.15, slot - w - 0.15), 3))
                p0 = np.append(a, z0)
                bl = p0 + off * u + sill * ez
                corners = np.stack([bl + h * ez, bl + w * u + h * ez, bl + w * u, bl])
                out.append(ExpectedWindow(name=f"W{i}-{k}-{j}", wall_index=i, storey=k,
                                          width=w, height=h, sill=sill, corners_world=corners,
                                          normal=normal))
    return out


# --------------------------------------------------------------------------- IFC writing
def _placement(origin3: np.ndarray, x_dir3: np.ndarray) -> np.ndarray:
    """4x4 matrix: local x = x_dir (horizontal), local y = z-up x x_dir (inward), z up."""
    m = np.eye(4)
    x = x_dir3 / np.linalg.norm(x_dir3)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross([0.0, 0.0, 1.0], x), [0.0, 0.0, 1.0], origin3
    return m


def make_house(spec: HouseSpec, out_path: str | Path) -> GeneratedHouse:
    """Write the IFC4 house of ``spec`` to out_path; return its expected ground truth."""
    import ifcopenshell
    import ifcopenshell.api

    if spec.storeys < 1 or spec.windows_per_wall < 0:
        raise ValueError(f"storeys must be >= 1 and windows_per_wall >= 0, got "
                         f"{spec.storeys}, {spec.windows_per_wall}")
    if not 0 < spec.wall_thickness < 2 or spec.storey_height < 1.5:
        raise ValueError(f"wall_thickness {spec.wall_thickness} or storey_height "
                         f"{spec.storey_height} out of range")
    if not 0 <= spec.reveal_depth < spec.wall_thickness - spec.frame_depth:
        raise ValueError(f"reveal_depth {spec.reveal_depth} must leave room for the frame")
    poly = rotate_xy(check_footprint(spec.footprint), spec.rotation_deg)
    plan = plan_windows(spec, poly)
    api = ifcopenshell.api.run
    f = ifcopenshell.file(schema="IFC4")
    project = api("root.create_entity", f, ifc_class="IfcProject", name="Fenestra procedural house")
    api("unit.assign_unit", f, length={"is_metric": True, "raw": "METERS"})
    model_ctx = api("context.add_context", f, context_type="Model")
    body = api("context.add_context", f, context_type="Model", context_identifier="Body",
               target_view="MODEL_VIEW", parent=model_ctx)
    site = api("root.create_entity", f, ifc_class="IfcSite", name="Site")
    building = api("root.create_entity", f, ifc_class="IfcBuilding", name="House")
    api("aggregate.assign_object", f, products=[site], relating_object=project)
    api("aggregate.assign_object", f, products=[building], relating_object=site)

    def style(name, rgb, transparency=0.0):
        st = api("style.add_style", f, name=name)
        api("style.add_surface_style", f, style=st, ifc_class="IfcSurfaceStyleShading", attributes={
            "SurfaceColour": {"Name": None, "Red": rgb[0], "Green": rgb[1], "Blue": rgb[2]},
            "Transparency": transparency})
        return st

    styles = {"wall": style("wall", (0.86, 0.80, 0.70)), "slab": style("slab", (0.6, 0.6, 0.6)),
              "window": style("glass", (0.3, 0.5, 0.7), 0.6)}

    def element(ifc_class, name, storey_ent, matrix, rep, style_key=None):
        el = api("root.create_entity", f, ifc_class=ifc_class, name=name)
        api("geometry.edit_object_placement", f, product=el, matrix=matrix)
        api("geometry.assign_representation", f, product=el, representation=rep)
        if style_key:
            api("style.assign_representation_styles", f, shape_representation=rep,
                styles=[styles[style_key]])
        if storey_ent is not None:
            api("spatial.assign_container", f, products=[el], relating_structure=storey_ent)
        return el

    t, H = spec.wall_thickness, spec.storey_height
    windows_out: list[ExpectedWindow] = []
    by_wall = {(w.wall_index, w.storey): [] for w in plan}
    for w in plan:
        by_wall[(w.wall_index, w.storey)].append(w)
    for k in range(spec.storeys):
        z0 = k * H
        storey = api("root.create_entity", f, ifc_class="IfcBuildingStorey", name=f"Storey {k}")
        storey.Elevation = z0
        api("aggregate.assign_object", f, products=[storey], relating_object=building)
        slab_rep = api("geometry.add_slab_representation", f, context=body,
                       depth=spec.slab_thickness, polyline=[tuple(p) for p in poly])
        element("IfcSlab", f"Floor {k}", storey,
                _placement(np.array([0, 0, z0 - spec.slab_thickness]), np.array([1.0, 0, 0])),
                slab_rep, "slab")
        for i in range(len(poly)):
            a, b = poly[i], poly[(i + 1) % len(poly)]
            length = float(np.linalg.norm(b - a))
            u = np.append((b - a) / length, 0.0)
            origin = np.append(a, z0)
            rep = api("geometry.add_wall_representation", f, context=body, length=length,
                      height=H, thickness=t)
            wall = element("IfcWall", f"Wall {i}-{k}", storey, _placement(origin, u), rep, "wall")
            for w in by_wall.get((i, k), []):
                bl = w.corners_world[3]
                off = float((bl - origin) @ u)
                o_rep = api("geometry.add_wall_representation", f, context=body, length=w.width,
                            height=w.height, thickness=t + 0.2)
                opening = element("IfcOpeningElement", f"Opening {w.name}", None,
                                  _placement(origin + off * u + np.array([0, 0, w.sill])
                                             + 0.1 * np.append(-np.cross([0, 0, 1.0], u)[:2], 0), u),
                                  o_rep)
                api("feature.add_feature", f, feature=opening, element=wall)
                w_rep = api("geometry.add_wall_representation", f, context=body, length=w.width,
                            height=w.height, thickness=spec.frame_depth)
                inward = np.cross([0.0, 0.0, 1.0], u)
                win = element("IfcWindow", w.name, storey,
                              _placement(origin + off * u + np.array([0, 0, w.sill])
                                         + spec.reveal_depth * inward, u), w_rep, "window")
                win.OverallWidth, win.OverallHeight = w.width, w.height
                api("feature.add_filling", f, opening=opening, element=win)
                windows_out.append(ExpectedWindow(**{**w.__dict__, "window_id": win.GlobalId}))
    roof_rep = api("geometry.add_slab_representation", f, context=body,
                   depth=spec.slab_thickness, polyline=[tuple(p) for p in poly])
    element("IfcSlab", "Roof", storey, _placement(np.array([0, 0, spec.storeys * H]),
                                                  np.array([1.0, 0, 0])), roof_rep, "slab")
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    f.write(str(out_path))
    return GeneratedHouse(spec=spec, path=str(out_path), footprint_world=poly,
                          windows=tuple(windows_out))
