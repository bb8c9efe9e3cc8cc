"""Procedural daylight materials (numpy textures) shared by the raster and path-traced backends.

A scene's meshes are grouped by material (IFC class + colour), each group gets a
:class:`MaterialSpec` chosen from a seeded palette, and planar texture coordinates in metres.
Textures are small tileable uint8 images made with numpy (value noise, bricks, roof tiles).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fenestra.renders.base import LOOKS  # RenderSettings.look: which palette/lighting distribution is drawn
from fenestra.scenes.model import ElementMesh, Scene

TEX = 256  # texture size, px


@dataclass(frozen=True, eq=False)
class MaterialSpec:
    """How a group of faces looks. texture: (TEX, TEX, 3) uint8 sRGB-ish or None; tile_m: metres
    that one texture repeat spans; rgb: base colour in [0, 1] (multiplies the texture)."""

    name: str
    kind: str  # "diffuse" | "glass" | "metal"
    rgb: tuple[float, float, float]
    texture: np.ndarray | None = None
    tile_m: float = 1.0
    roughness: float = 0.9
    metallic: float = 0.0


@dataclass(frozen=True, eq=False)
class MaterialGroup:
    """Triangles sharing one material. vertices (N, 3) m (unshared per face), faces (M, 3),
    uvs (N, 2) in texture repeats; element_ids: GlobalIds of the merged elements;
    face_element: (M,) int, each face's index into element_ids."""

    material: MaterialSpec
    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    element_ids: tuple[str, ...]
    is_window: bool
    face_element: np.ndarray | None = None


@dataclass(frozen=True)
class Look:
    """The seeded appearance choices of one renderer (palette, sun, sky): of a whole render set with
    ``RenderSettings.look_per = "set"``, of one view with ``"view"`` (renders.dataset.view_settings).
    The fields after sky_horizon default to what the "classic" look always used (see :func:`sample_look`)."""

    wall_style: str  # "plaster" | "brick" | "stone" (stone: "wide" only)
    wall_rgb: tuple[float, float, float]
    frame_rgb: tuple[float, float, float]
    roof_rgb: tuple[float, float, float]
    ground_style: str  # "grass" | "paving"
    sun_azimuth_deg: float
    sun_elevation_deg: float
    sun_intensity: float
    ambient: float
    sky_zenith: tuple[float, float, float]
    sky_horizon: tuple[float, float, float]
    weather: str = "clear"  # "clear" | "low_sun" | "overcast"
    sun_tint: tuple[float, float, float] = (1.0, 1.0, 1.0)  # multiplies each backend's sun colour
    glass_reflect: float = 1.0  # scale of the sky reflection in the glass texture
    glass_interior: tuple[float, float, float] = (0.10, 0.12, 0.14)  # the room seen through it
    glass_tint: tuple[float, float, float] = (1.0, 1.0, 1.0)


PLASTER_RGB = [(0.93, 0.91, 0.86), (0.95, 0.90, 0.76), (0.86, 0.86, 0.84), (0.92, 0.84, 0.74), (0.80, 0.85, 0.86)]
FRAME_RGB = [(0.95, 0.95, 0.95), (0.22, 0.23, 0.25), (0.40, 0.26, 0.16), (0.55, 0.57, 0.58)]
ROOF_RGB = [(0.55, 0.20, 0.14), (0.25, 0.25, 0.27), (0.45, 0.28, 0.20)]
# "wide": St Petersburg-like plaster (ochre, pink, mint, pale blue, terracotta, grey, white, yellow,
# lilac), more frame and roof colours, glass tints, warm/neutral/cool skies
WIDE_WALL_RGB = [(0.85, 0.66, 0.35), (0.88, 0.62, 0.60), (0.62, 0.80, 0.68), (0.62, 0.75, 0.86),
                 (0.72, 0.38, 0.26), (0.62, 0.62, 0.62), (0.94, 0.93, 0.90), (0.93, 0.80, 0.45),
                 (0.74, 0.66, 0.80)]
WIDE_FRAME_RGB = FRAME_RGB + [(0.08, 0.08, 0.09), (0.30, 0.18, 0.10), (0.15, 0.27, 0.18),
                              (0.78, 0.72, 0.60), (0.20, 0.26, 0.42), (0.55, 0.15, 0.12)]
WIDE_ROOF_RGB = ROOF_RGB + [(0.35, 0.47, 0.40), (0.60, 0.61, 0.63), (0.20, 0.30, 0.22)]
GLASS_TINTS = [(1.0, 1.0, 1.0), (0.85, 0.95, 1.0), (0.90, 1.0, 0.92), (1.0, 0.93, 0.82), (0.78, 0.78, 0.80)]
SKY_HORIZONS = {"warm": (0.96, 0.86, 0.74), "neutral": (0.82, 0.88, 0.95), "cool": (0.74, 0.84, 0.98)}
SUN_TINTS = {"warm": (1.0, 0.90, 0.75), "neutral": (1.0, 1.0, 1.0), "cool": (0.92, 0.96, 1.0)}


def sample_look(rng: np.random.Generator, style: str = "classic") -> Look:
    """Draw a palette, sun and sky from ``rng``: ``style`` one of LOOKS. "classic" makes exactly
    the draws it always made (dataset folders and renders unchanged); "wide" see sample_wide_look."""
    if style == "wide":
        return sample_wide_look(rng)
    if style != "classic":
        raise ValueError(f"look must be one of {LOOKS}, got {style!r}")
    pick = lambda opts: opts[int(rng.integers(len(opts)))]  # noqa: E731
    return Look(wall_style="brick" if rng.random() < 0.35 else "plaster", wall_rgb=pick(PLASTER_RGB),
                frame_rgb=pick(FRAME_RGB), roof_rgb=pick(ROOF_RGB),
                ground_style="grass" if rng.random() < 0.7 else "paving",
                sun_azimuth_deg=float(rng.uniform(0, 360)), sun_elevation_deg=float(rng.uniform(20, 60)),
                sun_intensity=float(rng.uniform(2.5, 3.5)), ambient=float(rng.uniform(0.35, 0.5)),
                sky_zenith=(float(rng.uniform(0.25, 0.4)), float(rng.uniform(0.45, 0.6)), float(rng.uniform(0.8, 0.95))),
                sky_horizon=(0.82, 0.88, 0.95))


def _jitter(rng: np.random.Generator, rgb, lo: float, hi: float, spread: float = 0.04) -> tuple:
    """rgb scaled by a uniform brightness in [lo, hi] plus per-channel noise, clipped to [0, 1]."""
    c = np.asarray(rgb) * rng.uniform(lo, hi) + rng.uniform(-spread, spread, 3)
    return tuple(float(x) for x in np.clip(c, 0.0, 1.0))


def sample_wide_look(rng: np.random.Generator) -> Look:
    """The "wide" look: walls plaster (55 %) / brick (25 %) / rusticated stone (20 %) in saturated
    or pale colours, darker or lighter; more frame and roof colours; glass of varied reflection,
    interior brightness and tint; weather clear (sun 20-60 deg), low sun (8-20 deg) or overcast
    (weak sun, strong ambient, grey sky), each under a warm, neutral or cool sky."""
    pick = lambda opts: opts[int(rng.integers(len(opts)))]  # noqa: E731
    u = rng.random()
    wall_style = "plaster" if u < 0.55 else "brick" if u < 0.8 else "stone"
    wall_rgb = _jitter(rng, pick(WIDE_WALL_RGB), 0.7, 1.1)
    frame_rgb = _jitter(rng, pick(WIDE_FRAME_RGB), 0.85, 1.1, 0.02)
    roof_rgb = _jitter(rng, pick(WIDE_ROOF_RGB), 0.8, 1.15, 0.02)
    ground_style = "grass" if rng.random() < 0.5 else "paving"
    weather = pick(("clear", "clear", "low_sun", "overcast"))
    tone = pick(tuple(SKY_HORIZONS))
    azimuth = float(rng.uniform(0, 360))
    if weather == "overcast":
        elevation, intensity, ambient = float(rng.uniform(30, 70)), float(rng.uniform(0.2, 0.8)), float(rng.uniform(0.8, 1.0))
        g = float(rng.uniform(0.6, 0.85))
        zenith = _jitter(rng, (g, g, g * 1.03), 1.0, 1.0, 0.02)
        horizon = _jitter(rng, SKY_HORIZONS[tone], 0.85, 0.95, 0.01)
    else:
        elevation = float(rng.uniform(8, 20) if weather == "low_sun" else rng.uniform(20, 60))
        intensity = float(rng.uniform(2.5, 3.8))
        ambient = float(rng.uniform(0.35, 0.55) if weather == "low_sun" else rng.uniform(0.25, 0.5))
        zenith = (float(rng.uniform(0.2, 0.4)), float(rng.uniform(0.4, 0.6)), float(rng.uniform(0.75, 0.95)))
        horizon = SKY_HORIZONS[tone]
    sun_tint = SUN_TINTS["warm"] if weather == "low_sun" else SUN_TINTS[tone]
    return Look(wall_style=wall_style, wall_rgb=wall_rgb, frame_rgb=frame_rgb, roof_rgb=roof_rgb,
                ground_style=ground_style, sun_azimuth_deg=azimuth, sun_elevation_deg=elevation,
                sun_intensity=intensity, ambient=ambient, sky_zenith=zenith, sky_horizon=horizon,
                weather=weather, sun_tint=sun_tint, glass_reflect=float(rng.uniform(0.5, 1.6)),
                glass_interior=_jitter(rng, (0.10, 0.12, 0.14), 0.4, 2.5, 0.0), glass_tint=pick(GLASS_TINTS))


# ---------------------------------------------------------------------------------- textures
def value_noise(rng: np.random.Generator, size: int = TEX, octaves: int = 5, base: int = 4) -> np.ndarray:
    """Tileable fractal value noise, (size, size) float32 roughly in [-1, 1]."""
    out = np.zeros((size, size), np.float32)
    amp, total = 1.0, 0.0
    for o in range(octaves):
        n = base * 2 ** o
        g = rng.uniform(-1, 1, (n, n)).astype(np.float32)
        big = cv2.resize(np.tile(g, (3, 3)), (3 * size, 3 * size), interpolation=cv2.INTER_CUBIC)
        out += amp * big[size:2 * size, size:2 * size]
        total += amp
        amp *= 0.5
    return out / total


def _to_u8(img: np.ndarray) -> np.ndarray:
    return np.clip(img * 255.0, 0, 255).astype(np.uint8)


def plaster_texture(rng, rgb) -> np.ndarray:
    n = value_noise(rng)
    fine = value_noise(rng, base=32, octaves=2)
    shade = 1.0 + 0.05 * n + 0.035 * fine
    return _to_u8(np.asarray(rgb, np.float32)[None, None, :] * shade[..., None])


def brick_texture(rng, courses: int = 12, per_row: int = 4) -> np.ndarray:
    """Running-bond bricks with mortar; one tile = ``courses`` courses x ``per_row`` bricks."""
    img = np.zeros((TEX, TEX, 3), np.float32)
    img[:] = (0.72, 0.70, 0.66)  # mortar
    ch = TEX / courses
    bw = TEX / per_row
    mortar = max(1, int(round(ch * 0.12)))
    base = np.array([rng.uniform(0.5, 0.7), rng.uniform(0.22, 0.32), rng.uniform(0.15, 0.22)], np.float32)
    for r in range(courses):
        y0, y1 = int(round(r * ch)) + mortar, int(round((r + 1) * ch))
        off = 0.5 * bw * (r % 2)
        for b in range(-1, per_row + 1):
            x0 = int(round(b * bw + off)) + mortar
            x1 = int(round((b + 1) * bw + off))
            col = base * rng.uniform(0.8, 1.15) + rng.uniform(-0.03, 0.03, 3)
            xs = np.arange(x0, x1) % TEX
            img[y0:y1][:, xs] = col
    n = value_noise(rng, base=32, octaves=2)
    return _to_u8(img * (1.0 + 0.08 * n[..., None]))


def roof_texture(rng, rgb, rows: int = 8) -> np.ndarray:
    v = (np.arange(TEX) % (TEX // rows)) / (TEX // rows)
    shade = 0.75 + 0.35 * v  # each tile row darker at its top (overlap shadow)
    n = value_noise(rng, base=16, octaves=3)
    img = np.asarray(rgb, np.float32)[None, None, :] * (shade[:, None] * (1 + 0.1 * n))[..., None]
    return _to_u8(img)


def ground_texture(rng, style: str) -> np.ndarray:
    n = value_noise(rng, base=8)
    fine = value_noise(rng, base=64, octaves=2)
    if style == "grass":
        rgb = np.array([0.30, 0.45, 0.18], np.float32)
        return _to_u8(rgb * (1 + 0.25 * n + 0.2 * fine)[..., None])
    rgb = np.array([0.55, 0.54, 0.52], np.float32)
    img = rgb * (1 + 0.08 * n + 0.06 * fine)[..., None]
    img[(np.arange(TEX) % 64) < 2] *= 0.7  # paving joints
    img[:, (np.arange(TEX) % 64) < 2] *= 0.7
    return _to_u8(img)


def ashlar_texture(rng, rgb, courses: int = 4, per_row: int = 2) -> np.ndarray:
    """Rusticated ashlar: stone blocks in half bond with deep dark joints and bevelled edges (lit
    top, shaded bottom); one tile = ``courses`` courses x ``per_row`` blocks, tileable."""
    ch, bw = TEX // courses, TEX // per_row
    y, x = np.mgrid[0:TEX, 0:TEX]
    row = y // ch
    xs = (x + (row % 2) * (bw // 2)) % TEX
    col = xs // bw
    fy, fx = (y % ch) / ch, (xs % bw) / bw  # position inside the block, 0..1
    block = rng.uniform(0.86, 1.08, (courses, per_row)).astype(np.float32)[row, col]
    joint = 0.035
    edge = np.minimum(np.minimum(fx, 1 - fx) * bw / ch, np.minimum(fy, 1 - fy))  # in course heights
    bevel = np.clip((edge - joint) / 0.08, 0.0, 1.0)
    shade = np.where(fy < 0.5, 1.12, 0.78)  # top bevel lit, bottom bevel in shade
    f = np.where(edge < joint, 0.45, bevel + (1 - bevel) * shade) * block
    n = value_noise(rng, base=16, octaves=4)
    return _to_u8(np.asarray(rgb, np.float32)[None, None, :] * (f * (1 + 0.07 * n))[..., None])


def glass_texture(horizon, zenith, reflect: float = 1.0, interior=(0.10, 0.12, 0.14),
                  tint=(1.0, 1.0, 1.0)) -> np.ndarray:
    """Fake sky reflection: brighter at the top of each pane, dark below (the room behind).
    reflect scales the reflection, interior is the room's colour, tint multiplies the pane; the
    defaults give the classic glass exactly."""
    v = np.linspace(1.0, 0.0, TEX)[:, None]
    sky = (np.asarray(horizon, np.float32) * 0.45 + np.asarray(zenith, np.float32) * 0.15) * np.float32(reflect)
    dark = np.asarray(interior, np.float32)
    img = (dark + (sky - dark) * (v ** 1.5)[..., None]) * np.asarray(tint, np.float32)
    return _to_u8(np.broadcast_to(img, (TEX, TEX, 3)).copy())


# ---------------------------------------------------------------------------------- assignment
WALL_CLASSES = ("IfcWall", "IfcCurtainWall", "IfcPlate")  # compared with ElementMesh.kind (subclasses as parents)
ROOF_CLASSES = ("IfcRoof", "IfcSlab", "IfcCovering")


def material_key(m: ElementMesh) -> str:
    """Which material group a mesh falls into (IFC class family + transparency). The class is the
    mesh's ``kind``: a StandardCase subclass (IfcWindowStandardCase, IfcWallStandardCase) as its parent."""
    kind = m.kind
    if kind == "IfcSite":
        return "ground"
    if m.rgba[3] < 0.9:
        return "glass"
    if kind == "IfcWindow":
        return "frame"
    if kind in WALL_CLASSES:
        return "wall"
    if kind in ROOF_CLASSES:
        return "roof"
    if kind == "IfcDoor":
        return "door"
    return "other:" + "%.2f,%.2f,%.2f" % tuple(m.rgba[:3])


def make_material(key: str, look: Look, rng: np.random.Generator) -> MaterialSpec:
    if key == "wall":
        if look.wall_style == "brick":
            return MaterialSpec("brick", "diffuse", (1, 1, 1), brick_texture(rng), tile_m=1.0)
        if look.wall_style == "stone":
            return MaterialSpec("stone", "diffuse", (1, 1, 1), ashlar_texture(rng, look.wall_rgb), tile_m=2.0)
        return MaterialSpec("plaster", "diffuse", (1, 1, 1), plaster_texture(rng, look.wall_rgb), tile_m=2.0)
    if key == "roof":
        return MaterialSpec("roof", "diffuse", (1, 1, 1), roof_texture(rng, look.roof_rgb), tile_m=2.0)
    if key == "frame":
        return MaterialSpec("frame", "diffuse", look.frame_rgb, None, roughness=0.5)
    if key == "glass":
        return MaterialSpec("glass", "glass", (1, 1, 1), glass_texture(look.sky_horizon, look.sky_zenith, look.glass_reflect,
                                                                  look.glass_interior, look.glass_tint),
                            tile_m=1.5, roughness=0.1, metallic=0.3)
    if key == "door":
        return MaterialSpec("door", "diffuse", (0.45, 0.30, 0.18), None, roughness=0.6)
    if key == "ground":
        return MaterialSpec("ground", "diffuse", (1, 1, 1), ground_texture(rng, look.ground_style), tile_m=3.0)
    rgb = tuple(float(x) for x in key.split(":")[1].split(","))
    return MaterialSpec(key, "diffuse", rgb, None, roughness=0.8)


def planar_metres(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unshare vertices and give each face planar coordinates along its dominant axis (z is always v).

    vertices (N, 3) m, faces (M, 3) -> (3M, 3) vertices, (M, 3) faces, (3M, 2) (u, v) in metres.
    """
    tri = vertices[faces]  # (M, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    axis = np.argmax(np.abs(n), axis=1)
    u = np.where(axis[:, None] == 0, tri[..., 1], tri[..., 0])  # x-facing: u = y
    v = np.where(axis[:, None] == 2, tri[..., 1], tri[..., 2])  # z-facing: v = y
    return tri.reshape(-1, 3), np.arange(3 * len(faces)).reshape(-1, 3), np.stack([u, -v], axis=-1).reshape(-1, 2)


def ground_z(scene: Scene) -> float:
    """Height of the ground plane: the lowest window-hosting wall's base, else the scene minimum."""
    lo = scene.bounds()[0, 2]
    hosts = {w.host_id for w in scene.windows}
    zs = [m.vertices[:, 2].min() for m in scene.meshes if m.global_id in hosts]
    return float(min(zs)) if zs else float(lo)


def glass_faces(vertices: np.ndarray, faces: np.ndarray, normal: np.ndarray, max_thickness_m: float = 0.04,
                min_area_m2: float = 0.03) -> np.ndarray:
    """(M,) bool: faces of a window element that belong to glass panes.

    A pane is a connected component thinner than ``max_thickness_m`` along the window normal
    with at least ``min_area_m2`` of faces facing along it; everything else is frame.
    """
    import trimesh  # noqa: PLC0415 (trimesh: imported when first used, not at the package's import)

    tm = trimesh.Trimesh(vertices, faces, process=False)
    tm.merge_vertices()
    labels = trimesh.graph.connected_component_labels(tm.face_adjacency, node_count=len(faces))
    fn = face_normals(np.asarray(tm.vertices), np.asarray(tm.faces))
    along = np.abs(fn @ normal) > 0.9
    area = tm.area_faces
    depth = np.asarray(tm.vertices) @ normal
    out = np.zeros(len(faces), bool)
    for lab in np.unique(labels):
        sel = labels == lab
        d = depth[np.asarray(tm.faces)[sel].ravel()]
        if d.max() - d.min() < max_thickness_m and area[sel & along].sum() >= min_area_m2:
            out |= sel
    return out


def glass_split(scene: Scene) -> dict[str, np.ndarray]:
    """{GlobalId: (M,) bool :func:`glass_faces`} of every window mesh of the scene (an IfcWindow
    with a window's ground truth): which of its faces are glass."""
    normals = {w.id: w.normal for w in scene.windows}
    return {m.global_id: glass_faces(m.vertices, m.faces, normals[m.global_id])
            for m in scene.meshes if m.kind == "IfcWindow" and m.global_id in normals}


class SceneGeometry:
    """The look-free part of :func:`group_scene` for one scene, computed once and shared by the
    renderers of its looks (renders.backends.make_renderer's ``like``): the window meshes' glass
    faces (:func:`glass_split`), each mesh part's unshared vertices and planar coordinates in metres
    (:func:`planar_metres`, kept as first asked for, read-only), the scene's bounds and ground height.
    An explicit cache, one per scene; not thread-safe."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.glass = glass_split(scene)
        self.bounds = scene.bounds()
        self.ground_z = ground_z(scene)
        self._planar: dict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def planar_uvs(self, part: tuple, mesh: ElementMesh, tile_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`planar_metres` of ``mesh``, the scene's mesh part ``part`` (its index in
        ``scene.meshes`` and which faces: "all", "glass", "frame"), the coordinates in texture
        repeats of ``tile_m`` metres: (3M, 3) vertices, (M, 3) faces, (3M, 2) uvs (the metres kept)."""
        if part not in self._planar:
            out = planar_metres(mesh.vertices, mesh.faces)
            for a in out:
                a.flags.writeable = False
            self._planar[part] = out
        tri, faces, uv_m = self._planar[part]
        return tri, faces, uv_m / tile_m


def group_scene(scene: Scene, look: Look, rng: np.random.Generator, geometry: SceneGeometry | None = None,
                ground_size_m: float = 400.0) -> list[MaterialGroup]:
    """Merge the scene's meshes by material; window meshes stay per window element (is_window),
    split into glass and frame. geometry: the scene's :class:`SceneGeometry` (made when None)."""
    geometry = SceneGeometry(scene) if geometry is None else geometry
    buckets: dict[str, list[tuple[tuple, ElementMesh]]] = {}
    for i, m in enumerate(scene.meshes):
        key = material_key(m)
        if m.kind == "IfcWindow" and m.global_id in geometry.glass:
            pane = geometry.glass[m.global_id]
            for k, sel in (("glass", pane), ("frame", ~pane)):
                if sel.any():
                    buckets.setdefault(k, []).append(((i, k), ElementMesh(
                        m.global_id, m.ifc_class, m.name, m.vertices, m.faces[sel], m.rgba, base_class=m.base_class)))
            continue
        buckets.setdefault(key, []).append(((i, "all"), m))
    groups = []
    for key in sorted(buckets):
        mat = make_material(key, look, rng)
        V, F, UV, ids, FE = [], [], [], [], []
        off = 0
        for part, m in buckets[key]:
            v, f, uv = geometry.planar_uvs(part, m, mat.tile_m)
            V.append(v); F.append(f + off); UV.append(uv); FE.append(np.full(len(f), len(ids)))  # noqa: E702
            ids.append(m.global_id)
            off += len(v)
        groups.append(MaterialGroup(mat, np.concatenate(V), np.concatenate(F), np.concatenate(UV), tuple(ids),
                                    is_window=key in ("frame", "glass"), face_element=np.concatenate(FE)))
    c = geometry.bounds.mean(axis=0)
    z, h = geometry.ground_z - 0.002, ground_size_m / 2
    gv = np.array([[c[0] - h, c[1] - h, z], [c[0] + h, c[1] - h, z], [c[0] + h, c[1] + h, z], [c[0] - h, c[1] + h, z]])
    gmat = make_material("ground", look, rng)
    groups.append(MaterialGroup(gmat, gv, np.array([[0, 1, 2], [0, 2, 3]]), gv[:, :2] / gmat.tile_m, ("ground",), False,
                                np.zeros(2, int)))
    return groups


def sky_colour(directions: np.ndarray, look: Look) -> np.ndarray:
    """Sky radiance (..., 3) in [0, 1] for unit world directions (..., 3): horizon -> zenith blend."""
    el = np.clip(directions[..., 2], 0.0, 1.0)
    w = (el ** 0.6)[..., None]
    return (1 - w) * np.asarray(look.sky_horizon) + w * np.asarray(look.sky_zenith)


def sun_direction(look: Look) -> np.ndarray:
    """Unit world vector from the scene towards the sun."""
    az, el = np.radians(look.sun_azimuth_deg), np.radians(look.sun_elevation_deg)
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


SUN_RGB = np.array([1.0, 0.96, 0.88])


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(M, 3) unit normals of triangles (right-handed winding: IFC solids are wound outward)."""
    n = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def lighting(normals: np.ndarray, look: Look) -> tuple[np.ndarray, np.ndarray]:
    """Baked daylight per face: colour multiplier (M, 3) in [0, 1] and shadow ratio (M,).

    multiplier = sky ambient (brighter for upward faces) + sun * max(0, n . sun), scaled so a
    face square to the sun is ~1; ratio = what is left in shadow (ambient / total), 1 if unlit.
    """
    s = sun_direction(look)
    amb = look.ambient * (0.8 + 0.2 * normals[:, 2])
    sun = look.sun_intensity / 3.5 * np.clip(normals @ s, 0.0, None)
    total = amb + sun
    norm = look.ambient + look.sun_intensity / 3.5
    sky_tint = np.asarray(look.sky_horizon) / np.max(look.sky_horizon)
    mult = (amb[:, None] * sky_tint + sun[:, None] * (SUN_RGB * np.asarray(look.sun_tint))) / norm
    return np.clip(mult, 0.0, 1.0), amb / np.maximum(total, 1e-9)
