"""Where a window's void is, for every window, with or without ``IfcRelFillsElement``.

``IfcRelFillsElement`` is optional in IFC (IfcOpenShell's IfcOpenHouse, Vectorworks 2013, FreeCAD
0.15 write windows without it), so the void of a window is taken from the first of these sources
that works (model.SOURCES, recorded as WindowGT.source):

- ``fill``: the IfcOpeningElement the window fills, and the wall that opening voids;
- ``opening``: a wall-voiding IfcOpeningElement whose volume (convex hull, 1 cm slack) holds the
  centre of the window's body (its placement origin when it has no body) and that no other
  element fills;
- ``wall_hole``: the hole around the window in the wall it sits in (:func:`host_wall`): the wall's
  mesh sectioned half-way through its thickness, the hole ring around the window's centre;
- ``window_body``: the window's own body: its extent along the wall and up, replaced by
  OverallWidth / OverallHeight where set (> 0) about the same centre.

Each source gives a *void prism* (an opening-like mesh through the wall) and a host wall; the void
rectangle is then measured on the wall's exterior face exactly as for a real opening
(ground_truth.void_on_wall). A source that does not apply raises :class:`SourceError` with the reason.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fenestra.scenes.model import ElementMesh

WALL_CLASSES: tuple[str, ...] = ("IfcWall", "IfcCurtainWall")  # is_a() includes subtypes
EZ = np.array([0.0, 0.0, 1.0])
HULL_SLACK_M = 0.01  # a window's centre may lie this far outside its opening's hull
WALL_SLACK_M = 0.05  # ... this far outside its host wall's faces
PRISM_MARGIN_M = 0.1  # a synthetic void prism reaches this far beyond both wall faces
NEAR_M = 0.3


class SourceError(Exception):
    """This source does not give the window's void; the message says why (one line)."""


@dataclass(frozen=True)
class VoidSource:
    """A window's void as found by one source: a prism mesh through the host wall (world m)."""

    source: str  # one of model.SOURCES
    host: object  # the host wall (ifcopenshell entity)
    opening_id: str  # the IfcOpeningElement's GlobalId, "" for wall_hole / window_body
    vertices: np.ndarray  # (N, 3) m
    faces: np.ndarray  # (M, 3)


# --------------------------------------------------------------------------- geometry helpers
def horizontal_axis(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit horizontal axis (3,) along which the triangles' normals mostly point (sign arbitrary):
    the principal eigenvector of the area-weighted scatter of their horizontal normals."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # |cross| = 2 area
    h = cross[:, :2]
    norm = np.linalg.norm(cross, axis=1)
    keep = (norm > 1e-12) & (np.abs(cross[:, 2]) < 0.2 * np.maximum(norm, 1e-12))
    if not keep.any():
        raise SourceError("no vertical wall face near the window")
    h = h[keep] / np.sqrt(norm[keep])[:, None]  # weight area: (n a)(n a)^T / a
    w, v = np.linalg.eigh(h.T @ h)
    return np.array([v[0, -1], v[1, -1], 0.0])


def prism(outline2: np.ndarray, axis: np.ndarray, d0: float, d1: float) -> tuple[np.ndarray, np.ndarray]:
    """A prism along ``axis`` from depth d0 to d1 (m) over a face outline (K, 2) m in face
    coordinates (x = up x axis, y = world z) -> vertices (2K, 3), faces (4K - 4, 3) (sides, caps fanned)."""
    x_ax = np.cross(EZ, axis)
    x_ax = x_ax / np.linalg.norm(x_ax)
    k = len(outline2)
    flat = outline2[:, :1] * x_ax + outline2[:, 1:2] * EZ
    verts = np.concatenate([flat + d0 * axis, flat + d1 * axis])
    i = np.arange(k)
    j = (i + 1) % k
    sides = np.concatenate([np.stack([i, j, j + k], axis=1), np.stack([i, j + k, i + k], axis=1)])
    fan = np.stack([np.zeros(k - 2, int), np.arange(1, k - 1), np.arange(2, k)], axis=1)
    return verts, np.concatenate([sides, fan[:, ::-1], fan + k]).astype(np.int64)


def face_coords(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """World points (N, 3) -> face coordinates (N, 2): x = up x axis, y = world z."""
    x_ax = np.cross(EZ, axis)
    return np.stack([points @ (x_ax / np.linalg.norm(x_ax)), points[:, 2]], axis=1)


def wall_depths(axis: np.ndarray, lo2: np.ndarray, hi2: np.ndarray, wall: ElementMesh) -> tuple[float, float]:
    """(min, max) depth (m along axis) of the wall's triangles whose face extent overlaps the box
    [lo2, hi2] (face coordinates, m); SourceError when none does."""
    tri = wall.vertices[wall.faces]
    c = face_coords(tri.reshape(-1, 3), axis).reshape(-1, 3, 2)
    sel = np.all((c.max(axis=1) >= lo2) & (c.min(axis=1) <= hi2), axis=1)
    if not sel.any():
        raise SourceError(f"wall {wall.global_id} has no part across the window")
    d = tri[sel] @ axis
    return float(d.min()), float(d.max())


# --------------------------------------------------------------------------- sources
def local_axis(wall: ElementMesh, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The wall's horizontal normal axis near the box [lo, hi] (3,) m (its triangles within NEAR_M)."""
    tri = wall.vertices[wall.faces]
    sel = np.all((tri.max(axis=1) >= lo - NEAR_M) & (tri.min(axis=1) <= hi + NEAR_M), axis=1)
    if not sel.any():
        raise SourceError(f"wall {wall.global_id} has no face near the window")
    return horizontal_axis(wall.vertices, wall.faces[sel])


def wall_span(mesh: ElementMesh, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(axis (3,), d0, d1): the wall's normal axis and depth range (m along it) around the box
    [lo, hi] (3,) m, from its triangles within NEAR_M of the box (beside a hole, not in it)."""
    axis = local_axis(mesh, lo, hi)
    box2 = face_coords(np.stack([lo, hi]), axis)
    d0, d1 = wall_depths(axis, box2.min(axis=0) - NEAR_M, box2.max(axis=0) + NEAR_M, mesh)
    return axis, d0, d1


def holds(mesh: ElementMesh, body: np.ndarray) -> tuple[np.ndarray, float] | None:
    """(axis, distance of the body's centre from the wall's mid-plane, m) when the wall's mesh spans
    the body (N, 3) m within WALL_SLACK_M, else None."""
    lo, hi = body.min(axis=0), body.max(axis=0)
    if np.any(mesh.vertices.min(axis=0) > hi + WALL_SLACK_M) or np.any(mesh.vertices.max(axis=0) < lo - WALL_SLACK_M):
        return None
    try:
        axis, d0, d1 = wall_span(mesh, lo, hi)
    except SourceError:
        return None
    depth = float((lo + hi) / 2.0 @ axis)
    if not d0 - WALL_SLACK_M <= depth <= d1 + WALL_SLACK_M:
        return None
    return axis, abs(depth - (d0 + d1) / 2.0)


def host_wall(body: np.ndarray, walls: list[tuple[object, ElementMesh]]) -> tuple[object, ElementMesh, np.ndarray]:
    """The wall a window's body (N, 3) m sits in: among walls that span the body (:func:`holds`),
    the one whose mid-plane is nearest its centre. Returns (entity, mesh, axis (3,)); SourceError
    when no wall holds it."""
    best, best_d = None, np.inf
    for ent, mesh in walls:
        h = holds(mesh, body)
        if h is not None and h[1] < best_d:
            best, best_d = (ent, mesh, h[0]), h[1]
    if best is None:
        raise SourceError("no wall holds the window's body")
    return best


def hole_outline(wall: ElementMesh, body: np.ndarray, others: np.ndarray) -> np.ndarray:
    """The hole ring (K, 2) m, face coordinates, of the wall's section half-way through its
    thickness that contains the window body's (N, 3) centre; SourceError when there is none or
    when it also holds one of the other windows' centres (M, 3) (one hole, several windows)."""
    import trimesh  # noqa: PLC0415 (trimesh: imported when first used, not at the package's import)
    from shapely.geometry import MultiLineString, Point, Polygon  # noqa: PLC0415 (shapely: imported when first used, not at the package's import)
    from shapely.ops import polygonize  # noqa: PLC0415 (shapely: imported when first used, not at the package's import)

    lo, hi = body.min(axis=0), body.max(axis=0)
    axis, d0, d1 = wall_span(wall, lo, hi)
    c2 = face_coords(((lo + hi) / 2.0)[None], axis)[0]
    mesh = trimesh.Trimesh(wall.vertices, wall.faces, process=False)
    segs = trimesh.intersections.mesh_plane(mesh, axis, axis * (d0 + d1) / 2.0)
    if len(segs) == 0:
        raise SourceError(f"wall {wall.global_id} does not cross its own mid-plane at the window")
    seg2 = face_coords(segs.reshape(-1, 3), axis).reshape(-1, 2, 2)
    polys = list(polygonize(MultiLineString([tuple(map(tuple, s)) for s in np.round(seg2, 7)])))
    rings = [Polygon(r) for p in polys for r in p.interiors if Polygon(r).contains(Point(c2))]
    if not rings:
        raise SourceError(f"wall {wall.global_id} has no closed hole around the window")
    ring = min(rings, key=lambda r: r.area).simplify(1e-6, preserve_topology=True)
    shared = sum(ring.contains(Point(p)) for p in face_coords(others, axis)) if len(others) else 0
    if shared:
        raise SourceError(f"the hole in wall {wall.global_id} also holds {shared} other window(s)")
    return np.asarray(ring.exterior.coords)[:-1]


def through_wall(outline2: np.ndarray, axis: np.ndarray, wall: ElementMesh) -> tuple[np.ndarray, np.ndarray]:
    """A void prism over outline2 (K, 2) reaching PRISM_MARGIN_M beyond both of the wall's faces."""
    d0, d1 = wall_depths(axis, outline2.min(axis=0), outline2.max(axis=0), wall)
    return prism(outline2, axis, d0 - PRISM_MARGIN_M, d1 + PRISM_MARGIN_M)


def body_outline(body: np.ndarray, axis: np.ndarray, overall: tuple[float | None, float | None]
                 ) -> np.ndarray:
    """The window body's rectangle (4, 2) m in face coordinates: its extent along the wall and up,
    each side replaced by overall (width, height) m where set and > 0, about the extent's centre."""
    c = face_coords(body, axis)
    lo, hi = c.min(axis=0), c.max(axis=0)
    mid, size = (lo + hi) / 2.0, hi - lo
    for i, v in enumerate(overall):
        if v is not None and v > 0:
            size[i] = v
    if np.any(size <= 1e-3):
        raise SourceError(f"the window's body is flat ({size[0]:.3f} x {size[1]:.3f} m)")
    (x0, y0), (x1, y1) = mid - size / 2.0, mid + size / 2.0
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


@dataclass
class OpeningIndex:
    """Wall-voiding openings of a file, their meshes (create_shape, cached) and convex hulls."""

    ifc_file: object
    settings: object
    centres: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # every window's centre (W, 3) m
    _items: list | None = None

    def items(self) -> list[tuple[object, object, np.ndarray, np.ndarray, object]]:
        """[(opening, host wall, vertices (N, 3), faces (M, 3), scipy Delaunay)] of every opening
        that voids a wall and has a body."""
        if self._items is None:
            import ifcopenshell.geom  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)
            from scipy.spatial import Delaunay  # noqa: PLC0415 (SciPy: imported when first used, not at the package's import)

            from fenestra.scenes.ifc_read import is_any

            self._items = []
            for op in self.ifc_file.by_type("IfcOpeningElement"):
                hosts = [r.RelatingBuildingElement for r in op.VoidsElements or ()]
                if not hosts or not is_any(hosts[0], WALL_CLASSES):
                    continue
                try:
                    sh = ifcopenshell.geom.create_shape(self.settings, op)
                except RuntimeError:
                    continue
                v = np.asarray(sh.geometry.verts, dtype=np.float64).reshape(-1, 3)
                f = np.asarray(sh.geometry.faces, dtype=np.int64).reshape(-1, 3)
                if len(f) < 4:
                    continue
                c = v.mean(axis=0)
                out = v - c
                grown = c + out + HULL_SLACK_M * out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
                try:
                    hull = Delaunay(grown)
                except Exception:  # noqa: BLE001  (flat opening: qhull refuses it)
                    continue
                self._items.append((op, hosts[0], v, f, hull))
        return self._items


def opening_holding(body: np.ndarray, window_id: str, index: OpeningIndex,
                    meshes: dict[str, ElementMesh]) -> VoidSource:
    """Source ``opening``: the wall-voiding opening, unfilled or filled by this window, whose hull
    holds the body's (N, 3) m centre, whose wall holds the body, and that holds no other window."""
    c = (body.min(axis=0) + body.max(axis=0)) / 2.0
    for op, host, v, f, hull in index.items():
        fillers = {r.RelatedBuildingElement.GlobalId for r in op.HasFillings or ()}
        if fillers - {window_id} or hull.find_simplex(c[None])[0] < 0:
            continue
        wall = meshes.get(host.GlobalId)
        if wall is None or holds(wall, body) is None:
            continue
        n = int((hull.find_simplex(index.centres) >= 0).sum()) if len(index.centres) else 1
        if n > 1:
            raise SourceError(f"opening {op.GlobalId} holds {n} windows")
        return VoidSource("opening", host, op.GlobalId, v, f)
    raise SourceError("no wall-voiding opening holds the window")


def window_void(win, window_mesh: ElementMesh | None, placement: np.ndarray, overall,
                index: OpeningIndex, walls: list[tuple[object, ElementMesh]],
                meshes: dict[str, ElementMesh]) -> tuple[VoidSource, list[str]]:
    """The first source (after ``fill``) that gives the window's void, and the reasons the ones
    before it did not. placement: the window's placement origin (3,) m, world (its body when it
    has no geometry of its own); overall: (width, height) m or None. SourceError with every
    reason when none works."""
    reasons: list[str] = []
    body = window_mesh.vertices if window_mesh is not None else placement[None]
    try:
        return opening_holding(body, win.GlobalId, index, meshes), reasons
    except SourceError as e:
        reasons.append(f"opening: {e}")
    if window_mesh is None:
        raise SourceError("; ".join(reasons + ["the window has no body to find its wall by"]))
    try:
        host, mesh, axis = host_wall(body, walls)
    except SourceError as e:
        raise SourceError("; ".join(reasons + [str(e)])) from None
    c = (body.min(axis=0) + body.max(axis=0)) / 2.0
    others = index.centres[np.linalg.norm(index.centres - c, axis=1) > 1e-9] if len(index.centres) else index.centres
    try:
        v, f = through_wall(hole_outline(mesh, body, others), axis, mesh)
        return VoidSource("wall_hole", host, "", v, f), reasons
    except SourceError as e:
        reasons.append(f"wall_hole: {e}")
    v, f = through_wall(body_outline(body, axis, overall), axis, mesh)
    return VoidSource("window_body", host, "", v, f), reasons
