"""OBJ + MTL and GLB export of the same model as model.ifc (few IFC viewers show textures).

Per fitted wall: one slab with every window's void cut out (photo-textured, UVs as in the IFC; a
window without a wall: a fragment of its own), and per window the catalogue window's frame and glass.
The slab is model.ifc's wall envelope: its photo cladding (IfcCovering, COVERING_THICKNESS_M, outer
face on the photographed plane) and wall solid (WALL_THICKNESS_M) behind it, as one.
Coordinates in the export world of fenestra/pipeline/export/geometry.py (metres, z up: upright, the
ground at z = 0, the camera above the origin), the very coordinates of model.ifc's placements; model.glb
holds them under a root node that turns them y-up (glTF's convention).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fenestra.conventions import LIMITS
from fenestra.pipeline.catalogue import WindowStyle, get_style, window_mesh
from fenestra.pipeline.export.geometry import (COVERING_THICKNESS_M, WALL_MARGIN_M, WALL_THICKNESS_M, Z_UP_TO_Y_UP,
                                               PlacedWindow, TextureLayout, facade_pixels, wall_mesh)
from fenestra.pipeline.export.walls_plan import facade_walls
from PIL import Image


# A GLB's texture is at most this many px along its longer side: glTF viewers (WebGL) commonly
# refuse larger textures, and a 100 Mpx photo's texture would hold gigabytes while written.
GLB_MAX_TEXTURE_PX = 8192
GLB_ROOT_NODE = "z_up_to_y_up"  # the GLB's root node: the export world (z up) turned y-up for glTF


@dataclass(frozen=True)
class MeshPart:
    """One exported object: vertices (N, 3) m in the export world, faces (M, 3), uv (N, 2) or None."""

    name: str
    material: str
    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray | None


def model_parts(K: np.ndarray, placed: list[PlacedWindow], layout: TextureLayout,
                style: str | WindowStyle = "casement-white", margin_m: float = WALL_MARGIN_M,
                thickness_m: float = WALL_THICKNESS_M, walls: dict[int, int] | None = None) -> list[MeshPart]:
    """Wall, frame and glass parts, in the export world: one wall per façade plane of ``walls``
    ({window index: wall id}; walls_plan.facade_walls, as model.ifc's IfcWalls: ``wall_w<id>``) with
    a hole per window, and a wall fragment of its own (``wall_<index>``) for a window without one;
    each window's frame and glass (in its wall's axes).
    A wall slab is thickness_m + COVERING_THICKNESS_M thick (model.ifc's wall and photo cladding)."""
    style = get_style(style)
    parts = []
    for wall in facade_walls(placed, walls, K, (layout.photo_width, layout.photo_height), margin_m):
        V, F = wall_mesh(wall.frame, wall.holes, True, wall.margin_m, thickness_m + COVERING_THICKNESS_M)
        uv = layout.uv(facade_pixels(K, wall.frame, V[:, :2]))
        parts.append(MeshPart(f"wall_{wall.id}" if wall.own else f"wall_w{wall.id}", "photo",
                              wall.frame.to_export(V), F, uv))
        for pw in wall.members:
            mesh = window_mesh(style, pw.width_m, pw.height_m)
            for part in ("frame", "glass"):
                v, f = mesh.select(part)
                parts.append(MeshPart(f"{part}_{pw.index}", part, pw.to_export(v), f, None))
    return parts


def _materials(style: WindowStyle, texture_file: str) -> str:
    fr, gl = style.frame_rgb, style.glass_rgb
    return "\n".join([
        "# Fenestra materials",
        "newmtl photo", "Ka 1 1 1", "Kd 1 1 1", "Ks 0 0 0", "illum 1", f"map_Kd {texture_file}", "",
        "newmtl frame", f"Kd {fr[0]:.4f} {fr[1]:.4f} {fr[2]:.4f}", "Ks 0.1 0.1 0.1", "illum 2", "",
        "newmtl glass", f"Kd {gl[0]:.4f} {gl[1]:.4f} {gl[2]:.4f}", "Ks 0.6 0.6 0.6", "Ns 200",
        f"d {style.glass_alpha:.3f}", "illum 2", "",
    ])


def write_obj(obj_path: str | Path, parts: list[MeshPart], style: str | WindowStyle = "casement-white",
              texture_file: str = "texture.png") -> tuple[Path, Path]:
    """Write ``model.obj`` and its ``model.mtl`` (same stem); return both paths."""
    obj_path = Path(obj_path)
    mtl_path = obj_path.with_suffix(".mtl")
    mtl_path.write_text(_materials(get_style(style), texture_file))
    lines = ["# Fenestra reconstruction: metres, z up (upright), ground at z = 0, camera above the origin looking "
             "along +y (model.ifc's coordinates)",
             f"mtllib {mtl_path.name}"]
    v_off = vt_off = 0
    for p in parts:
        lines += [f"o {p.name}", f"usemtl {p.material}"]
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in p.vertices]
        if p.uv is not None:
            lines += [f"vt {s:.6f} {t:.6f}" for s, t in p.uv]
            lines += [f"f {a + v_off + 1}/{a + vt_off + 1} {b + v_off + 1}/{b + vt_off + 1} "
                      f"{c + v_off + 1}/{c + vt_off + 1}" for a, b, c in p.faces]
            vt_off += len(p.uv)
        else:
            lines += [f"f {a + v_off + 1} {b + v_off + 1} {c + v_off + 1}" for a, b, c in p.faces]
        v_off += len(p.vertices)
    obj_path.write_text("\n".join(lines) + "\n")
    return obj_path, mtl_path


def glb_texture(texture_rgb: np.ndarray, max_px: int = GLB_MAX_TEXTURE_PX) -> np.ndarray:
    """The texture (H, W, 3) uint8 as the GLB holds it: area-downscaled to at most ``max_px`` along
    its longer side (texture coordinates are fractions of the image: unchanged), else as it is."""
    h, w = texture_rgb.shape[:2]
    if max(h, w) <= max_px:
        return texture_rgb
    k = max_px / max(h, w)
    return cv2.resize(texture_rgb, (max(1, round(w * k)), max(1, round(h * k))), interpolation=cv2.INTER_AREA)


def write_glb(glb_path: str | Path, parts: list[MeshPart], texture_rgb: np.ndarray,
              style: str | WindowStyle = "casement-white") -> Path:
    """Write a textured binary glTF. ``texture_rgb``: (H, W, 3) uint8 RGB (the padded texture; the
    GLB holds :func:`glb_texture` of it). The parts' vertices (export world, z up) are stored as they
    are, under one root node (GLB_ROOT_NODE) whose matrix is Z_UP_TO_Y_UP: a glTF viewer (y up)
    shows the model upright."""
    import trimesh  # noqa: PLC0415 (trimesh: imported when first used, not at the package's import)

    style = get_style(style)
    image = png_image(np.ascontiguousarray(glb_texture(texture_rgb)), LIMITS.glb_png_compress_level)
    colours = {"frame": (*style.frame_rgb, 1.0), "glass": (*style.glass_rgb, style.glass_alpha)}
    # one photo material for every textured part, hashed by the texture's sha256 read in place: the
    # glTF exporter hashes each part's material, and trimesh's own hash copies the whole texture
    # into bytes each time (minutes for 1000 windows on a 6000x4000 photo, and a copy of the
    # texture in memory); equal hashes are what it deduplicates on, so the file is unchanged
    digest = hashlib.sha256(memoryview(np.ascontiguousarray(texture_rgb))).digest()
    photo = _fixed_hash(trimesh.visual.material.PBRMaterial, int.from_bytes(digest[:8], "little"))(
        name="photo", baseColorTexture=image, metallicFactor=0.0, roughnessFactor=1.0)
    scene = trimesh.Scene()
    # glTF is y-up: one root node turns the export world (z up) into it, the parts stay in its coordinates
    root = np.eye(4)
    root[:3, :3] = Z_UP_TO_Y_UP
    scene.graph.update(frame_from=scene.graph.base_frame, frame_to=GLB_ROOT_NODE, matrix=root)
    for p in parts:
        if p.uv is not None:
            visual = trimesh.visual.TextureVisuals(uv=p.uv, material=photo)
        else:
            rgba = np.asarray(colours[p.material])
            material = trimesh.visual.material.PBRMaterial(
                name=p.material, baseColorFactor=rgba, metallicFactor=0.0, roughnessFactor=0.5,
                alphaMode="BLEND" if rgba[3] < 1 else "OPAQUE")
            visual = trimesh.visual.TextureVisuals(material=material)
        mesh = trimesh.Trimesh(p.vertices, p.faces, visual=visual, process=False)
        scene.add_geometry(mesh, node_name=p.name, geom_name=p.name, parent_node_name=GLB_ROOT_NODE)
    glb_path = Path(glb_path)
    glb_path.write_bytes(scene.export(file_type="glb"))
    return glb_path


def png_image(rgb: np.ndarray, compress_level: int):
    """A PIL image of rgb (H, W, 3) uint8 whose PNG encoding (``save(..., format="png")``, what
    trimesh's glTF exporter calls) uses zlib ``compress_level`` (0-9) unless the caller states one:
    the same pixels, lossless; level 1 encodes a 12 Mpx photo in ~0.6 CPU-s instead of level 6's
    ~2.4 s, for a ~25 % larger file."""

    class LevelledPng(Image.Image):
        def save(self, fp, format=None, **params):  # noqa: A002 (PIL's signature)
            if str(format or "").lower() == "png":
                params.setdefault("compress_level", compress_level)
            return super().save(fp, format, **params)

    image = Image.fromarray(rgb)
    image.__class__ = LevelledPng
    return image


def _fixed_hash(material_cls: type, value: int) -> type:
    """A subclass of a trimesh material class whose instances hash to ``value``."""
    class FixedHash(material_cls):
        def __hash__(self) -> int:
            return value
    return FixedHash
