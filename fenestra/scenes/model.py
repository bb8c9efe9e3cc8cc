"""Data types of a loaded scene: element meshes and window ground truth (the scenes/ contract).

Everything downstream (renders/, bench/) consumes these types; nothing here depends on IFC.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ElementMesh:
    """One IFC element as a triangle mesh in world coordinates (metres, z up).

    vertices: (N, 3) float64 m; faces: (M, 3) int64 indices into vertices;
    rgba: (4,) float in [0, 1] from the IFC surface style (a class default when none).
    """

    global_id: str
    ifc_class: str  # e.g. "IfcWall", "IfcWindow", "IfcSlab"
    name: str
    vertices: np.ndarray
    faces: np.ndarray
    rgba: tuple[float, float, float, float]
    # Optional per-face colours (M, 4) float in [0, 1] when the element has several surface styles
    # (e.g. a window's frame and its glass; alpha = 1 - IFC transparency). None: use ``rgba``.
    face_rgba: np.ndarray | None = None
    # GlobalId of the element this one is aggregated into (IfcRelAggregates), e.g. the
    # IfcCurtainWall of an IfcPlate panel; "" when none.
    parent_id: str = ""
    # The class the element loads, looks and renders as: its nearest ancestor among the loader's
    # BASE_CLASSES by IFC inheritance (IfcWindowStandardCase -> "IfcWindow", IfcWallStandardCase ->
    # "IfcWall"); "" for a class with none (then ``ifc_class`` itself, see :attr:`kind`).
    base_class: str = ""

    @property
    def kind(self) -> str:
        """``base_class`` when set, else ``ifc_class``: what material and class checks compare."""
        return self.base_class or self.ifc_class


# How a window's void was found (WindowGT.source), first that works, in this order (docs/DESIGN.md):
# "fill": the IfcOpeningElement it fills (IfcRelFillsElement) and the wall that opening voids;
# "opening": no fill relation; the wall-voiding IfcOpeningElement whose volume holds the window's
# body (or placement); "wall_hole": no such opening; the hole around the window's body in the wall
# it sits in (a wall shape with the hole built in); "window_body": no hole either; the window's own
# body (OverallWidth/Height where set) on that wall's exterior face.
SOURCES: tuple[str, ...] = ("fill", "opening", "wall_hole", "window_body")


@dataclass(frozen=True)
class WindowGT:
    """Exact ground truth of one window void.

    corners_world: (4, 3) m, the opening's outline on the host wall's exterior face, ordered
    TL, TR, BR, BL as seen from outside (x along the wall to the right, y = world up).
    normal: (3,) unit outward normal of the exterior face. width/height in m (width = |TR - TL|).
    """

    id: str  # IfcWindow GlobalId
    host_id: str  # host wall GlobalId
    host_class: str
    opening_id: str  # IfcOpeningElement GlobalId ("" when the source has none: wall_hole, window_body)
    name: str
    corners_world: np.ndarray
    normal: np.ndarray
    width: float
    height: float
    ifc_overall_width: float | None  # IfcWindow.OverallWidth in metres (None if unset)
    ifc_overall_height: float | None
    # "rectangle": corners_world are the void's own 4 corners. "non_rectangular" (e.g. FZK-Haus's
    # round gable windows): corners_world is the void's bounding rectangle in the wall plane and
    # outline_world (K, 3) m holds the true outline on the exterior face.
    shape: str = "rectangle"
    outline_world: np.ndarray | None = None
    notes: str = ""  # e.g. that the void overlaps another opening of the same wall
    source: str = "fill"  # one of SOURCES: how the void was found

    @property
    def center(self) -> np.ndarray:
        return self.corners_world.mean(axis=0)

    @property
    def aspect_ratio(self) -> float:
        return self.width / self.height


@dataclass(frozen=True)
class SkippedWindow:
    """An IfcWindow with no ground truth, and why (e.g. hosted in a roof slab)."""

    id: str
    name: str
    reason: str  # one line: why, naming the elements involved
    cause: str = ""  # a short class of the reason for the census ("not in a wall", "no geometry", ...)


@dataclass(frozen=True)
class Scene:
    """A loaded house: its meshes and its windows' ground truth."""

    name: str
    path: str
    schema: str
    sha256: str
    meshes: tuple[ElementMesh, ...]
    windows: tuple[WindowGT, ...]
    skipped: tuple[SkippedWindow, ...] = field(default_factory=tuple)

    @property
    def n_present(self) -> int:
        """IfcWindow elements in the file: every one is a window or a skipped window."""
        return len(self.windows) + len(self.skipped)

    def census(self) -> dict:
        """{"present", "extracted", "skipped": {cause: count}, "sources": {source: count}}."""
        skipped: dict[str, int] = {}
        for s in self.skipped:
            skipped[s.cause or s.reason] = skipped.get(s.cause or s.reason, 0) + 1
        sources: dict[str, int] = {}
        for w in self.windows:
            sources[w.source] = sources.get(w.source, 0) + 1
        return {"present": self.n_present, "extracted": len(self.windows), "skipped": skipped,
                "sources": sources}

    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned world bounds of all meshes, m."""
        v = np.concatenate([m.vertices for m in self.meshes])
        return np.stack([v.min(axis=0), v.max(axis=0)])
