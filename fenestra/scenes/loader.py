"""Load an IFC house: element meshes (openings cut) + window ground truth, cached on disk.

    >>> from scenes import load_scene
    >>> scene = load_scene("fzk-haus")          # bundled short name or a path to an .ifc
    >>> len(scene.windows), scene.windows[0].width
    (11, 2.0)

Meshes come from ``ifcopenshell.geom.iterator`` (all cores, world coordinates, openings subtracted),
one :class:`ElementMesh` per element; IfcOpeningElement, IfcSpace and IfcAnnotation bodies are not
loaded (nor any other of ``ifc_read.SKIP_CLASSES``: spatial, virtual, annotation elements, by
is_a(), subtypes included). Each mesh records its ``base_class`` (IfcWindowStandardCase ->
IfcWindow) and the parts of a window or door (IfcRelAggregates) are merged into its mesh. Colours come from the IFC surface styles (per face when an element has several; the
element colour is the largest-area style), else :data:`CLASS_COLOURS`.

Cache: ``$FENESTRA_CACHE`` or ``~/.cache/fenestra/scenes``; one ``<sha256>-<code>.npz`` (arrays) and
``.json`` (everything else) per file content and :func:`cache_version` (a digest of the sources in
:data:`CACHE_SOURCES` and the ifcopenshell version), so edits to a file or to that code never serve
stale data, with no version number to bump by hand.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import multiprocessing
import os
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np

from fenestra.errors import SceneError
from fenestra.files import file_sha256, source_digest, write_atomic, write_json
from fenestra.scenes.ifc_read import SKIP_CLASSES, base_class, by_types, is_any, open_ifc  # noqa: F401
from fenestra.scenes.model import ElementMesh, Scene, SkippedWindow, WindowGT
from fenestra.scenes.registry import BUNDLED, resolve, scene_name

# The code a loaded Scene depends on (this module's folder); with the ifcopenshell version they key the cache.
CACHE_SOURCES: tuple[str, ...] = ("loader.py", "ground_truth.py", "model.py", "ifc_read.py",
                                  "window_sources.py")
# Parts aggregated into one of these are merged into its mesh (IfcOpenShell's IfcOpenHouse writes a
# window as IfcMember frames and an IfcPlate pane with no body of the window's own).
MERGE_INTO: tuple[str, ...] = ("IfcWindow", "IfcDoor")

# Fallback colours (RGBA, 0-1) for elements without a surface style.
CLASS_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "IfcWall": (0.85, 0.82, 0.76, 1.0),
    "IfcWallStandardCase": (0.85, 0.82, 0.76, 1.0),
    "IfcCurtainWall": (0.6, 0.7, 0.8, 0.5),
    "IfcWindow": (0.55, 0.75, 0.9, 0.4),
    "IfcDoor": (0.55, 0.35, 0.2, 1.0),
    "IfcSlab": (0.7, 0.7, 0.7, 1.0),
    "IfcRoof": (0.6, 0.25, 0.2, 1.0),
    "IfcSite": (0.35, 0.55, 0.3, 1.0),
}
DEFAULT_COLOUR = (0.75, 0.75, 0.75, 1.0)


# --------------------------------------------------------------------------- helpers
def default_cache_dir() -> Path:
    """``$FENESTRA_CACHE`` (if set) else ``~/.cache/fenestra/scenes``."""
    env = os.environ.get("FENESTRA_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "fenestra" / "scenes"


def _style_rgba(material) -> tuple[float, float, float, float]:
    """ifcopenshell geometry style -> RGBA in [0, 1] (alpha = 1 - transparency)."""
    rgb = tuple(float(c) for c in material.diffuse.components)
    alpha = 1.0 - float(material.transparency) if material.has_transparency else 1.0
    if not np.all(np.isfinite(rgb)) or len(rgb) != 3:
        raise ValueError(f"bad diffuse colour {rgb}")
    return (*rgb, alpha)


def _element_mesh(shape, base: str = "") -> ElementMesh | None:
    """One iterator shape -> ElementMesh (None when its body is empty); base: its base class."""
    g = shape.geometry
    verts = np.asarray(g.verts, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(g.faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        return None
    default = CLASS_COLOURS.get(base or shape.type, CLASS_COLOURS.get(shape.type, DEFAULT_COLOUR))
    palette = []
    for m in g.materials:
        try:
            palette.append(_style_rgba(m))
        except (ValueError, AttributeError, TypeError):
            palette.append(default)
    mat_ids = np.asarray(g.material_ids, dtype=np.int64)
    face_rgba = None
    rgba = default
    if palette and len(mat_ids) == len(faces) and mat_ids.min() >= 0:
        pal = np.asarray(palette, dtype=np.float64)
        tri = verts[faces]
        areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        rgba = tuple(float(c) for c in pal[np.argmax(np.bincount(mat_ids, weights=areas,
                                                                 minlength=len(pal)))])
        if len(np.unique(mat_ids)) > 1:
            face_rgba = pal[mat_ids]
    return ElementMesh(global_id=shape.guid, ifc_class=shape.type, name=shape.name or "",
                       vertices=verts, faces=faces, rgba=rgba, face_rgba=face_rgba,
                       base_class=base if base != shape.type else "")


def geom_settings():
    """ifcopenshell geometry settings used everywhere: world coordinates, openings cut."""
    import ifcopenshell.geom  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    s = ifcopenshell.geom.settings()
    s.set("use-world-coords", True)
    return s


def iterate_meshes(ifc_file, label: str) -> dict[str, ElementMesh]:
    """GlobalId -> ElementMesh for every element with a body (multi-core geometry iterator), none
    of SKIP_CLASSES; the parts of a window or door merged into it (:func:`merge_parts`)."""
    import ifcopenshell.geom  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    exclude = by_types(ifc_file, SKIP_CLASSES)
    it = ifcopenshell.geom.iterator(geom_settings(), ifc_file, multiprocessing.cpu_count(),
                                    exclude=exclude)
    meshes: dict[str, ElementMesh] = {}
    if not it.initialize():
        raise SceneError(f"{label}: no element with 3D geometry")
    while True:
        shape = it.get()
        el = ifc_file.by_guid(shape.guid)
        if not is_any(el, SKIP_CLASSES):
            mesh = _element_mesh(shape, base_class(el))
            if mesh is not None:
                meshes[mesh.global_id] = mesh
        if not it.next():
            break
    for gid, m in meshes.items():
        parent = _aggregate_parent(ifc_file, gid)
        if parent:
            meshes[gid] = dataclasses.replace(m, parent_id=parent)
    return merge_parts(meshes, {m.parent_id: ifc_file.by_guid(m.parent_id) for m in meshes.values()
                                if m.parent_id})


def merge_parts(meshes: dict[str, ElementMesh], parents: dict) -> dict[str, ElementMesh]:
    """Meshes with the parts of every MERGE_INTO whole (parents: GlobalId -> entity) merged into
    one mesh of the whole (its own body first, when it has one; per-face colours kept)."""
    groups: dict[str, list[ElementMesh]] = {}
    for m in meshes.values():
        whole = parents.get(m.parent_id)
        if whole is not None and is_any(whole, MERGE_INTO):
            groups.setdefault(m.parent_id, []).append(m)
    merged = {p.global_id for g in groups.values() for p in g}
    out = {gid: m for gid, m in meshes.items() if gid not in merged}
    for gid, parts in groups.items():
        whole = parents[gid]
        own = [out[gid]] if gid in out else []
        out[gid] = _merged(own + parts, gid, whole.is_a(), whole.Name or "", base_class(whole))
    return out


def _merged(parts: list[ElementMesh], gid: str, ifc_class: str, name: str, base: str) -> ElementMesh:
    """One ElementMesh of several (vertices stacked, faces re-indexed, per-face colours)."""
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts])[:-1]
    faces = np.concatenate([p.faces + o for p, o in zip(parts, offsets)])
    face_rgba = np.concatenate([p.face_rgba if p.face_rgba is not None
                                else np.tile(p.rgba, (len(p.faces), 1)) for p in parts])
    first = parts[0]
    return ElementMesh(global_id=gid, ifc_class=ifc_class, name=name,
                       vertices=np.concatenate([p.vertices for p in parts]), faces=faces,
                       rgba=first.rgba, face_rgba=face_rgba, parent_id="",
                       base_class=base if base != ifc_class else "")


def _aggregate_parent(ifc_file, global_id: str) -> str:
    """GlobalId of the element ``global_id`` is aggregated into (IfcRelAggregates), "" when none
    or when the whole is a spatial element (storey, building, site)."""
    el = ifc_file.by_guid(global_id)
    for rel in getattr(el, "Decomposes", None) or ():
        whole = rel.RelatingObject
        if rel.is_a("IfcRelAggregates") and whole.is_a("IfcElement"):
            return whole.GlobalId
    return ""


# --------------------------------------------------------------------------- cache
@functools.cache
def cache_version() -> str:
    """12 hex digits of the CACHE_SOURCES' bytes and the ifcopenshell version (the cache key's code part)."""

    here = Path(__file__).resolve().parent
    return source_digest([here / f for f in CACHE_SOURCES], f"ifcopenshell {version('ifcopenshell')}")


def _cache_paths(cache_dir: Path, sha: str) -> tuple[Path, Path]:
    stem = cache_dir / f"{sha}-{cache_version()}"
    return stem.with_suffix(".npz"), stem.with_suffix(".json")


def _save_cache(scene: Scene, cache_dir: Path) -> None:
    """Write scene arrays (.npz) and metadata (.json) atomically (temp file + rename)."""
    cache_dir.mkdir(parents=True, exist_ok=True)
    npz_path, json_path = _cache_paths(cache_dir, scene.sha256)
    arrays: dict[str, np.ndarray] = {}
    meshes_meta = []
    for i, m in enumerate(scene.meshes):
        arrays[f"v{i}"], arrays[f"f{i}"] = m.vertices, m.faces
        if m.face_rgba is not None:
            arrays[f"c{i}"] = m.face_rgba
        meshes_meta.append({"global_id": m.global_id, "ifc_class": m.ifc_class, "name": m.name,
                            "rgba": list(m.rgba), "face_rgba": m.face_rgba is not None,
                            "parent_id": m.parent_id, "base_class": m.base_class})
    for i, w in enumerate(scene.windows):
        arrays[f"wc{i}"], arrays[f"wn{i}"] = w.corners_world, w.normal
        if w.outline_world is not None:
            arrays[f"wo{i}"] = w.outline_world
    windows_meta = [{k: getattr(w, k) for k in ("id", "host_id", "host_class", "opening_id", "name",
                                                "width", "height", "ifc_overall_width",
                                                "ifc_overall_height", "shape", "notes", "source")}
                    | {"outline": w.outline_world is not None} for w in scene.windows]
    meta = {"name": scene.name, "schema": scene.schema, "sha256": scene.sha256,
            "meshes": meshes_meta, "windows": windows_meta,
            "skipped": [{"id": s.id, "name": s.name, "reason": s.reason, "cause": s.cause}
                        for s in scene.skipped]}
    write_atomic(npz_path, lambda p: np.savez(p, **arrays))
    write_json(json_path, meta, indent=None)


def _load_cache(cache_dir: Path, sha: str, path: Path, name: str) -> Scene | None:
    """Scene from the cache, or None when absent or unreadable."""
    npz_path, json_path = _cache_paths(cache_dir, sha)
    if not (npz_path.is_file() and json_path.is_file()):
        return None
    try:
        meta = json.loads(json_path.read_text())
        with np.load(npz_path) as z:
            arrays = {k: z[k] for k in z.files}
        meshes = tuple(
            ElementMesh(global_id=m["global_id"], ifc_class=m["ifc_class"], name=m["name"],
                        vertices=arrays[f"v{i}"], faces=arrays[f"f{i}"], rgba=tuple(m["rgba"]),
                        face_rgba=arrays[f"c{i}"] if m["face_rgba"] else None,
                        parent_id=m.get("parent_id", ""), base_class=m.get("base_class", ""))
            for i, m in enumerate(meta["meshes"]))
        windows = tuple(
            WindowGT(**{k: v for k, v in w.items() if k != "outline"},
                     corners_world=arrays[f"wc{i}"], normal=arrays[f"wn{i}"],
                     outline_world=arrays[f"wo{i}"] if w["outline"] else None)
            for i, w in enumerate(meta["windows"]))
        skipped = tuple(SkippedWindow(**s) for s in meta["skipped"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return Scene(name=name, path=str(path), schema=meta["schema"], sha256=sha, meshes=meshes,
                 windows=windows, skipped=skipped)


# --------------------------------------------------------------------------- public API
def load_scene(name_or_path: str | Path, cache_dir: str | Path | None = None,
               use_cache: bool = True, strict: bool = False) -> Scene:
    """Load a bundled house (short name) or an .ifc path -> :class:`Scene`.

    cache_dir: defaults to :func:`default_cache_dir`. A window that cannot be measured is listed in
    ``Scene.skipped`` with its reason; strict: raise SceneError for the first one instead. Raises
    SceneError (one line naming the file) for a missing, non-IFC, truncated, unreadable file, an
    unsupported schema, and a file with no IfcWindow.
    """
    path = resolve(name_or_path)
    name = scene_name(path)
    sha = file_sha256(path)
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    scene = _load_cache(cache, sha, path, name) if use_cache else None
    if scene is None:
        scene = build_scene(path, name, sha)
        if use_cache:
            try:
                _save_cache(scene, cache)
            except OSError:
                pass  # a read-only cache folder only costs speed
    if strict and scene.skipped:
        s = scene.skipped[0]
        raise SceneError(f"{path}: window {s.id} ('{s.name}') skipped: {s.reason} "
                         f"(strict; {len(scene.skipped)} of {scene.n_present} windows skipped)")
    return scene


def build_scene(path: Path, name: str, sha: str) -> Scene:
    """Read the IFC and compute meshes and ground truth (no cache)."""
    from fenestra.scenes.ground_truth import windows_ground_truth  # noqa: PLC0415 (a cycle: fenestra.scenes.ground_truth imports this module)

    f = open_ifc(path)
    if not f.by_type("IfcWindow"):
        raise SceneError(f"{path}: the model has no IfcWindow")
    meshes = iterate_meshes(f, str(path))
    windows, skipped = windows_ground_truth(f, meshes, str(path), geom_settings())
    return Scene(name=name, path=str(path), schema=f.schema, sha256=sha,
                 meshes=tuple(meshes.values()), windows=tuple(windows), skipped=tuple(skipped))


def list_scenes() -> list[str]:
    """Short names of the bundled houses."""
    return list(BUNDLED)


def timed_load(name_or_path: str | Path, **kwargs) -> tuple[Scene, float]:
    """(scene, seconds) for benchmarking the loader."""
    t0 = time.perf_counter()
    scene = load_scene(name_or_path, **kwargs)
    return scene, time.perf_counter() - t0
