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
- Optional (all off by default; off, the file holds exactly today's elements and windows):
  ``roof_overhang`` m: the roof slab is the footprint offset outward by that distance (each edge
  moved along its outward normal). ``fascia_height`` m: one IfcMember box per roof edge, 0.04 m
  thick, just outside the roof's outer edge, from the roof's top down by ``fascia_height`` (below
  the slab when taller than it), in a seeded dark colour. ``glazed_doors``: that many storey-0
  walls get an IfcDoor (glass style) in place of their first window (j = 0): same offset and
  width (clipped to 0.8-2.0 m inside the slot), from the floor to a seeded 2.0-2.4 m.
  ``curtain_walls``: that many walls (seeded, longer ones likelier) get no windows; instead, per
  storey, an unfilled opening (0.1 m above the floor to 0.1 m below the top, corner margin + 0.2 m
  from both ends) glazed by IfcPlate panels (0.02 m, glass style, flush with the exterior face;
  ``curtain_wall_rows`` rows, default 2, seeded panel width 1.0-1.8 m) and IfcMember
  mullions/transoms (0.06 x 0.12 m, protruding 0.03 m, seeded grey) aggregated into an
  IfcCurtainWall. ``curtain_wall_width`` > 0 m makes it a strip of that width (clipped to the free
  length) instead, at the wall's start, its end or a place between (seeded, stream ``[seed, 8]``);
  only the windows overlapping it (0.3 m clearance) are dropped. Doors and curtain walls are NOT
  windows: the loader's ground truth (IfcWindow fillings only) leaves them out, so they are negatives.
  The other random choices of these options use ``default_rng([seed, 7])``, never the window stream.
  Ornament (:func:`plan_ornament`, stream ``[seed, 12]``): ``sill_depth`` > 0 m: an IfcMember box
  under each window (0.05 m wider each side, 0.04-0.08 m high, top at the void's bottom)
  protruding that far; ``surround_width`` > 0 m: an architrave of 4 IfcMember boxes just outside
  the void's edges (0.03 m proud; the top one taller and deeper, a hood); ``shutters``: two
  panels (each ~half the window wide, its height, 0.03 m) left and right of the window or its
  architrave. No part overlaps any void in the facade plane (0.05 m clear of other openings) or
  another window's ornament, or leaves the wall's free length (corner margins); a part that does
  not fit is narrowed, else left out. Ornament is written after everything else, so windows,
  GlobalIds and every other element are those of the same spec without it.
Expected ground truth of a window: its opening's rectangle on the exterior face line:
x from ``offset`` to ``offset + width`` along the wall edge, z from ``sill`` to ``sill + height``
above the storey's floor. Doors and curtain-wall voids are recorded the same way
(:class:`ExpectedOpening`, sill = height of the void's bottom above the storey floor).
"""
from __future__ import annotations

import contextlib
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from fenestra.conventions import LIMITS
from fenestra.files import write_ifc_file

FASCIA_THICKNESS = 0.04  # m
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
    roof_overhang: float = 0.0  # roof slab = footprint offset outward by this, 0-2 m
    fascia_height: float = 0.0  # dark band around the roof edge, from its top down, 0-1 m
    glazed_doors: int = 0  # storey-0 walls whose first window becomes a glazed IfcDoor
    curtain_walls: int = 0  # walls glazed by an IfcPlate/IfcMember grid instead of windows
    curtain_wall_width: float = 0.0  # m; 0: the wall's whole free length, else a strip this wide
    curtain_wall_rows: int = 2  # panel rows of a curtain wall, 1-4
    sill_depth: float = 0.0  # m; > 0: a stone sill under each window protruding this far, 0-0.5
    surround_width: float = 0.0  # m; > 0: an architrave of this width around each window, 0-0.3
    shutters: bool = False  # a pair of shutter panels beside each window
    window_styles: tuple[str, ...] = ()  # () : every IfcWindow one solid box; else each window draws
    # one of these WINDOW_STYLES (stream [seed, 13]): a frame ring, mullions and transoms round glass panes


@dataclass(frozen=True)
class ExpectedOpening:
    """Ground truth by construction of a window, glazed door or curtain-wall void: corners (4, 3) m
    TL TR BR BL on the exterior face; sill = the void's bottom above the storey floor."""

    name: str
    wall_index: int
    storey: int
    width: float
    height: float
    sill: float
    corners_world: np.ndarray
    normal: np.ndarray
    element_id: str = ""  # GlobalId: IfcWindow (windows), IfcDoor (doors), IfcOpeningElement (curtain walls)

    @property
    def window_id(self) -> str:
        """The IfcWindow GlobalId (windows): the id the loader's ground truth uses."""
        return self.element_id

    def to_json(self) -> dict:
        return {"id": self.element_id, "name": self.name, "wall": self.wall_index,
                "storey": self.storey, "width": self.width, "height": self.height,
                "sill": self.sill, "normal": self.normal.tolist(),
                "corners_world": self.corners_world.tolist()}


ExpectedWindow = ExpectedOpening  # a window is an opening filled by an IfcWindow


@dataclass(frozen=True)
class GeneratedHouse:
    """What :func:`make_house` wrote: the spec, the file, and each window's expected void."""

    spec: HouseSpec
    path: str
    footprint_world: np.ndarray  # (N, 2) m, counter-clockwise, rotated
    windows: tuple[ExpectedWindow, ...] = field(default_factory=tuple)
    doors: tuple[ExpectedOpening, ...] = field(default_factory=tuple)
    curtain_walls: tuple[ExpectedOpening, ...] = field(default_factory=tuple)  # one per storey

    def to_json(self) -> dict:
        return {"path": self.path, "seed": self.spec.seed,
                "footprint": self.footprint_world.tolist(),
                "windows": [w.to_json() for w in self.windows],
                "doors": [d.to_json() for d in self.doors],
                "curtain_walls": [c.to_json() for c in self.curtain_walls]}


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


def offset_polygon(poly: np.ndarray, d: float) -> np.ndarray:
    """Convex CCW polygon (N, 2) m with every edge moved outward (along its outward normal, the
    right of a CCW edge) by d m -> (N, 2): vertex i = intersection of offset edges i-1 and i."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([e[:, 1], -e[:, 0]], axis=1) / np.linalg.norm(e, axis=1, keepdims=True)
    c = np.einsum("ij,ij->i", n, poly) + d  # offset line i: n_i . p = c_i
    A = np.stack([np.roll(n, 1, axis=0), n], axis=1)  # (N, 2, 2): rows n_{i-1}, n_i
    b = np.stack([np.roll(c, 1), c], axis=1)[..., None]
    return np.linalg.solve(A, b)[..., 0]


def face_rect(a: np.ndarray, u: np.ndarray, z0: float, off: float, sill: float, w: float,
              h: float) -> np.ndarray:
    """Corners (4, 3) m TL TR BR BL of a rectangle on the exterior face line of a wall starting at
    a (2,) with unit direction u (3,): x from off to off + w along u, z from z0 + sill up by h."""
    ez = np.array([0.0, 0.0, 1.0])
    bl = np.append(a, z0) + off * u + sill * ez
    return np.stack([bl + h * ez, bl + w * u + h * ez, bl + w * u, bl])


def check_counts(spec: HouseSpec, n_walls: int) -> None:
    """ValueError naming the field, its value and the bound when the house would be larger than
    fenestra.conventions.LIMITS allows (storeys, windows per wall and storey, windows in all)."""
    LIMITS.check("max_storeys", spec.storeys, "storeys")
    LIMITS.check("max_windows_per_wall", spec.windows_per_wall, "windows_per_wall")
    LIMITS.check("max_house_windows", n_walls * spec.storeys * spec.windows_per_wall,
                 f"walls x storeys x windows_per_wall ({n_walls} x {spec.storeys} x {spec.windows_per_wall})")


def check_options(spec: HouseSpec, n_walls: int) -> None:
    """ValueError naming the field and value for an out-of-range optional part."""
    bad = [w for w in spec.window_styles if w not in WINDOW_STYLES]
    if bad:
        raise ValueError(f"window_styles {bad} unknown; choose from {WINDOW_STYLES}")
    if not 0.0 <= spec.roof_overhang <= 2.0:
        raise ValueError(f"roof_overhang must be in [0, 2] m, got {spec.roof_overhang}")
    if not 0.0 <= spec.fascia_height <= 1.0:
        raise ValueError(f"fascia_height must be in [0, 1] m, got {spec.fascia_height}")
    if spec.glazed_doors < 0:
        raise ValueError(f"glazed_doors must be >= 0, got {spec.glazed_doors}")
    if spec.glazed_doors and spec.storey_height < 2.3:
        raise ValueError(f"glazed_doors={spec.glazed_doors} needs storey_height >= 2.3 m, got "
                         f"{spec.storey_height}")
    if not 0 <= spec.curtain_walls <= n_walls:
        raise ValueError(f"curtain_walls must be in [0, {n_walls}] (the number of walls), got "
                         f"{spec.curtain_walls}")
    if spec.curtain_wall_width != 0.0 and not 0.5 <= spec.curtain_wall_width <= 50.0:
        raise ValueError(f"curtain_wall_width must be 0 (whole wall) or in [0.5, 50] m, got "
                         f"{spec.curtain_wall_width}")
    if not 1 <= spec.curtain_wall_rows <= 4:
        raise ValueError(f"curtain_wall_rows must be in [1, 4], got {spec.curtain_wall_rows}")
    if not 0.0 <= spec.sill_depth <= 0.5:
        raise ValueError(f"sill_depth must be in [0, 0.5] m, got {spec.sill_depth}")
    if not 0.0 <= spec.surround_width <= 0.3:
        raise ValueError(f"surround_width must be in [0, 0.3] m, got {spec.surround_width}")


def choose_curtain_walls(spec: HouseSpec, poly: np.ndarray, rng: np.random.Generator
                         ) -> list[int]:
    """Indices of the ``spec.curtain_walls`` walls glazed as curtain walls: a seeded choice
    weighted by wall length among walls leaving >= 1 m between the corner margins + 0.2 m."""
    if spec.curtain_walls == 0:
        return []
    lengths = np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1)
    free = lengths - corner_margins(poly, spec.wall_thickness).sum(axis=1) - 0.4
    ok = np.flatnonzero(free >= 1.0)
    if spec.curtain_walls > len(ok):
        raise ValueError(f"curtain_walls={spec.curtain_walls} but only {len(ok)} walls are long "
                         "enough (>= 1 m between the corner margins)")
    p = lengths[ok] / lengths[ok].sum()
    return sorted(int(i) for i in rng.choice(ok, size=spec.curtain_walls, replace=False, p=p))


def plan_doors(spec: HouseSpec, poly: np.ndarray, plan: list[ExpectedWindow], skip: list[int],
               rng: np.random.Generator) -> list[tuple[ExpectedOpening, str]]:
    """Glazed doors, each with the name of the window it replaces (its wall's W{i}-0-0).

    Candidates: walls not in ``skip`` with a storey-0 window in slot j = 0 whose slot fits 0.8 m
    + 0.3 m. The door keeps the window's offset and width (width clipped to [0.8, 2.0] m, the
    offset moved left if needed to stay 0.15 m inside the slot); sill 0, seeded height (m)."""
    if spec.glazed_doors == 0:
        return []
    margins = corner_margins(poly, spec.wall_thickness)
    first = {w.wall_index: w for w in plan if w.name == f"W{w.wall_index}-0-0"}
    cand = []
    for i, w in sorted(first.items()):
        length = float(np.linalg.norm(poly[(i + 1) % len(poly)] - poly[i]))
        slot = (length - margins[i].sum()) / max(spec.windows_per_wall, 1)
        if i not in skip and slot - 0.3 >= 0.8:
            cand.append((i, slot))
    if spec.glazed_doors > len(cand):
        raise ValueError(f"glazed_doors={spec.glazed_doors} but only {len(cand)} walls have a "
                         "ground-floor window slot wide enough for a door")
    picks = sorted(rng.choice(len(cand), size=spec.glazed_doors, replace=False))
    out = []
    for c in picks:
        i, slot = cand[c]
        w, a, b = first[i], poly[i], poly[(i + 1) % len(poly)]
        u = np.append((b - a) / np.linalg.norm(b - a), 0.0)
        width = float(np.clip(w.width, 0.8, min(2.0, slot - 0.3)))
        off = min(float((w.corners_world[3][:2] - a) @ u[:2]), margins[i, 0] + slot - 0.15 - width)
        h = float(np.round(rng.uniform(2.0, min(2.4, spec.storey_height - 0.3)), 3))
        corners = face_rect(a, u, 0.0, off, 0.0, width, h)
        out.append((ExpectedOpening(name=f"D{i}", wall_index=i, storey=0, width=width, height=h,
                                    sill=0.0, corners_world=corners, normal=w.normal), w.name))
    return out


def plan_curtain_walls(spec: HouseSpec, poly: np.ndarray, walls: list[int]
                       ) -> list[ExpectedOpening]:
    """The curtain-wall void of each wall in ``walls`` on every storey: from corner margin + 0.2 m
    to length - margin - 0.2 m along the wall, 0.1 m above the floor to 0.1 m below the top.

    With ``spec.curtain_wall_width`` > 0 the void is a strip that wide (clipped to that free
    length) at the free length's start, its end or a uniform place between (seeded per wall with
    ``default_rng([seed, 8])``, a stream of its own: houses without strips are unchanged)."""
    margins = corner_margins(poly, spec.wall_thickness)
    rng = np.random.default_rng([spec.seed, 8])
    out = []
    for i in walls:
        a, b = poly[i], poly[(i + 1) % len(poly)]
        length = float(np.linalg.norm(b - a))
        u = np.append((b - a) / length, 0.0)
        off, width = margins[i, 0] + 0.2, length - margins[i].sum() - 0.4
        if spec.curtain_wall_width > 0:
            strip = min(spec.curtain_wall_width, width)
            place = int(rng.integers(3))  # 0 start, 1 end, 2 uniform between
            off += (0.0, width - strip, float(rng.uniform(0.0, width - strip)))[place]
            width = strip
        h = spec.storey_height - 0.2
        for k in range(spec.storeys):
            out.append(ExpectedOpening(
                name=f"CW{i}-{k}", wall_index=i, storey=k, width=width, height=h, sill=0.1,
                corners_world=face_rect(a, u, k * spec.storey_height, off, 0.1, width, h),
                normal=np.array([u[1], -u[0], 0.0])))
    return out


def _overlaps(a: ExpectedOpening, b: ExpectedOpening, clearance: float) -> bool:
    """Do two openings on the same wall overlap along it, with ``clearance`` m added (corners)?"""
    u = a.corners_world[1] - a.corners_world[0]
    u = u / np.linalg.norm(u)
    xa = sorted(float(p @ u) for p in a.corners_world[:2])
    xb = sorted(float(p @ u) for p in b.corners_world[:2])
    return xa[0] < xb[1] + clearance and xb[0] < xa[1] + clearance


Rect = tuple[float, float, float, float]  # (x, z, w, h) m


def curtain_grid(width: float, height: float, panel_width: float, rows: int = 2
                 ) -> tuple[list[Rect], list[Rect]]:
    """Panels and members of a curtain-wall void width x height m, in void coordinates (x along
    the wall, z up from the void's bottom), each (x, z, w, h) m.

    Panels: round(width / panel_width) (>= 1) equal columns x ``rows`` equal rows, tiling the void.
    Members (0.06 m wide): a vertical one at every column line, a horizontal one at every row line
    (bottom and top included), all inside the void (edge members flush with its sides)."""
    m = 0.06
    nc = max(1, int(round(width / panel_width)))
    cw, rh = width / nc, height / rows
    panels = [(j * cw, r * rh, cw, rh) for r in range(rows) for j in range(nc)]
    xs = np.clip(np.arange(nc + 1) * cw - m / 2, 0.0, width - m)
    zs = np.clip(np.arange(rows + 1) * rh - m / 2, 0.0, height - m)
    members = [(float(x), 0.0, m, height) for x in xs] + [(0.0, float(z), width, m) for z in zs]
    return panels, members


# --------------------------------------------------------------------------- window styles
WINDOW_STYLES = ("box", "frame", "mullion", "transom", "grid")
PANE_THICKNESS = 0.012  # m: a glass pane, thin enough for the renderers' glass_faces (< 0.04 m)
Box3 = tuple[float, float, float, float, float, float]  # x0, y0, z0, x1, y1, z1 (m, window-local)


def _bars(lo: float, hi: float, n: int, bar: float) -> tuple[list[float], list[tuple[float, float]]]:
    """n bars of width ``bar`` evenly spaced inside [lo, hi]: (bar starts, free spans between)."""
    step = (hi - lo - n * bar) / (n + 1)
    starts = [lo + step * (k + 1) + bar * k for k in range(n)]
    edges = [lo] + [e for x in starts for e in (x, x + bar)] + [hi]
    return starts, [(edges[2 * k], edges[2 * k + 1]) for k in range(n + 1)]


def window_parts(width: float, height: float, depth: float, style: str, rng: np.random.Generator
                 ) -> tuple[list[Box3], list[Box3]]:
    """The boxes of one IfcWindow of ``style`` in its local frame (x along the wall from the void's
    left edge, y inward from the window's outer face, z up from the sill): (frame and bars, panes).

    "box" is one solid box (no pane). The others: a frame ring of seeded bar width (0.04-0.09 m,
    at most 15 % of the shorter side) and glass panes (PANE_THICKNESS, mid-depth) filling what the
    bars leave; "mullion" adds a vertical bar, "transom" a horizontal bar at 65-78 % of the height
    (a top light, with a mullion below on wide windows), "grid" 1-2 of each. Bars stay inside the
    void, so the window's ground truth (its opening) is unchanged.
    """
    if style not in WINDOW_STYLES:
        raise ValueError(f"window style must be one of {WINDOW_STYLES}, got {style!r}")
    if style == "box":
        return [(0.0, 0.0, 0.0, width, depth, height)], []
    f = min(float(rng.uniform(0.04, 0.09)), 0.15 * min(width, height))
    bar, bd = 0.8 * f, 0.8 * depth
    frame = [(0.0, 0.0, 0.0, width, depth, f), (0.0, 0.0, height - f, width, depth, height),
             (0.0, 0.0, f, f, depth, height - f), (width - f, 0.0, f, width, depth, height - f)]
    y0 = (depth - bd) / 2
    n_mull = {"frame": 0, "mullion": 1, "transom": 0, "grid": int(rng.integers(1, 3))}[style]
    n_trans = {"frame": 0, "mullion": 0, "transom": 0, "grid": int(rng.integers(1, 3))}[style]
    n_mull = n_mull if width >= 0.6 else 0
    rows = [(f, height - f)]
    bars: list[Box3] = []
    if style == "transom" and height >= 0.9:
        zt = height * float(rng.uniform(0.65, 0.78))
        bars.append((f, y0, zt, width - f, y0 + bd, zt + bar))
        rows = [(f, zt), (zt + bar, height - f)]
        n_mull = 1 if width >= 0.9 else 0
        mull_rows = rows[:1]
    elif n_trans and height >= 0.9:
        starts, rows = _bars(f, height - f, n_trans, bar)
        bars += [(f, y0, z, width - f, y0 + bd, z + bar) for z in starts]
        mull_rows = rows
    else:
        mull_rows = rows
    xs, cols = _bars(f, width - f, n_mull, bar) if n_mull else ([], [(f, width - f)])
    for z0, z1 in mull_rows:
        bars += [(x, y0, z0, x + bar, y0 + bd, z1) for x in xs]
    py = depth / 2 - PANE_THICKNESS / 2
    panes = []
    for z0, z1 in rows:
        spans = cols if (z0, z1) in mull_rows else [(f, width - f)]
        panes += [(x0, py, z0, x1, py + PANE_THICKNESS, z1) for x0, x1 in spans]
    return frame + bars, panes


def box_mesh(boxes: list[Box3]) -> tuple[list[list[tuple[float, float, float]]], list[list[tuple[int, ...]]]]:
    """Closed axis-aligned boxes as mesh items (add_mesh_representation's vertices, faces): one
    item per box, 8 vertices and 6 outward-wound quads each."""
    verts, faces = [], []
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (0, 4, 7, 3)]
    for x0, y0, z0, x1, y1, z1 in boxes:
        verts.append([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                      (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)])
        faces.append(quads)
    return verts, faces


# --------------------------------------------------------------------------- ornament
SHUTTER_COLOURS = ((0.18, 0.33, 0.20), (0.36, 0.22, 0.12), (0.16, 0.24, 0.40), (0.50, 0.12, 0.10),
                   (0.85, 0.84, 0.80), (0.30, 0.30, 0.30))  # green, brown, blue, red, white, grey


@dataclass(frozen=True)
class OrnamentPart:
    """A box on a wall's exterior face: x from the wall's start along it, z above the storey
    floor, w x h m in the facade plane, protruding m out of the face; style is its colour key."""

    name: str
    wall_index: int
    storey: int
    x: float
    z: float
    w: float
    h: float
    protrusion: float
    style: str


def _hits(r: Rect, o: Rect, clearance: float) -> bool:
    """Do rectangles (x, z, w, h) overlap with positive area once o is grown by clearance m?"""
    eps = 1e-9
    return (r[0] < o[0] + o[2] + clearance - eps and o[0] - clearance < r[0] + r[2] - eps
            and r[1] < o[1] + o[3] + clearance - eps and o[1] - clearance < r[1] + r[3] - eps)


def _void_rect(o: ExpectedOpening, a: np.ndarray, u: np.ndarray) -> Rect:
    """An opening's void on its wall as (x along the wall from a, z world, w, h) m."""
    bl = o.corners_world[3]
    return (float((bl[:2] - a) @ u[:2]), float(bl[2]), o.width, o.height)


def plan_ornament(spec: HouseSpec, poly: np.ndarray, windows: list[ExpectedOpening],
                  openings: list[ExpectedOpening]) -> tuple[list[OrnamentPart], dict]:
    """Sills, architraves and shutters of ``windows`` (see the module doc) -> (parts, colours).

    ``openings``: every void of the house (windows, doors, curtain walls), which no part may
    overlap in the facade plane. Sizes and colours come from ``default_rng([seed, 12])``, drawn
    in a fixed order whatever fits; with all ornament off: ([], {})."""
    if spec.sill_depth == 0 and spec.surround_width == 0 and not spec.shutters:
        return [], {}
    rng = np.random.default_rng([spec.seed, 12])
    light = rng.uniform(0.0, 1.0) < 0.6  # a light architrave on a darker wall, or dark
    colours = {"sill": tuple(rng.uniform(0.55, 0.8) * np.array([1.0, 0.97, 0.92])),
               "surround": tuple(rng.uniform(0.85, 0.98, 3) if light else rng.uniform(0.2, 0.45, 3)),
               "shutter": tuple(np.clip(np.array(SHUTTER_COLOURS[int(rng.integers(
                   len(SHUTTER_COLOURS)))]) * rng.uniform(0.85, 1.15), 0.0, 1.0))}
    sill_h, hood_f, hood_p = rng.uniform(0.04, 0.08), rng.uniform(1.0, 2.0), rng.uniform(0.03, 0.08)
    shutter_f = rng.uniform(0.42, 0.55)
    margins = corner_margins(poly, spec.wall_thickness)
    top = spec.storeys * spec.storey_height
    geo = {}
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        length = float(np.linalg.norm(b - a))
        geo[i] = (a, np.append((b - a) / length, 0.0), margins[i, 0], length - margins[i, 1])
    voids = {i: [(o.name, _void_rect(o, geo[i][0], geo[i][1])) for o in openings if o.wall_index == i]
             for i in geo}
    placed: dict[int, list[tuple[str, Rect]]] = {i: [] for i in geo}

    def fits(win: ExpectedOpening, rects: list[Rect]) -> bool:
        i = win.wall_index
        x_lo, x_hi = geo[i][2], geo[i][3]
        for r in rects:
            if r[0] < x_lo - 1e-9 or r[0] + r[2] > x_hi + 1e-9 or r[1] < 0 or r[1] + r[3] > top:
                return False
            if any(_hits(r, v, 0.0 if n == win.name else 0.05) for n, v in voids[i]):
                return False
            if any(_hits(r, p, 0.0) for n, p in placed[i] if n != win.name):
                return False
        return True

    parts: list[OrnamentPart] = []
    used_sw: dict[str, float] = {}

    def accept(win, rects, protrusions, styles, label):
        z0 = win.storey * spec.storey_height
        for n, (r, p, st) in enumerate(zip(rects, protrusions, styles)):
            placed[win.wall_index].append((win.name, r))
            parts.append(OrnamentPart(f"{win.name} {label} {n}", win.wall_index, win.storey,
                                      r[0], r[1] - z0, r[2], r[3], p, st))

    for win in windows:  # sills and architraves first, shutters after, so they yield
        x, z, w, h = _void_rect(win, geo[win.wall_index][0], geo[win.wall_index][1])
        if spec.sill_depth > 0:
            for extra in (0.05, 0.0):
                rects = [(x - extra, z - sill_h, w + 2 * extra, sill_h)]
                if fits(win, rects):
                    accept(win, rects, [spec.sill_depth], ["sill"], "sill")
                    break
        if spec.surround_width > 0:
            for sw in (spec.surround_width, spec.surround_width / 2):
                rects = [(x - sw, z + h, w + 2 * sw, sw * hood_f), (x - sw, z - sw, w + 2 * sw, sw),
                         (x - sw, z, sw, h), (x + w, z, sw, h)]
                if fits(win, rects):
                    accept(win, rects, [hood_p, 0.03, 0.03, 0.03], ["surround"] * 4, "surround")
                    used_sw[win.name] = sw
                    break
    if spec.shutters:
        for win in windows:
            x, z, w, h = _void_rect(win, geo[win.wall_index][0], geo[win.wall_index][1])
            sw = used_sw.get(win.name, 0.0)
            for scale in (1.0, 0.7, 0.5):
                sh = shutter_f * w * scale
                rects = [(x - sw - sh, z, sh, h), (x + w + sw, z, sh, h)]
                if sh >= 0.15 and fits(win, rects):
                    accept(win, rects, [0.03, 0.03], ["shutter"] * 2, "shutter")
                    break
    return parts, colours


# --------------------------------------------------------------------------- IFC writing
def _placement(origin3: np.ndarray, x_dir3: np.ndarray) -> np.ndarray:
    """4x4 matrix: local x = x_dir (horizontal), local y = z-up x x_dir (inward), z up."""
    m = np.eye(4)
    x = x_dir3 / np.linalg.norm(x_dir3)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross([0.0, 0.0, 1.0], x), [0.0, 0.0, 1.0], origin3
    return m


IFC_TIMESTAMP = "2000-01-01T00:00:00"  # the header's time stamp: not the time of generation


@contextlib.contextmanager
def _seeded_guids(seed: int) -> Iterator[None]:
    """Within the block, ifcopenshell.guid.new draws GlobalIds from a generator seeded by ``seed``,
    so a spec always gives the same window ids (results tables comparable across clones)."""

    import ifcopenshell.guid  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    rng = np.random.default_rng([seed, 11])
    original = ifcopenshell.guid.new
    ifcopenshell.guid.new = lambda: ifcopenshell.guid.compress(uuid.UUID(bytes=rng.bytes(16), version=4).hex)
    try:
        yield
    finally:
        ifcopenshell.guid.new = original


def make_house(spec: HouseSpec, out_path: str | Path, schema: str = "IFC4") -> GeneratedHouse:
    """Write the IFC4 house of ``spec`` to out_path (another schema ifcopenshell writes:
    ``schema``, e.g. "IFC4X3" or "IFC2X3"); return its expected ground truth.

    The same spec gives the same entities, geometry and GlobalIds (seeded) and header; only the
    order of references inside unordered IFC SETs may differ between processes (ifcopenshell
    keeps them in Python sets), so two files of one spec can differ in bytes, not in content.
    """
    with _seeded_guids(spec.seed):
        return _make_house(spec, out_path, schema)


def _make_house(spec: HouseSpec, out_path: str | Path, schema: str = "IFC4") -> GeneratedHouse:
    import ifcopenshell  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)
    import ifcopenshell.api  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    if spec.storeys < 1 or spec.windows_per_wall < 0:
        raise ValueError(f"storeys must be >= 1 and windows_per_wall >= 0, got "
                         f"{spec.storeys}, {spec.windows_per_wall}")
    if not 0 < spec.wall_thickness < 2 or spec.storey_height < 1.5:
        raise ValueError(f"wall_thickness {spec.wall_thickness} or storey_height "
                         f"{spec.storey_height} out of range")
    if not 0 <= spec.reveal_depth < spec.wall_thickness - spec.frame_depth:
        raise ValueError(f"reveal_depth {spec.reveal_depth} must leave room for the frame")
    poly = rotate_xy(check_footprint(spec.footprint), spec.rotation_deg)
    check_counts(spec, len(poly))
    check_options(spec, len(poly))
    plan = plan_windows(spec, poly)
    rng = np.random.default_rng([spec.seed, 7])  # optional parts only: plan's stream is untouched
    style_rng = np.random.default_rng([spec.seed, 13])  # window styles only
    cw_walls = choose_curtain_walls(spec, poly, rng)
    panel_w = {i: float(rng.uniform(1.0, 1.8)) for i in cw_walls}
    grey = float(rng.uniform(0.08, 0.45)) if cw_walls else 0.0
    door_plan = plan_doors(spec, poly, plan, cw_walls, rng)
    fascia_rgb = rng.uniform(0.05, 0.35, 3).tolist() if spec.fascia_height > 0 else None
    replaced = {name for _, name in door_plan}
    doors_at = {d.wall_index: d for d, _ in door_plan}  # all on storey 0
    curtains = plan_curtain_walls(spec, poly, cw_walls)
    plan = [w for w in plan if w.name not in replaced
            and not any(_overlaps(w, c, 0.3) for c in curtains if c.wall_index == w.wall_index)]
    curtain_at = {(c.wall_index, c.storey): c for c in curtains}

    api = ifcopenshell.api.run
    f = ifcopenshell.file(schema=schema)
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
    if cw_walls:
        styles["mullion"] = style("mullion", (grey, grey, grey))
    if fascia_rgb is not None:
        styles["fascia"] = style("fascia", fascia_rgb)

    def element(ifc_class, name, storey_ent, matrix, rep, style_key=None):
        el = api("root.create_entity", f, ifc_class=ifc_class, name=name)
        api("geometry.edit_object_placement", f, product=el, matrix=matrix)
        if rep is not None:
            api("geometry.assign_representation", f, product=el, representation=rep)
        if style_key:
            api("style.assign_representation_styles", f, shape_representation=rep,
                styles=[styles[style_key]])
        if storey_ent is not None:
            api("spatial.assign_container", f, products=[el], relating_structure=storey_ent)
        return el

    t, H = spec.wall_thickness, spec.storey_height

    def box(ifc_class, name, storey_ent, origin, u, off, z, w, h, depth, setback, style_key, rep=None):
        """Box w x h x depth m (x along u, z up, y inward) at off (m) along u from origin (3,),
        z m up, its outer face setback m inward; styled and contained in storey_ent. rep: another
        representation in the same local frame instead of the box (a styled window's parts)."""
        if rep is None:
            rep = api("geometry.add_wall_representation", f, context=body, length=w, height=h,
                      thickness=depth)
        inward = np.cross([0.0, 0.0, 1.0], u)
        return element(ifc_class, name, storey_ent,
                       _placement(origin + off * u + np.array([0, 0, z]) + setback * inward, u),
                       rep, style_key)

    def void(wall, name, origin, u, off, sill, w, h):
        """IfcOpeningElement w x h m through ``wall`` (0.1 m beyond both faces), x from off."""
        opening = box("IfcOpeningElement", name, None, origin, u, off, sill, w, h, t + 0.2, -0.1,
                      None)
        api("feature.add_feature", f, feature=opening, element=wall)
        return opening

    windows_out: list[ExpectedWindow] = []
    doors_out: list[ExpectedOpening] = []
    curtains_out: list[ExpectedOpening] = []
    by_wall = {(w.wall_index, w.storey): [] for w in plan}
    for w in plan:
        by_wall[(w.wall_index, w.storey)].append(w)
    storeys = []
    for k in range(spec.storeys):
        z0 = k * H
        storey = api("root.create_entity", f, ifc_class="IfcBuildingStorey", name=f"Storey {k}")
        storeys.append(storey)
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
                off = float((w.corners_world[3] - origin) @ u)
                opening = void(wall, f"Opening {w.name}", origin, u, off, w.sill, w.width, w.height)
                parts_rep = None
                if spec.window_styles:
                    style_w = spec.window_styles[int(style_rng.integers(len(spec.window_styles)))]
                    solid, panes = window_parts(w.width, w.height, spec.frame_depth, style_w, style_rng)
                    verts, faces = box_mesh(solid + panes)
                    parts_rep = api("geometry.add_mesh_representation", f, context=body,
                                    vertices=verts, faces=faces)
                win = box("IfcWindow", w.name, storey, origin, u, off, w.sill, w.width, w.height,
                          spec.frame_depth, spec.reveal_depth, "window", rep=parts_rep)
                win.OverallWidth, win.OverallHeight = w.width, w.height
                api("feature.add_filling", f, opening=opening, element=win)
                windows_out.append(ExpectedWindow(**{**w.__dict__, "element_id": win.GlobalId}))
            d = doors_at.get(i) if k == 0 else None
            if d is not None:
                off = float((d.corners_world[3] - origin) @ u)
                opening = void(wall, f"Opening {d.name}", origin, u, off, 0.0, d.width, d.height)
                door = box("IfcDoor", d.name, storey, origin, u, off, 0.0, d.width, d.height,
                           spec.frame_depth, spec.reveal_depth, "window")
                door.OverallWidth, door.OverallHeight = d.width, d.height
                api("feature.add_filling", f, opening=opening, element=door)
                doors_out.append(ExpectedOpening(**{**d.__dict__, "element_id": door.GlobalId}))
            c = curtain_at.get((i, k))
            if c is not None:  # unfilled opening glazed by plates and members (no IfcWindow)
                off = float((c.corners_world[3] - origin) @ u)
                opening = void(wall, f"Opening {c.name}", origin, u, off, c.sill, c.width, c.height)
                panels, members = curtain_grid(c.width, c.height, panel_w[i],
                                               spec.curtain_wall_rows)
                parts = [box("IfcPlate", f"{c.name} panel {n}", None, origin, u, off + x,
                             c.sill + z, pw, ph, 0.02, 0.0, "window")
                         for n, (x, z, pw, ph) in enumerate(panels)]
                parts += [box("IfcMember", f"{c.name} member {n}", None, origin, u, off + x,
                              c.sill + z, mw, mh, 0.12, -0.03, "mullion")
                          for n, (x, z, mw, mh) in enumerate(members)]
                cwall = element("IfcCurtainWall", c.name, storey, _placement(origin, u), None)
                api("aggregate.assign_object", f, products=parts, relating_object=cwall)
                curtains_out.append(ExpectedOpening(**{**c.__dict__,
                                                       "element_id": opening.GlobalId}))
    top = spec.storeys * H
    roof = poly if spec.roof_overhang == 0 else offset_polygon(poly, spec.roof_overhang)
    roof_rep = api("geometry.add_slab_representation", f, context=body,
                   depth=spec.slab_thickness, polyline=[tuple(p) for p in roof])
    element("IfcSlab", "Roof", storey, _placement(np.array([0, 0, top]),
                                                  np.array([1.0, 0, 0])), roof_rep, "slab")
    if spec.fascia_height > 0:  # boxes just outside the roof edge, inner face on it
        outer = offset_polygon(poly, spec.roof_overhang + FASCIA_THICKNESS)
        for i in range(len(outer)):
            a, b = outer[i], outer[(i + 1) % len(outer)]
            length = float(np.linalg.norm(b - a))
            box("IfcMember", f"Fascia {i}", storey,
                np.append(a, top + spec.slab_thickness - spec.fascia_height),
                np.append((b - a) / length, 0.0), 0.0, 0.0, length, spec.fascia_height,
                FASCIA_THICKNESS, 0.0, "fascia")
    parts, colours = plan_ornament(spec, poly, windows_out, windows_out + doors_out + curtains_out)
    for key, rgb in colours.items():  # written last: every other entity and GlobalId unchanged
        styles[key] = style(key, [float(c) for c in rgb])
    for p in parts:
        a, b = poly[p.wall_index], poly[(p.wall_index + 1) % len(poly)]
        box("IfcMember", p.name, storeys[p.storey], np.append(a, p.storey * H),
            np.append((b - a) / np.linalg.norm(b - a), 0.0), p.x, p.z, p.w, p.h, p.protrusion,
            -p.protrusion, p.style)
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    f.header.file_name.time_stamp = IFC_TIMESTAMP
    write_ifc_file(f, out_path)
    return GeneratedHouse(spec=spec, path=str(out_path), footprint_world=poly,
                          windows=tuple(windows_out), doors=tuple(doors_out),
                          curtain_walls=tuple(curtains_out))
