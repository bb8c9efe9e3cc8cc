"""Geometry shared by the exporters: frames, the wall fragment, photo texture coordinates.

Frames
    window frame  (W)  x along the wall, y up, z outward; origin at the void's bottom-left corner on
                       the facade; the void is [0, w] x [0, h] at z = 0 (see pipeline.types).
    camera frame  (C)  OpenCV: x right, y down, z forward. ``X_C = R @ X_W + t`` (WindowResult R, t).
    export world  (E)  the frame of model.ifc / model.obj / model.glb: upright, z up (gravity, as
                       the walls' fitted up axes give it: :func:`gravity_up`), the optical axis's
                       horizontal heading along +y, the ground plane at z = 0 and the camera above
                       the origin:
                           X_E = M @ X_C + o,  M = :func:`camera_to_world` (up), o = (0, 0, -ground_z)
                       (PlacedWindow.world and .offset). For a level camera (up = -y_C) M is
                       CAMERA_TO_EXPORT: x_E = x_C, y_E = z_C, z_E = -y_C; without a usable gravity
                       estimate the export falls back to it. The ground (:func:`storey_rows`,
                       :func:`storey_levels`, :func:`grounded`) lies SILL_HEIGHT_M (at most the
                       typical window height) below the lowest row of windows' sill, so the camera
                       stands at (0, 0, -ground_z); o = 0 before :func:`grounded` (the camera at the origin).
                       Units: metres, at the scale the pose was solved with (the window is
                       ``height_m`` tall). model.glb holds the same coordinates under a root node
                       that turns them y-up, as glTF requires (:data:`Z_UP_TO_Y_UP`).

Rows
    Windows are grouped into rows by their sill height in the export world (:func:`storey_rows`):
    sills within STOREY_TOL_FRACTION of the typical (median) window height are one row. model.ifc's
    storeys are floors made from one wall's rows (pipeline.export.floors), not every row.

Texture
    The texture is the inpainted photo, padded by replication so that every wall vertex projects
    inside it. Texture coordinates (s, t) in [0, 1] have their origin at the texture's bottom-left
    (IFC IfcTextureVertex, OBJ vt, and glTF after trimesh's flip all agree on this):
        s = (u + 0.5 + pad_left) / tex_width,   t = 1 - (v + 0.5 + pad_top) / tex_height
    for a photo pixel coordinate (u, v) under the pixel-centre convention of fenestra.conventions.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from fenestra.checks import check_K, check_rotation
from fenestra.conventions import project, vote_axis
from fenestra.pipeline.types import Unavailable, WindowResult

# Camera frame (OpenCV) -> export world of a level camera (z up, camera looking along +y); a proper rotation.
CAMERA_TO_EXPORT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
# The export world (z up) -> glTF's y-up frame: (x, y, z) -> (x, z, -y); model.glb's root node.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
GRAVITY_AGREE_DEG = 5.0  # walls whose up axes agree within this vote for one gravity direction
GRAVITY_MAX_TILT_DEG = 60.0  # a gravity estimate further than this from the camera's -y is not believed

WALL_MARGIN_M = 1.0  # wall fragment extends this far beyond the void on every side
WALL_THICKNESS_M = 0.30
WALL_CELL_FRACTION = 0.05  # facade grid cell, as a fraction of the camera distance
WALL_MAX_CELLS = 64  # ... but at most this many cells along the wall's longer side
MAX_PAD_FRACTION = 1.0  # texture padding per side, at most this fraction of the photo size
# The photo cladding: model.ifc's IfcCovering, this thick, in front of the wall's solid (its outer
# face is the photographed plane, the wall frame's z = 0); the OBJ/GLB slab is their envelope.
COVERING_THICKNESS_M = 0.01
# A typical sill height above its storey's floor: the ground plane (z = 0) lies this far below the
# lowest row of windows' sill, and each storey's floor this far below its row's sill. At most the
# typical window height (a 1:25 model's ground is not 0.9 m below its 9 cm windows).
SILL_HEIGHT_M = 0.9
STOREY_TOL_FRACTION = 0.5  # sills within this fraction of the median window height are one row


@dataclass(frozen=True)
class PlacedWindow:
    """A reconstructed window ready to export: size (m) and window-to-camera pose."""

    index: int
    width_m: float
    height_m: float
    R: np.ndarray  # (3, 3) window -> camera
    t: np.ndarray  # (3,) m
    world: np.ndarray = field(default_factory=CAMERA_TO_EXPORT.copy)  # (3, 3) camera -> export world
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))  # (3,) m, X_E = world @ X_C + offset
    partial: bool = False  # cut by the photo's border: its visible part only (never sets a storey row)

    def to_camera(self, X: np.ndarray) -> np.ndarray:
        """Window-frame points (N, 3) m -> camera frame (N, 3) m."""
        return np.asarray(X, dtype=np.float64).reshape(-1, 3) @ self.R.T + self.t

    def to_export(self, X: np.ndarray) -> np.ndarray:
        """Window-frame points (N, 3) m -> export world (N, 3) m."""
        return self.to_camera(X) @ self.world.T + self.offset

    def export_matrix(self) -> np.ndarray:
        """4x4 homogeneous window-frame -> export-world transform (the IFC object placement)."""
        T = np.eye(4)
        T[:3, :3] = self.world @ self.R
        T[:3, 3] = self.world @ self.t + self.offset
        return T

    def void_corners(self) -> np.ndarray:
        """The void's corners TL, TR, BR, BL in the window frame, (4, 3) m."""
        w, h = self.width_m, self.height_m
        return np.array([[0, h, 0], [w, h, 0], [w, 0, 0], [0, 0, 0]], dtype=np.float64)


def place(result: WindowResult) -> PlacedWindow | Unavailable:
    """A PlacedWindow, or why ``result`` cannot be exported (Unavailable, one line).

    Rejects results that failed upstream, miss pose or aspect ratio, have a rotation that is not
    proper/orthonormal, a non-positive size, or a void not entirely in front of the camera.
    """
    if not isinstance(result, WindowResult):
        return Unavailable(f"not a WindowResult: {type(result).__name__}")
    if result.failure:
        return Unavailable(f"upstream failure: {result.failure}")
    if result.R is None or result.t is None or result.aspect_ratio is None:
        return Unavailable("missing pose or aspect ratio")
    t = np.asarray(result.t, dtype=np.float64).reshape(-1)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        return Unavailable(f"bad translation t: shape {t.shape}, values {t.tolist()}")
    try:
        R = check_rotation(result.R, "R")
    except ValueError as e:
        return Unavailable(str(e))
    h = float(result.height_m)
    w = float(result.aspect_ratio) * h
    if not (np.isfinite(w) and np.isfinite(h) and w > 0 and h > 0):
        return Unavailable(f"bad window size w={w}, h={h} (aspect_ratio={result.aspect_ratio}, height_m={result.height_m})")
    pw = PlacedWindow(int(result.index), w, h, R, t, partial=getattr(result, "partial", None) is not None)
    if np.any(pw.to_camera(pw.void_corners())[:, 2] <= 1e-6):
        return Unavailable("void is not in front of the camera")
    return pw


def wall_outline(pw: PlacedWindow, margin_m: float = WALL_MARGIN_M) -> np.ndarray:
    """Outer rectangle of the wall fragment on the facade, window frame, (4, 2) m: BL, BR, TR, TL."""
    x0, y0, x1, y1 = -margin_m, -margin_m, pw.width_m + margin_m, pw.height_m + margin_m
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def _breaks(lo: float, hi: float, edges, cell_m: float) -> np.ndarray:
    """Sorted breakpoints (m) from ``lo`` to ``hi`` through every edge inside (knots closer than
    1 um are one), each interval split into cells <= cell_m."""
    knots = np.sort(np.clip(np.asarray([lo, hi, *edges], dtype=np.float64), lo, hi))
    knots = knots[np.concatenate([[True], np.diff(knots) > 1e-6])]
    knots[-1] = hi
    parts = [np.linspace(p, q, max(1, int(np.ceil((q - p) / cell_m))) + 1) for p, q in zip(knots[:-1], knots[1:])]
    return np.concatenate([parts[0]] + [q[1:] for q in parts[1:]])


def void_hole(pw: PlacedWindow) -> tuple[float, float, float, float]:
    """The void of ``pw`` in its own window frame: (x0, y0, x1, y1) m."""
    return (0.0, 0.0, pw.width_m, pw.height_m)


def wall_cell_m(pw: PlacedWindow, margin_m: float = WALL_MARGIN_M) -> float:
    """Grid cell size (m) for the wall's facade: WALL_CELL_FRACTION of the nearest corner's depth.

    Why a grid: texture coordinates are the photo projection of each vertex, which is not affine
    on a slanted plane; renderers interpolate them affinely in 3D, so one big triangle would smear
    the photo by pixels (measured: 1-4 px on a 20-degree slanted view). Cells of 5 % of the depth
    keep it under ~0.05 px (measured with tests/pipeline/test_pipeline_export.py, pyrender re-render).
    """
    depth = pw.to_camera(np.column_stack([wall_outline(pw, margin_m), np.zeros(4)]))[:, 2]
    near = depth[depth > 1e-6].min() if np.any(depth > 1e-6) else pw.height_m
    span = max(pw.width_m, pw.height_m) + 2 * margin_m
    return float(max(WALL_CELL_FRACTION * near, span / WALL_MAX_CELLS))


def wall_mesh(pw: PlacedWindow, voids=(), cut: bool = True, margin_m: float = WALL_MARGIN_M,
              thickness_m: float = WALL_THICKNESS_M, cell_m: float | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """A wall as a closed, gridded triangle mesh in the frame of ``pw``: (N, 3) m, (M, 3).

    Exterior face at z = 0, interior face at z = -thickness_m, outline = [0, w] x [0, h] of ``pw``
    + margin_m on every side. ``voids``: rectangles (x0, y0, x1, y1) m in that frame (:func:`void_hole`
    of a window, walls_plan.member_rect of a wall's windows); their edges and [0, w] x [0, h]'s are grid
    lines. ``cut=True`` leaves the voids out, with reveal faces (OBJ/GLB); ``cut=False`` gives a
    solid slab (IFC, where an IfcOpeningElement cuts each void: clean booleans on grid lines). Faces
    wind counter-clockwise seen from outside the solid; a side face stands wherever a solid grid
    cell meets a void or the outside.
    """
    cell = wall_cell_m(pw, margin_m) if cell_m is None else float(cell_m)
    voids = np.asarray(list(voids), dtype=np.float64).reshape(-1, 4)
    holes = voids if cut else voids[:0]
    m = margin_m
    xs = _breaks(-m, pw.width_m + m, [0.0, pw.width_m, *voids[:, [0, 2]].ravel()], cell)
    ys = _breaks(-m, pw.height_m + m, [0.0, pw.height_m, *voids[:, [1, 3]].ravel()], cell)
    nx, ny = len(xs), len(ys)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")  # (nx, ny)
    V = np.concatenate([np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)]) for z in (0.0, -thickness_m)])
    cx, cy = (xs[:-1] + xs[1:]) / 2, (ys[:-1] + ys[1:]) / 2
    solid = np.ones((nx - 1, ny - 1), dtype=bool)
    for x0, y0, x1, y1 in holes:
        solid &= ~(((cx > x0) & (cx < x1))[:, None] & ((cy > y0) & (cy < y1))[None, :])

    def vid(layer: int, i: int, j: int) -> int:
        return layer * nx * ny + i * ny + j

    def is_solid(i: int, j: int) -> bool:
        return 0 <= i < nx - 1 and 0 <= j < ny - 1 and bool(solid[i, j])

    quads = []  # (4 vertex ids, outward normal)
    for i, j in zip(*np.nonzero(solid)):
        for layer, n in ((0, (0, 0, 1)), (1, (0, 0, -1))):
            quads.append(([vid(layer, i, j), vid(layer, i + 1, j), vid(layer, i + 1, j + 1), vid(layer, i, j + 1)], n))

    def side(a: tuple[int, int], b: tuple[int, int], n) -> None:  # the face along grid edge a-b
        quads.append(([vid(0, *a), vid(0, *b), vid(1, *b), vid(1, *a)], n))

    for i in range(nx):  # edges along y at x = xs[i], between cells (i - 1, j) and (i, j)
        for j in range(ny - 1):
            left, right = is_solid(i - 1, j), is_solid(i, j)
            if left != right:
                side((i, j), (i, j + 1), (1, 0, 0) if left else (-1, 0, 0))
    for j in range(ny):  # edges along x at y = ys[j], between cells (i, j - 1) and (i, j)
        for i in range(nx - 1):
            below, above = is_solid(i, j - 1), is_solid(i, j)
            if below != above:
                side((i, j), (i + 1, j), (0, 1, 0) if below else (0, -1, 0))
    F = _outward(V, quads)
    used, inverse = np.unique(F, return_inverse=True)
    return V[used], inverse.reshape(-1, 3)


def _outward(V: np.ndarray, quads: list) -> np.ndarray:
    """Triangles (2Q, 3) of quads [(4 vertex ids into V (N, 3) m, outward normal (3,))]: each quad
    (a, b, c, d) as (a, b, c), (a, c, d), reversed where its winding's normal points against the
    outward one (all triangles' normals in one vectorised cross product)."""
    if not quads:
        return np.zeros((0, 3), dtype=np.int64)
    ids = np.array([q for q, _ in quads], dtype=np.int64)
    outward = np.repeat(np.array([n for _, n in quads], dtype=np.float64), 2, axis=0)
    T = np.stack([ids[:, [0, 1, 2]], ids[:, [0, 2, 3]]], axis=1).reshape(-1, 3)
    normal = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    keep = np.einsum("ij,ij->i", normal, outward) > 0
    return np.where(keep[:, None], T, T[:, ::-1])


@dataclass(frozen=True)
class TextureLayout:
    """Where the photo lies inside the padded texture image (px)."""

    photo_width: int
    photo_height: int
    pad_left: int
    pad_top: int
    pad_right: int
    pad_bottom: int

    @property
    def width(self) -> int:
        return self.photo_width + self.pad_left + self.pad_right

    @property
    def height(self) -> int:
        return self.photo_height + self.pad_top + self.pad_bottom

    def uv(self, px: np.ndarray) -> np.ndarray:
        """Photo pixel coordinates (N, 2) -> texture coordinates (N, 2), origin bottom-left, clipped to [0, 1]."""
        px = np.asarray(px, dtype=np.float64).reshape(-1, 2)
        s = (px[:, 0] + 0.5 + self.pad_left) / self.width
        t = 1.0 - (px[:, 1] + 0.5 + self.pad_top) / self.height
        return np.clip(np.column_stack([s, t]), 0.0, 1.0)

    def pixel(self, uv: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`uv` (for checks): texture coordinates (N, 2) -> photo pixels (N, 2)."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        u = uv[:, 0] * self.width - 0.5 - self.pad_left
        v = (1.0 - uv[:, 1]) * self.height - 0.5 - self.pad_top
        return np.column_stack([u, v])

    def pad(self, image: np.ndarray) -> np.ndarray:
        """The padded texture image (edge pixels replicated)."""
        return cv2.copyMakeBorder(image, self.pad_top, self.pad_bottom, self.pad_left, self.pad_right,
                                  cv2.BORDER_REPLICATE)


def facade_pixels(K: np.ndarray, pw: PlacedWindow, xy: np.ndarray) -> np.ndarray:
    """Photo pixel positions (N, 2) of window-frame facade points (x, y, 0), xy (N, 2) m."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    X = np.column_stack([xy, np.zeros(len(xy))])
    return project(check_K(K), pw.R, pw.t, X)


def texture_layout(K: np.ndarray, image_shape: tuple[int, ...], placed: list[PlacedWindow],
                   margin_m: float = WALL_MARGIN_M) -> TextureLayout:
    """Padding that keeps every wall-fragment corner's projection inside the texture.

    Padding per side is capped at MAX_PAD_FRACTION of the photo size; corners that project further
    (grazing views, corners behind the camera) get clipped texture coordinates.
    """
    H, W = int(image_shape[0]), int(image_shape[1])
    pads = np.zeros(4)  # left, top, right, bottom
    for pw in placed:
        o = wall_outline(pw, margin_m)
        depth = pw.to_camera(np.column_stack([o, np.zeros(4)]))[:, 2]
        px = facade_pixels(K, pw, o)[depth > 1e-6]
        if len(px) == 0:
            continue
        pads = np.maximum(pads, [-(px[:, 0].min() + 0.5), -(px[:, 1].min() + 0.5),
                                 px[:, 0].max() + 0.5 - W, px[:, 1].max() + 0.5 - H])
    cap = np.array([W, H, W, H]) * MAX_PAD_FRACTION
    pads = np.ceil(np.clip(pads, 0.0, cap)).astype(int)
    return TextureLayout(W, H, *map(int, pads))


def union_layout(a: TextureLayout, b: TextureLayout) -> TextureLayout:
    """The padding that holds both layouts' (same photo)."""
    return TextureLayout(a.photo_width, a.photo_height, max(a.pad_left, b.pad_left), max(a.pad_top, b.pad_top),
                         max(a.pad_right, b.pad_right), max(a.pad_bottom, b.pad_bottom))


@dataclass(frozen=True)
class Gravity:
    """The export world's vertical: ``up`` (3,) unit vector in the camera frame, or None (the
    camera-level frame, CAMERA_TO_EXPORT); ``source``: how it was found; ``windows``: how many
    windows voted for it; ``tilt_deg``: its angle from the camera's -y (0 for a level camera)."""

    up: np.ndarray | None
    source: str
    windows: int = 0

    @property
    def tilt_deg(self) -> float:
        return 0.0 if self.up is None else float(np.degrees(np.arccos(np.clip(-self.up[1], -1.0, 1.0))))

    def to_json(self) -> dict:
        return {"up_camera": None if self.up is None else self.up.tolist(), "source": self.source,
                "windows": self.windows, "tilt_deg": self.tilt_deg}


def gravity_up(placed: list[PlacedWindow], walls: dict[int, int] | None = None,
               agree_deg: float = GRAVITY_AGREE_DEG, max_tilt_deg: float = GRAVITY_MAX_TILT_DEG) -> Gravity:
    """Gravity from the windows' fitted up axes (each window's R[:, 1], the wall's vertical: its
    vertical vanishing direction, refined over all the wall's corners and façade lines).

    Each wall of ``walls`` ({window index: wall id}; a window without one is a wall of its own)
    proposes the mean up axis of its windows; the proposal that the most windows' walls agree with
    (within ``agree_deg``) wins, and the up is the window-weighted mean of the agreeing walls'. None
    (the camera-level frame) when no window is placed or the winner leans more than
    ``max_tilt_deg`` from the camera's -y (a wall fit with its axes confused, not a camera pitch).
    """
    groups: dict = {}
    for pw in placed:
        wid = None if walls is None else walls.get(pw.index)
        groups.setdefault(("wall", wid) if wid is not None else ("own", pw.index), []).append(pw.R[:, 1])
    if not groups:
        return Gravity(None, "camera level: no placed window")
    ups, weights = [], []
    for members in groups.values():
        u = np.sum(members, axis=0)
        ups.append(u / np.linalg.norm(u))
        weights.append(len(members))
    weights = np.array(weights, dtype=np.float64)
    up, inl = vote_axis(np.array(ups), weights, agree_deg)
    n = int(weights[inl].sum())
    g = Gravity(up, f"walls' up axes ({n} of {int(weights.sum())} windows agree within {agree_deg:g} deg)", n)
    if g.tilt_deg > max_tilt_deg:
        return Gravity(None, f"camera level: the walls' up axis is {g.tilt_deg:.0f} deg from the camera's vertical "
                             f"(over {max_tilt_deg:g})", 0)
    return g


def camera_to_world(up: np.ndarray | None) -> np.ndarray:
    """Camera frame -> export world rotation (3, 3): z along ``up`` (3,) camera frame (gravity's
    opposite), y the optical axis's horizontal heading, x = y x z; CAMERA_TO_EXPORT for None.
    A camera looking straight up or down has no heading: y is then the camera's -y made horizontal."""
    if up is None:
        return CAMERA_TO_EXPORT.copy()
    z = np.asarray(up, dtype=np.float64).reshape(3)
    if not (np.all(np.isfinite(z)) and np.linalg.norm(z) > 1e-9):
        raise ValueError(f"up must be a finite non-zero 3-vector, got {z.tolist()}")
    z = z / np.linalg.norm(z)
    y = np.array([0.0, 0.0, 1.0]) - z[2] * z
    if np.linalg.norm(y) < 1e-6:
        y = np.array([0.0, -1.0, 0.0]) - (-z[1]) * z
    y /= np.linalg.norm(y)
    return np.array([np.cross(y, z), y, z])


def upright(placed: list[PlacedWindow], gravity: Gravity) -> list[PlacedWindow]:
    """``placed`` in the export world of ``gravity`` (:func:`camera_to_world`), camera at the origin."""
    M = camera_to_world(gravity.up)
    return [replace(pw, world=M, offset=np.zeros(3)) for pw in placed]


def sill_z(pw: PlacedWindow) -> float:
    """The export-world height (m) of ``pw``'s sill: the mean z of its void's bottom corners."""
    return float(pw.to_export(pw.void_corners()[2:])[:, 2].mean())


def storey_rows(sills: np.ndarray, heights: np.ndarray, tol_fraction: float = STOREY_TOL_FRACTION) -> np.ndarray:
    """The storey row of each window, (N,) int, 0 = the lowest.

    sills (N,) m: the windows' sill heights in the upright export world (:func:`sill_z`);
    heights (N,) m: their void heights. tol = tol_fraction * median(heights): taken by rising sill,
    a window joins the current row when its sill is at most tol above the row's lowest sill, and
    starts the next row otherwise (so one row spans at most tol; rows are numbered bottom-up).
    ValueError naming the bad value for mismatched shapes, non-finite sills, non-positive heights
    or tol_fraction.
    """
    sills = np.asarray(sills, dtype=np.float64)
    heights = np.asarray(heights, dtype=np.float64)
    if sills.ndim != 1 or heights.shape != sills.shape:
        raise ValueError(f"sills and heights must be (N,) arrays of one length, got shapes {sills.shape} and "
                         f"{heights.shape}")
    if not np.all(np.isfinite(sills)):
        raise ValueError(f"sills must be finite, got {sills.tolist()}")
    if not np.all(np.isfinite(heights) & (heights > 0)):
        raise ValueError(f"heights must be finite and positive, got {heights.tolist()}")
    if not (np.isfinite(tol_fraction) and tol_fraction > 0):
        raise ValueError(f"tol_fraction must be finite and positive, got {tol_fraction!r}")
    rows = np.zeros(len(sills), dtype=np.int64)
    if len(sills) == 0:
        return rows
    tol = float(tol_fraction) * float(np.median(heights))
    row, base = 0, None
    for i in np.argsort(sills, kind="stable"):
        if base is None:
            base = sills[i]
        elif sills[i] - base > tol:
            row, base = row + 1, sills[i]
        rows[i] = row
    return rows


@dataclass(frozen=True)
class StoreyLevels:
    """The storey rows of the placed windows: ``row_of`` {window index: row (0 = lowest)}; ``sills_m``
    each row's sill (median of its windows' :func:`sill_z`, export world, m); ``sill_height_m`` the
    offset from a storey's floor to its row's sill (SILL_HEIGHT_M, at most the median window height);
    ``tol_m`` the row tolerance used (:func:`storey_rows`)."""

    row_of: dict
    sills_m: tuple
    sill_height_m: float
    tol_m: float

    @property
    def elevations_m(self) -> tuple:
        """Each storey's floor height (m, export world): its row's sill minus ``sill_height_m``."""
        return tuple(s - self.sill_height_m for s in self.sills_m)

    @property
    def ground_z_m(self) -> float:
        """The ground plane's height in the world the levels were taken in (0 once :func:`grounded`)."""
        return self.elevations_m[0] if self.sills_m else 0.0


def storey_levels(placed: list[PlacedWindow], sill_height_m: float = SILL_HEIGHT_M,
                  tol_fraction: float = STOREY_TOL_FRACTION) -> StoreyLevels:
    """The storey rows (:func:`storey_rows`) and levels of ``placed`` in their export world."""
    if not (np.isfinite(sill_height_m) and sill_height_m >= 0):
        raise ValueError(f"sill_height_m must be finite and non-negative, got {sill_height_m!r}")
    if not placed:
        return StoreyLevels({}, (), float(sill_height_m), 0.0)
    whole = [pw for pw in placed if not pw.partial] or list(placed)  # a cut window's sill may be the photo's edge
    sills = np.array([sill_z(pw) for pw in whole])
    heights = np.array([pw.height_m for pw in whole])
    rows = storey_rows(sills, heights, tol_fraction)
    typical = float(np.median(heights))
    row_sills = tuple(float(np.median(sills[rows == r])) for r in range(int(rows.max()) + 1))
    row_of = {pw.index: int(r) for pw, r in zip(whole, rows)}
    row_of.update({pw.index: partial_row(pw, row_sills, typical) for pw in placed if pw.index not in row_of})
    return StoreyLevels(row_of, row_sills, float(min(sill_height_m, typical)), float(tol_fraction) * typical)


def partial_row(pw: PlacedWindow, row_sills: tuple, typical_m: float) -> int:
    """The row of a partial window (cut by the photo's border, so its sill or top may be the
    photo's edge): the row whose window band [sill, sill + typical_m] (m, export world) has its
    middle nearest the visible part's middle."""
    mid = sill_z(pw) + 0.5 * pw.height_m
    return int(np.argmin([abs(mid - (s + 0.5 * typical_m)) for s in row_sills]))


def grounded(placed: list[PlacedWindow], levels: StoreyLevels) -> tuple[list[PlacedWindow], StoreyLevels]:
    """(``placed``, ``levels``) with the export world's origin moved down onto ``levels``' ground
    plane: z = 0 there, storey 0's elevation 0, the rows unchanged."""
    dz = levels.ground_z_m
    shift = np.array([0.0, 0.0, -dz])
    return ([replace(pw, offset=pw.offset + shift) for pw in placed],
            replace(levels, sills_m=tuple(s - dz for s in levels.sills_m)))
