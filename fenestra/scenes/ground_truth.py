"""Exact window-void ground truth from IFC: the opening's outline on the host wall's exterior face.

For every ``IfcWindow``, its void (an opening-like prism through its host wall) comes from the first
source that works (fenestra.scenes.window_sources, ``WindowGT.source``): the ``IfcOpeningElement`` it
fills (``IfcRelFillsElement``) which voids a wall (``IfcRelVoidsElement``; ``IfcWall`` and subtypes,
``IfcCurtainWall``), else the wall-voiding opening that holds it, the hole in its wall, its own body.
Then:

1. Wall normal axis ``n`` (horizontal unit vector): among the opening's own horizontal face
   directions (an opening is a prism through the wall), the one along which the host wall's mesh
   has the most face area. A straight wall's two faces dwarf its reveals and end faces.
2. The two face planes: the host wall's triangles with normal +n / -n that touch the opening's
   lateral extent; their outermost offsets along n are the two faces the opening passes through.
3. Exterior side (the rule, tested in tests/scenes/test_scenes_ground_truth.py): from a point just off
   each face, at the void's centre, cast a fixed fan of rays over the hemisphere on that side
   (upward-biased: never below -10 deg, so terrain/ground does not count) against every mesh of
   the building except the site. The side from which more rays escape to infinity is outside.
   Interior faces see walls, floors, ceilings, glazing in every direction; exterior faces see the
   sky. If the two escape fractions differ by less than ``MIN_ESCAPE_MARGIN`` the window is skipped
   with that reason rather than guessed.
4. The void outline: the opening mesh sectioned by the exterior face plane (1e-5 m inside when the
   opening's cap lies exactly on that face: openings are prisms along n, so the projection onto the
   face is exact). 2-D coordinates on the face: x = up x n (to the right seen from outside),
   y = world z. A 4-vertex outline with right angles is a rectangle and its own vertices are the
   corners; anything else (FZK-Haus's round gable windows) gets its bounding rectangle and
   ``shape="non_rectangular"``.

5. ``notes`` names any other opening of the same wall that overlaps the void (the visible hole is
   then their union: NiedriHa's Wind-074 and its neighbouring door, by 2.9 mm).

Windows hosted elsewhere (a roof or slab: the Duplex skylights) or whose geometry does not fit the
above go to ``Scene.skipped`` with the reason; none is dropped silently.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.scenes.ifc_read import is_any
from fenestra.scenes.model import ElementMesh, SkippedWindow, WindowGT
from fenestra.scenes.window_sources import WALL_CLASSES, OpeningIndex, SourceError, VoidSource, window_void
MIN_ESCAPE_MARGIN = 0.1  # exterior side needs this many more escaping rays (fraction)
N_RAYS = 48
RAY_OFFSET_M = 0.02
CAP_INSET_M = 1e-5
RIGHT_ANGLE_DEG = 0.01
FACE_COS = float(np.cos(np.radians(20.0)))  # a wall triangle within 20 deg of the axis is a face (curved walls)
NEAR_M = 0.3  # wall triangles this close to the opening's box decide its axis
SHORT_SLACK_M = 0.05  # an opening may stop this short of a (curved) exterior face: its prism's section is the same
RAY_CHUNK = 20000  # triangles per block in rays_hit_any
EZ = np.array([0.0, 0.0, 1.0])


class VoidGeometryError(Exception):
    """The void cannot be measured for this window; the message is the skip reason."""


@dataclass(frozen=True)
class VoidGeometry:
    """Result of :func:`void_on_wall`. corners (4, 3) m TL TR BR BL; normal (3,) outward unit."""

    corners: np.ndarray
    normal: np.ndarray
    width: float
    height: float
    shape: str
    outline: np.ndarray  # (K, 3) m, the void outline on the exterior face
    escape_out: float  # fraction of rays escaping from the exterior face
    escape_in: float  # ... from the interior face


# --------------------------------------------------------------------------- mesh helpers
def triangle_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (M, 3) and areas (M,) m^2 of triangles; degenerate triangles get normal 0."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    safe = np.where(norm > 0, norm, 1.0)
    return cross / safe[:, None], 0.5 * norm


def face_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-plane axes of a vertical face with outward ``normal``: x = up x normal (right, seen from
    outside), y = world up."""
    x = np.cross(EZ, normal)
    return x / np.linalg.norm(x), EZ.copy()


def near_box(tri: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(M,) bool: triangles (M, 3, 3) whose bounding box overlaps the box [lo, hi] (3,) m."""
    return np.all((tri.max(axis=1) >= lo) & (tri.min(axis=1) <= hi), axis=1)


def _ranked(cand: np.ndarray, w_n: np.ndarray, w_a: np.ndarray, cos_min: float) -> list[np.ndarray]:
    """Distinct candidate directions (3,) with wall area along them (triangles, normals w_n (M, 3),
    areas w_a (M,), with |n . c| > cos_min), most area first; those with none left out."""
    scored: list[tuple[float, np.ndarray]] = []
    for c in cand:
        c = c / np.linalg.norm(c)
        if any(abs(c @ t) > 1 - 1e-9 for _, t in scored):
            continue
        scored.append((float(w_a[np.abs(w_n @ c) > cos_min].sum()), c))
    return [c for a, c in sorted(scored, key=lambda x: -x[0]) if a > 0]


def candidate_axes(op_vertices: np.ndarray, op_faces: np.ndarray, wall_vertices: np.ndarray,
                   wall_faces: np.ndarray) -> list[np.ndarray]:
    """Horizontal unit axes (3,) the host wall's normal may be at the opening, best first.

    Candidates are the opening's own horizontal face directions (an opening is a prism through
    the wall, so the wall normal is one of them), ranked by the host wall's face area exactly
    parallel to them, then (a curved wall's facets) by the area of the host's triangles near the
    opening (within NEAR_M of its box) whose normal is within 20 deg of them.
    """
    op_n, op_a = triangle_normals(op_vertices, op_faces)
    w_n, w_a = triangle_normals(wall_vertices, wall_faces)
    cand = op_n[(np.abs(op_n[:, 2]) < 1e-6) & (op_a > 1e-9)]
    near = near_box(wall_vertices[wall_faces], op_vertices.min(axis=0) - NEAR_M,
                    op_vertices.max(axis=0) + NEAR_M)
    out: list[np.ndarray] = []
    for c in _ranked(cand, w_n, w_a, 1 - 1e-9) + _ranked(cand, w_n[near], w_a[near], FACE_COS):
        c = c.copy()
        c[2] = 0.0
        c /= np.linalg.norm(c)
        if not any(abs(c @ t) > 1 - 1e-9 for t in out):
            out.append(c)
    return out


def wall_normal_axis(op_vertices: np.ndarray, op_faces: np.ndarray, wall_vertices: np.ndarray,
                     wall_faces: np.ndarray) -> np.ndarray:
    """Horizontal unit normal axis (3,) of the host wall at the opening (sign arbitrary): the first
    of :func:`candidate_axes` for which the wall has a face on each side (:func:`face_offsets`).
    Raises VoidGeometryError when none has."""
    return wall_axis_and_faces(op_vertices, op_faces, wall_vertices, wall_faces)[0]


def wall_axis_and_faces(op_vertices: np.ndarray, op_faces: np.ndarray, wall_vertices: np.ndarray,
                        wall_faces: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """(axis (3,), (d_minus, d_plus) m): the first candidate axis whose face offsets exist."""
    axes = candidate_axes(op_vertices, op_faces, wall_vertices, wall_faces)
    if not axes:
        raise VoidGeometryError("no vertical face of the opening is parallel to a host wall face")
    first_error = None
    for axis in axes:
        try:
            return axis, face_offsets(axis, op_vertices, wall_vertices, wall_faces)
        except VoidGeometryError as e:
            first_error = first_error or e
    raise first_error


def face_offsets(axis: np.ndarray, op_vertices: np.ndarray, wall_vertices: np.ndarray,
                 wall_faces: np.ndarray) -> tuple[float, float]:
    """Offsets (m, along ``axis``) of the wall's two face planes where the opening passes.

    Uses wall triangles with normal within 20 deg of +-axis whose extent (x along the wall, z)
    overlaps the opening's, expanded by 1 mm: the outermost vertex on each side (a flat face's
    plane; a curved face's outermost point at the opening). Returns (d_minus, d_plus), d_minus < d_plus.
    """
    normals, areas = triangle_normals(wall_vertices, wall_faces)
    x_ax = np.cross(EZ, axis)
    tri = wall_vertices[wall_faces]  # (M, 3, 3)
    tx, tz = tri @ x_ax, tri[..., 2]
    ox, oz = op_vertices @ x_ax, op_vertices[:, 2]
    pad = 1e-3
    inside = ((tx.max(axis=1) >= ox.min() - pad) & (tx.min(axis=1) <= ox.max() + pad)
              & (tz.max(axis=1) >= oz.min() - pad) & (tz.min(axis=1) <= oz.max() + pad))
    dots = normals @ axis
    plus = inside & (dots > FACE_COS) & (areas > 0)
    minus = inside & (dots < -FACE_COS) & (areas > 0)
    if not plus.any() or not minus.any():
        raise VoidGeometryError("host wall has no pair of faces around the opening")
    d = tri @ axis
    d_minus, d_plus = float(d[minus].min()), float(d[plus].max())
    if d_minus >= d_plus:
        raise VoidGeometryError(f"host wall's faces around the opening are not on two sides of it "
                                f"({d_minus:.3f} >= {d_plus:.3f} m along the wall normal)")
    return d_minus, d_plus


# --------------------------------------------------------------------------- ray casting
def hemisphere_directions(normal: np.ndarray, n_rays: int = N_RAYS,
                          min_elevation_deg: float = -10.0) -> np.ndarray:
    """Deterministic unit directions (n_rays, 3) in the half-space of ``normal`` (horizontal),
    elevation in [min_elevation_deg, 85] deg, azimuth within +-85 deg of the normal."""
    n = normal / np.linalg.norm(normal)
    x = np.cross(EZ, n)
    k = int(np.ceil(np.sqrt(n_rays)))
    az = np.radians(np.linspace(-85.0, 85.0, k))
    el = np.radians(np.linspace(min_elevation_deg, 85.0, k))
    A, E = np.meshgrid(az, el)
    A, E = A.ravel()[:n_rays], E.ravel()[:n_rays]
    d = (np.cos(E) * np.cos(A))[:, None] * n + (np.cos(E) * np.sin(A))[:, None] * x \
        + np.sin(E)[:, None] * EZ
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@dataclass(frozen=True, eq=False)
class TriangleCones:
    """Triangles (T, 3, 3) m prepared once for many ray fans (:func:`rays_hit_any`).

    For an origin o, the cone edge normal (v_j - o) x (v_k - o) = P + o x E with P = v_j x v_k and
    E = v_j - v_k, so a ray direction d is on its inner side when [d, d x o] . [P, E] >= 0; the
    cone's determinant is Q + o . W. PE (3, T, 6) stacks [P, E] per edge; Q (T,), W (T, 3);
    xy (T, 3, 2) the corners' horizontal coordinates (the front cull).
    """

    PE: np.ndarray
    Q: np.ndarray
    W: np.ndarray
    xy: np.ndarray
    z: np.ndarray

    @staticmethod
    def of(triangles: np.ndarray) -> "TriangleCones":
        """Prepare triangles (T, 3, 3) m."""
        v0, v1, v2 = triangles[:, 0], triangles[:, 1], triangles[:, 2]
        P = np.stack([np.cross(v1, v2), np.cross(v2, v0), np.cross(v0, v1)])
        E = np.stack([v1 - v2, v2 - v0, v0 - v1])
        return TriangleCones(PE=np.concatenate([P, E], axis=2), Q=np.einsum("ij,ij->i", v0, P[0]),
                             W=np.cross(E[0], v0) - P[0], xy=triangles[..., :2].copy(),
                             z=triangles[..., 2].copy())

    def __len__(self) -> int:
        return self.Q.shape[0]

    def in_front(self, origin: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Indices of the triangles with a corner in front of the plane through origin (3,) with
        normal (3,): the only ones a ray into that half-space can hit."""
        depth = self.xy @ normal[:2] + self.z * normal[2]
        return np.nonzero(depth.max(axis=1) > origin @ normal - 1e-9)[0]


def rays_hit_any(origin: np.ndarray, directions: np.ndarray, triangles,
                 subset: np.ndarray | None = None) -> np.ndarray:
    """(R,) bool: does the ray origin + s*direction (s > 0) hit any of triangles (T, 3, 3) (or
    their :class:`TriangleCones`; ``subset``: indices of the only ones to test)?

    A ray hits a triangle when its direction is a non-negative combination of the corners seen
    from the origin (the triangle's cone): three sign tests against the cone's edge planes, done
    as matrix products over blocks of RAY_CHUNK triangles (T can be ~10^6); rays that hit are
    not tested further.
    """
    cones = triangles if isinstance(triangles, TriangleCones) else TriangleCones.of(np.asarray(triangles))
    d = np.asarray(directions, dtype=np.float64)
    dd = np.concatenate([d, np.cross(d, origin)], axis=1)  # (R, 6): d . (o x E) = E . (d x o)
    idx = np.arange(len(cones)) if subset is None else subset
    hits = np.zeros(len(d), dtype=bool)
    for k in range(0, len(idx), RAY_CHUNK):
        live = np.nonzero(~hits)[0]
        if len(live) == 0:
            break
        sel = idx[k:k + RAY_CHUNK]
        det = cones.Q[sel] + cones.W[sel] @ origin
        ok = np.abs(det) > 1e-12
        sel, sgn = sel[ok], np.sign(det[ok])[:, None]
        inside = dd[live] @ (cones.PE[0, sel] * sgn).T >= 0
        for j in (1, 2):
            inside &= dd[live] @ (cones.PE[j, sel] * sgn).T >= 0
        hits[live] = inside.any(axis=1)
    return hits


def escape_fraction(point: np.ndarray, normal: np.ndarray, triangles) -> float:
    """Fraction of a hemisphere ray fan from ``point + RAY_OFFSET_M*normal`` that hits nothing
    (triangles (T, 3, 3) m or their TriangleCones; only those in front of the origin are tested)."""
    origin = point + RAY_OFFSET_M * normal
    cones = triangles if isinstance(triangles, TriangleCones) else TriangleCones.of(np.asarray(triangles))
    dirs = hemisphere_directions(normal)
    return float(1.0 - rays_hit_any(origin, dirs, cones, cones.in_front(origin, normal)).mean())


# --------------------------------------------------------------------------- section
def section_outline(op_vertices: np.ndarray, op_faces: np.ndarray, normal: np.ndarray,
                    d_face: float) -> np.ndarray:
    """Outline (K, 2) m of the opening on the plane n.p = d_face, in face coordinates (x, y).

    Sections the opening mesh at the face (or CAP_INSET_M inside it when the opening's cap lies on
    the face) and returns the largest polygon, collinear vertices removed, counter-clockwise.
    """
    import shapely  # noqa: PLC0415 (shapely: imported when first used, not at the package's import)
    import trimesh  # noqa: PLC0415 (trimesh: imported when first used, not at the package's import)
    from shapely.geometry import MultiLineString  # noqa: PLC0415 (shapely: imported when first used, not at the package's import)
    from shapely.ops import polygonize  # noqa: PLC0415 (shapely: imported when first used, not at the package's import)

    depth = op_vertices @ normal
    if depth.max() < d_face - SHORT_SLACK_M:
        raise VoidGeometryError(
            f"opening stops {d_face - depth.max():.3f} m short of the exterior face")
    d_cut = min(d_face, depth.max() - CAP_INSET_M)
    d_cut = max(d_cut, depth.min() + CAP_INSET_M)
    mesh = trimesh.Trimesh(op_vertices, op_faces, process=False)
    segs = trimesh.intersections.mesh_plane(mesh, normal, normal * d_cut)
    if len(segs) == 0:
        raise VoidGeometryError("opening does not cross the exterior face plane")
    x_ax, y_ax = face_axes(normal)
    seg2 = np.stack([segs @ x_ax, segs @ y_ax], axis=-1)
    polys = list(polygonize(MultiLineString([tuple(map(tuple, s)) for s in np.round(seg2, 9)])))
    if not polys:
        raise VoidGeometryError("opening section is not a closed outline")
    poly = max(polys, key=lambda p: p.area)
    poly = shapely.geometry.polygon.orient(poly.simplify(1e-7, preserve_topology=True), 1.0)
    return np.asarray(poly.exterior.coords)[:-1]


def rectangle_corners(outline: np.ndarray) -> tuple[np.ndarray, str]:
    """Outline (K, 2) in face coords -> corners (4, 2) TL TR BR BL and shape name.

    A 4-vertex outline with right angles (RIGHT_ANGLE_DEG) returns its own vertices; any other
    outline its axis-aligned bounding rectangle with shape "non_rectangular".
    """
    if len(outline) == 4:
        edges = np.roll(outline, -1, axis=0) - outline
        unit = edges / np.linalg.norm(edges, axis=1, keepdims=True)
        cosines = np.abs(np.einsum("ij,ij->i", unit, np.roll(unit, -1, axis=0)))
        if np.all(cosines < np.sin(np.radians(RIGHT_ANGLE_DEG))):
            c = outline.mean(axis=0)
            picks = []
            for sx, sy in ((-1, 1), (1, 1), (1, -1), (-1, -1)):  # TL TR BR BL
                score = (outline - c) @ np.array([sx, sy], dtype=float)
                picks.append(outline[np.argmax(score)])
            return np.array(picks), "rectangle"
    (x0, y0), (x1, y1) = outline.min(axis=0), outline.max(axis=0)
    return np.array([[x0, y1], [x1, y1], [x1, y0], [x0, y0]]), "non_rectangular"


def to_world(points2: np.ndarray, normal: np.ndarray, d_face: float) -> np.ndarray:
    """Face coordinates (K, 2) -> world points (K, 3) on the plane normal.p = d_face."""
    x_ax, y_ax = face_axes(normal)
    return points2[:, :1] * x_ax + points2[:, 1:2] * y_ax + d_face * normal


def exterior_side_reason(esc_a: float, esc_b: float) -> str:
    """Why the exterior side cannot be told from two faces' escape fractions (one line): both
    enclosed (an interior wall), both open (a lone wall: nothing of the building around it), or
    merely too close to call."""
    both = f"{esc_a:.0%} vs {esc_b:.0%} of rays escape from the two faces"
    if max(esc_a, esc_b) < MIN_ESCAPE_MARGIN:
        return f"cannot tell the exterior side: both faces are enclosed, an interior wall ({both})"
    if min(esc_a, esc_b) > 1 - MIN_ESCAPE_MARGIN:
        return (f"cannot tell the exterior side: both faces see the sky, a lone wall with no building "
                f"around it ({both})")
    return f"cannot tell the exterior side ({both})"


# --------------------------------------------------------------------------- one window
def side_key(host_id: str, axis: np.ndarray, d_minus: float, d_plus: float) -> tuple:
    """Cache key of one flat wall's pair of faces: host, axis (sign fixed, 1e-3), offsets (cm)."""
    return host_id, tuple(np.round(axis, 3)), round(d_minus, 2), round(d_plus, 2)


def void_on_wall(op_vertices: np.ndarray, op_faces: np.ndarray, wall_vertices: np.ndarray,
                 wall_faces: np.ndarray, scene_triangles, side_cache: dict | None = None,
                 host_id: str = "") -> VoidGeometry:
    """The void of one opening on its host wall's exterior face (see module docstring).

    op_*: the opening's mesh, wall_*: the host wall's cut mesh, scene_triangles (T, 3, 3) (or their
    TriangleCones): every building triangle used for the exterior test; all world coordinates, m.
    side_cache: escape fractions of a wall's face pair (:func:`side_key`) already cast for another
    of its windows: the exterior side of a flat wall's face pair is one answer, cast once.
    Raises VoidGeometryError (message = skip reason) when the geometry does not fit.
    """
    axis, (d_minus, d_plus) = wall_axis_and_faces(op_vertices, op_faces, wall_vertices, wall_faces)
    if axis[np.argmax(np.abs(axis))] < 0:  # one sign per axis, so both faces' windows share the key
        axis, (d_minus, d_plus) = -axis, (-d_plus, -d_minus)
    x_ax = np.cross(EZ, axis)
    c2 = np.array([(op_vertices @ x_ax).min() + (op_vertices @ x_ax).max(),
                   op_vertices[:, 2].min() + op_vertices[:, 2].max()]) / 2.0
    key = side_key(host_id, axis, d_minus, d_plus)
    if side_cache is not None and host_id and key in side_cache:
        esc_plus, esc_minus = side_cache[key]
    else:
        centre_plus = c2[0] * x_ax + c2[1] * EZ + d_plus * axis
        centre_minus = c2[0] * x_ax + c2[1] * EZ + d_minus * axis
        esc_plus = escape_fraction(centre_plus, axis, scene_triangles)
        esc_minus = escape_fraction(centre_minus, -axis, scene_triangles)
        if side_cache is not None and host_id:
            side_cache[key] = (esc_plus, esc_minus)
    if abs(esc_plus - esc_minus) < MIN_ESCAPE_MARGIN:
        raise VoidGeometryError(exterior_side_reason(esc_plus, esc_minus))
    if esc_plus > esc_minus:
        normal, d_face, esc_out, esc_in = axis, d_plus, esc_plus, esc_minus
    else:
        normal, d_face, esc_out, esc_in = -axis, -d_minus, esc_minus, esc_plus
    outline2 = section_outline(op_vertices, op_faces, normal, d_face)
    corners2, shape = rectangle_corners(outline2)
    corners = to_world(corners2, normal, d_face)
    return VoidGeometry(
        corners=corners, normal=normal, shape=shape, outline=to_world(outline2, normal, d_face),
        width=float(np.linalg.norm(corners[1] - corners[0])),
        height=float(np.linalg.norm(corners[0] - corners[3])),
        escape_out=esc_out, escape_in=esc_in)


def _opening_vertices(opening, settings, cache: dict[str, np.ndarray]) -> np.ndarray | None:
    """World vertices (N, 3) of an opening's body (cached by GlobalId); None without geometry."""
    import ifcopenshell.geom  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    if opening.GlobalId not in cache:
        try:
            sh = ifcopenshell.geom.create_shape(settings, opening)
            cache[opening.GlobalId] = np.asarray(sh.geometry.verts, dtype=np.float64).reshape(-1, 3)
        except RuntimeError:
            cache[opening.GlobalId] = np.zeros((0, 3))
    v = cache[opening.GlobalId]
    return v if len(v) else None


def overlap_notes(g: VoidGeometry, opening, host, settings, cache: dict[str, np.ndarray]) -> str:
    """Text naming the other openings of the same host whose extent on the face overlaps this void
    (e.g. NiedriHa's Wind-074 overlaps the neighbouring door opening by 2.9 mm: the visible hole
    is their union); "" when none."""
    x_ax, _ = face_axes(g.normal)
    x0, x1 = sorted((g.corners[0] @ x_ax, g.corners[1] @ x_ax))
    z0, z1 = g.corners[3][2], g.corners[0][2]
    notes = []
    for rel in host.HasOpenings:
        other = rel.RelatedOpeningElement
        if other.GlobalId == opening.GlobalId:
            continue
        v = _opening_vertices(other, settings, cache)
        if v is None:
            continue
        ox0, ox1, oz0, oz1 = (v @ x_ax).min(), (v @ x_ax).max(), v[:, 2].min(), v[:, 2].max()
        dx, dz = min(x1, ox1) - max(x0, ox0), min(z1, oz1) - max(z0, oz0)
        if dx > 1e-6 and dz > 1e-6:
            fills = [f"{r.RelatedBuildingElement.is_a()} '{r.RelatedBuildingElement.Name}'"
                     for r in other.HasFillings] or ["nothing"]
            notes.append(f"void overlaps opening {other.GlobalId} (filled by {', '.join(fills)}) "
                         f"by {min(dx, dz) * 1000:.1f} mm; the visible hole is their union")
    return "; ".join(notes)


# --------------------------------------------------------------------------- whole file
def scene_triangles(meshes: dict[str, ElementMesh]) -> np.ndarray:
    """(T, 3, 3) world triangles of every mesh except the site (terrain), for the exterior test."""
    tris = [m.vertices[m.faces] for m in meshes.values() if m.kind != "IfcSite"]
    return np.concatenate(tris) if tris else np.zeros((0, 3, 3))


def _fill_source(win, meshes: dict[str, ElementMesh], settings) -> VoidSource:
    """Source ``fill``: the window's IfcRelFillsElement opening and the wall it voids.

    Raises NotInWall (final: a roof window) or SourceError (try the geometric sources)."""
    import ifcopenshell.geom  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    if not win.FillsVoids:
        raise SourceError("fills no opening (no IfcRelFillsElement)")
    opening = win.FillsVoids[0].RelatingOpeningElement
    if not opening.VoidsElements:
        raise SourceError(f"opening {opening.GlobalId} voids no element (no IfcRelVoidsElement)")
    host = opening.VoidsElements[0].RelatingBuildingElement
    if not is_any(host, WALL_CLASSES):
        kind = host.is_a()
        raise NotInWall(f"hosted in {kind} {host.GlobalId}, not a wall"
                        + (" (roof window / skylight)" if is_any(host, ("IfcRoof", "IfcSlab")) else ""))
    try:
        shape = ifcopenshell.geom.create_shape(settings, opening)
    except RuntimeError as e:
        raise SourceError(f"opening {opening.GlobalId} has no usable geometry ({e})") from None
    op_v = np.asarray(shape.geometry.verts, dtype=np.float64).reshape(-1, 3)
    op_f = np.asarray(shape.geometry.faces, dtype=np.int64).reshape(-1, 3)
    if len(op_f) == 0:
        raise SourceError(f"opening {opening.GlobalId} has an empty body")
    return VoidSource("fill", host, opening.GlobalId, op_v, op_f)


class NotInWall(Exception):
    """The window is hosted in something other than a wall (a roof window): skipped, no fallback."""


def placement_origin(win, scale: float) -> np.ndarray:
    """World position (3,) m of a product's ObjectPlacement origin (zeros when it has none)."""
    import ifcopenshell.util.placement  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    if win.ObjectPlacement is None:
        return np.zeros(3)
    return np.asarray(ifcopenshell.util.placement.get_local_placement(win.ObjectPlacement))[:3, 3] * scale


def _causes(reason: str) -> str:
    """A short class of a skip reason for the census."""
    for key, cause in (("not a wall", "not in a wall"), ("interior wall", "interior wall"),
                       ("lone wall", "lone wall"), ("exterior side", "exterior side unknown"),
                       ("no usable geometry", "opening has no geometry"), ("no body", "no body geometry"),
                       ("no wall holds", "not in a wall"), ("short of", "opening short of the face")):
        if key in reason:
            return cause
    return "void not measurable"


def measure_window(win, meshes, settings, index: OpeningIndex, walls, tris: TriangleCones,
                   scale: float, side_cache: dict | None = None) -> tuple[VoidSource, VoidGeometry]:
    """The window's void source and its rectangle on the exterior face, by the first source that
    works (window_sources); raises NotInWall, or SourceError naming every source's reason."""
    reasons: list[str] = []
    candidates = []
    try:
        candidates.append(_fill_source(win, meshes, settings))
    except SourceError as e:
        reasons.append(f"fill: {e}")
    ow, oh = win.OverallWidth, win.OverallHeight
    overall = (None if ow is None else float(ow) * scale, None if oh is None else float(oh) * scale)
    for attempt in range(2):
        if attempt == 1:
            try:
                src, why = window_void(win, meshes.get(win.GlobalId), placement_origin(win, scale),
                                       overall, index, walls, meshes)
            except SourceError as e:
                raise SourceError("; ".join(reasons + [str(e)])) from None
            reasons.extend(why)
            candidates = [src]
        for src in candidates:
            host_mesh = meshes.get(src.host.GlobalId)
            if host_mesh is None:
                reasons.append(f"{src.source}: host {src.host.is_a()} {src.host.GlobalId} has no body geometry")
                continue
            try:
                return src, void_on_wall(src.vertices, src.faces, host_mesh.vertices, host_mesh.faces, tris,
                                         side_cache, src.host.GlobalId)
            except VoidGeometryError as e:
                if "exterior side" in str(e):  # the same wall for every source: final
                    raise SourceError(f"{e} (wall {src.host.GlobalId})") from None
                reasons.append(f"{src.source}: {e}")
        candidates = []
    raise SourceError("; ".join(reasons))


def window_centres(ifc_file, meshes: dict[str, ElementMesh]) -> np.ndarray:
    """(W, 3) m: the centre of each IfcWindow's body box (windows without a body left out)."""
    boxes = [(m.vertices.min(axis=0) + m.vertices.max(axis=0)) / 2.0
             for w in ifc_file.by_type("IfcWindow") if (m := meshes.get(w.GlobalId)) is not None]
    return np.array(boxes) if boxes else np.zeros((0, 3))


def windows_ground_truth(ifc_file, meshes: dict[str, ElementMesh], label: str, geom_settings
                         ) -> tuple[list[WindowGT], list[SkippedWindow]]:
    """Ground truth of every IfcWindow (subtypes included) of an open ifcopenshell file.

    meshes: GlobalId -> ElementMesh (hosts already cut). label names the file in messages. Every
    window is either in the first list or in the second with a one-line reason naming it.
    """
    import ifcopenshell.util.unit  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    scale = ifcopenshell.util.unit.calculate_unit_scale(ifc_file)
    tris = TriangleCones.of(scene_triangles(meshes))
    side_cache: dict = {}
    windows: list[WindowGT] = []
    skipped: list[SkippedWindow] = []
    opening_cache: dict[str, np.ndarray] = {}
    index = OpeningIndex(ifc_file, geom_settings, centres=window_centres(ifc_file, meshes))
    walls = [(ifc_file.by_guid(m.global_id), m) for m in meshes.values() if m.kind in WALL_CLASSES
             or is_any(ifc_file.by_guid(m.global_id), WALL_CLASSES)]
    for win in ifc_file.by_type("IfcWindow"):
        name = win.Name or ""
        try:
            src, g = measure_window(win, meshes, geom_settings, index, walls, tris, scale, side_cache)
        except (NotInWall, SourceError) as e:
            cause = "not in a wall" if isinstance(e, NotInWall) else _causes(str(e))
            skipped.append(SkippedWindow(id=win.GlobalId, name=name, reason=str(e), cause=cause))
            continue
        opening = ifc_file.by_guid(src.opening_id) if src.opening_id else None
        notes = overlap_notes(g, opening, src.host, geom_settings, opening_cache) if opening else ""
        ow, oh = win.OverallWidth, win.OverallHeight
        windows.append(WindowGT(
            id=win.GlobalId, host_id=src.host.GlobalId, host_class=src.host.is_a(),
            opening_id=src.opening_id, name=name, corners_world=g.corners, normal=g.normal,
            width=g.width, height=g.height,
            ifc_overall_width=None if not ow else float(ow) * scale,
            ifc_overall_height=None if not oh else float(oh) * scale,
            shape=g.shape, outline_world=g.outline, notes=notes, source=src.source))
    return windows, skipped
