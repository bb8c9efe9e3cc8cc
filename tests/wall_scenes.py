"""Small hand-built scenes with exact ground truth by construction (for tests and benchmarks).

The wall's exterior face is the plane y = 0, outward normal -y (a viewer at y < 0 looking at the
wall sees world +x to the right, z up); the wall body is y in [0, thickness]. Walls are unions of axis-aligned boxes around rectangular holes, so the void
rectangles are exact; windows (frame + glass) sit recessed inside the holes.
"""
from __future__ import annotations

from dataclasses import dataclass

import hashlib

import numpy as np
import trimesh

from fenestra.scenes.model import ElementMesh, Scene, WindowGT


def box(lo, hi) -> trimesh.Trimesh:
    """Axis-aligned box from corner ``lo`` (3,) to ``hi`` (3,), metres."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if np.any(hi <= lo):
        raise ValueError(f"box needs hi > lo, got lo={lo.tolist()} hi={hi.tolist()}")
    b = trimesh.creation.box(extents=hi - lo)
    b.apply_translation((lo + hi) / 2)
    return b


def _element(gid, cls, name, meshes, rgba) -> ElementMesh:
    m = trimesh.util.concatenate(meshes) if isinstance(meshes, (list, tuple)) else meshes
    return ElementMesh(gid, cls, name, np.asarray(m.vertices, float), np.asarray(m.faces, np.int64), rgba)


@dataclass(frozen=True)
class Opening:
    """A window opening in the test wall: x0..x1 along the wall, z0..z1 heights (m)."""

    x0: float
    x1: float
    z0: float
    z1: float


def wall_with_holes(length: float, height: float, thickness: float, holes: list[Opening]) -> trimesh.Trimesh:
    """Wall slab x in [0, length], y in [0, thickness], z in [0, height] with rectangular holes.

    Built from boxes (columns between holes, plus pieces above and below each hole): exact edges.
    """
    parts = []
    xs = sorted(holes, key=lambda h: h.x0)
    cursor = 0.0
    for h in xs:
        if not (cursor <= h.x0 < h.x1 <= length and 0 < h.z0 < h.z1 < height):
            raise ValueError(f"opening {h} does not fit the wall (length {length}, height {height})")
        if h.x0 > cursor:
            parts.append(box([cursor, 0, 0], [h.x0, thickness, height]))
        parts.append(box([h.x0, 0, 0], [h.x1, thickness, h.z0]))
        parts.append(box([h.x0, 0, h.z1], [h.x1, thickness, height]))
        cursor = h.x1
    if cursor < length:
        parts.append(box([cursor, 0, 0], [length, thickness, height]))
    return trimesh.util.concatenate(parts)


def window_parts(h: Opening, recess: float = 0.10, frame: float = 0.06, depth: float = 0.07):
    """Frame (4 boxes) and glass pane for an opening, recessed ``recess`` m behind the face."""
    y0, y1 = recess, recess + depth
    fr = [box([h.x0, y0, h.z0], [h.x1, y1, h.z0 + frame]), box([h.x0, y0, h.z1 - frame], [h.x1, y1, h.z1]),
          box([h.x0, y0, h.z0 + frame], [h.x0 + frame, y1, h.z1 - frame]),
          box([h.x1 - frame, y0, h.z0 + frame], [h.x1, y1, h.z1 - frame])]
    glass = box([h.x0 + frame, y0 + 0.03, h.z0 + frame], [h.x1 - frame, y0 + 0.04, h.z1 - frame])
    return fr, glass


def wall_scene(openings: tuple[Opening, ...] = (Opening(1.0, 2.2, 1.0, 2.4), Opening(3.0, 4.0, 0.9, 2.3)),
                    length: float = 5.5, height: float = 3.0, thickness: float = 0.3,
                    sill_top: float | None = None, sill_protrusion: float = 0.08) -> Scene:
    """A facade wall with window openings; exact WindowGT by construction.

    sill_top: if set, a separate "IfcMember" box in front of the first opening, from 0.1 m below
    its bottom edge up to height ``sill_top`` (m), protruding ``sill_protrusion`` m: above the
    void's bottom edge it hides void pixels (a flower box), at the edge it is a plain sill.
    """
    openings = tuple(openings)
    meshes = [_element("wall-0", "IfcWall", "test wall", wall_with_holes(length, height, thickness, list(openings)),
                       (0.85, 0.82, 0.75, 1.0))]
    wins = []
    for i, h in enumerate(openings):
        fr, glass = window_parts(h)
        meshes.append(_element(f"win-{i}", "IfcWindow", f"window {i}", fr + [glass], (0.95, 0.95, 0.95, 1.0)))
        corners = np.array([[h.x0, 0, h.z1], [h.x1, 0, h.z1], [h.x1, 0, h.z0], [h.x0, 0, h.z0]], float)
        wins.append(WindowGT(id=f"win-{i}", host_id="wall-0", host_class="IfcWall", opening_id=f"open-{i}",
                             name=f"window {i}", corners_world=corners, normal=np.array([0.0, -1.0, 0.0]),
                             width=h.x1 - h.x0, height=h.z1 - h.z0, ifc_overall_width=h.x1 - h.x0,
                             ifc_overall_height=h.z1 - h.z0))
    if sill_top is not None:
        h = openings[0]
        meshes.append(_element("sill-0", "IfcMember", "sill", box([h.x0 - 0.05, -sill_protrusion, h.z0 - 0.1],
                                                                   [h.x1 + 0.05, 0.0, sill_top]),
                               (0.6, 0.6, 0.62, 1.0)))
    meshes.append(_element("slab-0", "IfcSlab", "roof slab", box([-0.2, -0.25, height],
                                                                 [length + 0.2, thickness + 0.2, height + 0.2]),
                           (0.45, 0.25, 0.2, 1.0)))
    key = repr((openings, length, height, thickness, sill_top, sill_protrusion)).encode()
    return Scene(name="test-wall", path="<synthetic>", schema="IFC4", sha256=hashlib.sha256(key).hexdigest(),
                 meshes=tuple(meshes), windows=tuple(wins))
