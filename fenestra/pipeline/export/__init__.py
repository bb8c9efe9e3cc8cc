"""Pipeline outputs: IFC4 with photo texture, OBJ/MTL, GLB, overlay, inpainted texture, substitution.

    from fenestra.pipeline.export import write_outputs
    paths = write_outputs("out/photo1", image, K, results, substitute="sash-cross")
    # {"ifc", "texture", "obj", "mtl", "glb", "overlay", "inpainted", "manifest"[, "substituted"]}

Frames, units, the ground plane, storey rows and texture conventions: fenestra/pipeline/export/geometry.py;
what model.ifc holds (storeys, editable walls, the photo cladding, types, quantities):
fenestra/pipeline/export/ifc.py.
"""
from __future__ import annotations

import json
import shutil
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from fenestra.checks import check_image, check_K
from fenestra.errors import PipelineError
from fenestra.files import write_image
from fenestra.pipeline.catalogue import WindowStyle, fitted_style, get_style, window_mesh
from fenestra.pipeline.export.floors import Floors, floor_levels, grounded_floors
from fenestra.pipeline.export.geometry import (Gravity, PlacedWindow, StoreyLevels, camera_to_world, gravity_up,
                                               place, storey_levels, texture_layout, union_layout, upright,
                                               WALL_THICKNESS_M)
from fenestra.pipeline.export.ifc import write_ifc
from fenestra.pipeline.export.inpaint import capped_size, inpaint_voids, scaled_K
from fenestra.pipeline.export.mesh import model_parts, write_glb, write_obj
from fenestra.pipeline.export.overlay import draw_overlay
from fenestra.pipeline.export.walls_plan import facade_walls
from fenestra.pipeline.types import Unavailable, WindowResult

DEFAULT_STYLE = "casement-white"  # the IFC/OBJ window body when no substitution style is chosen
# texture.png (padding included), inpainted.png and substituted.png are at most this many px along
# their longer side: a larger photo is inpainted and textured at a reduced size (one factor, the
# texture coordinates exact for it), so that a 100 Mpx photo's export costs what a 12 Mpx one's
# does. 4096 px is the texture size every WebGL / BIM viewer takes (GL_MAX_TEXTURE_SIZE >= 4096).
EXPORT_MAX_PX = 4096


def split_results(results: list[WindowResult], style: str | WindowStyle = DEFAULT_STYLE,
                  exclude: dict[int, str] | None = None) -> tuple[list[PlacedWindow], list[dict]]:
    """(exportable windows, skipped [{"index", "reason"}]) -- failed results never raise.

    Skipped: upstream failures, unusable poses (see geometry.place), sizes no mesh can take, and
    the windows named in ``exclude`` ({index: reason}, e.g. implausible ones).
    """
    placed, skipped = [], []
    exclude = exclude or {}
    for i, r in enumerate(results):
        index = int(getattr(r, "index", i))
        pw = Unavailable(exclude[index]) if index in exclude else place(r)
        if not isinstance(pw, Unavailable):
            try:
                window_mesh(style, pw.width_m, pw.height_m)
            except ValueError as e:
                pw = Unavailable(str(e))
        if isinstance(pw, Unavailable):
            skipped.append({"index": int(getattr(r, "index", i)), "reason": pw.reason})
        else:
            placed.append(pw)
    return placed, skipped


def export_decision(results: list[WindowResult], style: str | WindowStyle = DEFAULT_STYLE,
                    exclude: dict[int, str] | None = None) -> dict[int, str]:
    """{window index: reason} of every window that stays out of the BIM model: the windows named
    in ``exclude`` (e.g. implausible ones), upstream failures, unusable poses and sizes no mesh of
    ``style`` takes (:func:`split_results`). The one export decision (pipeline.session runs it
    once per method); the writers are given it as their ``exclude``."""
    return {s["index"]: s["reason"] for s in split_results(results, style, exclude)[1]}


def write_overlay(out_dir: str | Path, image: np.ndarray, K: np.ndarray, results: list[WindowResult],
                  exclude: dict[int, str] | None = None, boxes: dict[int, tuple] | None = None,
                  header: list[str] | None = None) -> Path:
    """overlay.png in ``out_dir`` (pipeline.export.overlay.draw_overlay: exclude, boxes, header as
    there); written whatever the results hold."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return write_image(out / "overlay.png", draw_overlay(check_image(image), check_K(K), list(results), exclude,
                                                       boxes, header), scratch=True)


def export_gravity(placed: list[PlacedWindow], walls: dict[int, int] | None,
                   gravity: Gravity | np.ndarray | bool = True) -> Gravity:
    """The export world's vertical for :func:`write_outputs` (its ``gravity`` argument): True:
    estimated (geometry.gravity_up of the placed windows and their walls), False: camera level, a
    (3,) camera-frame up vector: that (ValueError naming it when not a finite non-zero 3-vector)."""
    if isinstance(gravity, Gravity):
        return gravity
    if gravity is True:
        return gravity_up(placed, walls)
    if gravity is False or gravity is None:
        return Gravity(None, "camera level: as asked")
    up = np.asarray(gravity, dtype=np.float64).reshape(-1)
    if up.shape != (3,) or not (np.all(np.isfinite(up)) and np.linalg.norm(up) > 1e-9):
        raise ValueError(f"gravity must be True, False or a finite non-zero 3-vector (camera frame), got {gravity!r}")
    return Gravity(up / np.linalg.norm(up), "given")


@dataclass(frozen=True)
class WrittenModel:
    """What the model files hold, before any is written (:func:`written_model`): placed, the
    exported windows turned upright and grounded (export world); skipped [{"index", "reason"}] the
    others; gravity the export world's vertical (``up`` (3,) camera frame, None: camera level);
    levels the rows of windows (geometry.storey_rows, in the grounded world); ground_z_m the
    ground floor's level before grounding (m, upright world; export.json ``world_frame.offset`` is
    -ground_z_m); floors model.ifc's storeys (pipeline.export.floors.Floors, grounded: the ground
    floor at z = 0); doors the placed doors (indices of their own, on their floors) and
    doors_skipped [{"index", "reason"}] those that could not be placed."""

    placed: tuple[PlacedWindow, ...]
    skipped: tuple[dict, ...]
    gravity: Gravity
    levels: StoreyLevels
    ground_z_m: float
    floors: Floors
    doors: tuple[PlacedWindow, ...] = ()
    doors_skipped: tuple[dict, ...] = ()

    @property
    def camera_to_export(self) -> np.ndarray:
        """(3, 3) camera frame -> export world rotation (export.json ``world_frame.camera_to_export``)."""
        return camera_to_world(self.gravity.up)

    @property
    def up(self) -> np.ndarray:
        """The model's vertical (3,) unit, camera frame: the z row of :attr:`camera_to_export`
        (gravity's up, or the camera's -y for the camera-level frame)."""
        z = self.camera_to_export[2]
        return z / np.linalg.norm(z)

    def rows(self) -> list[list[int]]:
        """Each storey row's window indices, lowest first (export.json ``storeys.rows[*].windows``)."""
        return [sorted(i for i, row in self.levels.row_of.items() if row == r) for r in range(len(self.levels.sills_m))]


def written_model(results: list[WindowResult], style: str | WindowStyle = DEFAULT_STYLE,
                  exclude: dict[int, str] | None = None, walls: dict[int, int] | None = None,
                  gravity: Gravity | np.ndarray | bool = True, decided: bool = False,
                  doors: list[WindowResult] = ()) -> WrittenModel:
    """The model :func:`write_outputs` writes for ``results`` (its arguments of the same names), as
    a value: which windows and ``doors`` are placed, the export world's vertical, the rows of
    windows and the floors (pipeline.export.floors). Pure.
    decided: ``exclude`` is :func:`export_decision` of these results and ``style`` (what
    pipeline.session's run decided), so every other window places and takes a mesh: the checks of
    :func:`split_results` are not repeated (the same model)."""
    if decided:
        exclude = exclude or {}
        skipped = [{"index": int(r.index), "reason": exclude[r.index]} for r in results if r.index in exclude]
        placed = [place(r) for r in results if r.index not in exclude]
    else:
        placed, skipped = split_results(list(results), style, exclude)
    g = export_gravity(placed, walls, gravity)
    placed = upright(placed, g)
    door_pw, doors_skipped = split_results(list(doors), style)  # a door is placed as a window is
    door_pw = upright(door_pw, g)
    rows = storey_levels(placed)
    floors = floor_levels(placed, walls, door_pw)
    ground_z = floors.ground_z_m
    placed, door_pw, floors = grounded_floors(placed, door_pw, floors)  # the ground floor at z = 0
    rows = replace(rows, sills_m=tuple(s - ground_z for s in rows.sills_m))
    return WrittenModel(tuple(placed), tuple(skipped), g, rows, ground_z, floors, tuple(door_pw), tuple(doors_skipped))


def write_outputs(out_dir: str | Path, image: np.ndarray, K: np.ndarray, results: list[WindowResult],
                  substitute: str | WindowStyle | None = None, exclude: dict[int, str] | None = None,
                  walls: dict[int, int] | None = None, properties: dict[int, dict] | None = None,
                  wall_properties: dict[int, dict] | None = None, overlay: bool = True,
                  gravity: Gravity | np.ndarray | bool = True, max_px: int = EXPORT_MAX_PX,
                  gps: tuple | None = None, thickness_m: float = WALL_THICKNESS_M,
                  source: str | None = None, doors: list[WindowResult] = (), door_walls: dict[int, int] | None = None,
                  door_properties: dict[int, dict] | None = None) -> dict[str, Path]:
    """Write every output for one photo into ``out_dir``; return {kind: path}.

    image (H, W, 3) uint8 RGB; K (3, 3); results from the reconstruction. Written: model.ifc,
    texture.png (inpainted photo, padded), inpainted.png (the photo's size, or smaller: below),
    model.obj + model.mtl,
    model.glb, overlay.png, export.json (manifest: exported and skipped windows, with reasons, and
    export timings), and substituted.png when ``substitute`` names a catalogue style (which then
    also shapes the IFC/OBJ/GLB windows). exclude: {index: reason} of windows not to export;
    walls: {index: wall id} (one IfcWall per wall; None: one per window); properties: {index:
    {name: value}}, the IFC Fenestra property set of each window; overlay: write overlay.png too;
    wall_properties: {wall id: {name: value}}, that of each fitted wall; gravity: the export world's
    vertical (pipeline.export.geometry): True estimates it from the exported windows' wall up axes
    (:func:`~pipeline.export.geometry.gravity_up`, with ``walls``), a (3,) up vector in the camera
    frame or a Gravity gives it, False keeps the camera-level frame (CAMERA_TO_EXPORT). The world's
    origin is then moved down to the ground floor's level (pipeline.export.floors: the floors come
    from the main wall's rows of windows, the ground floor's level from the doors standing below
    them or SILL_HEIGHT_M below its lowest row's sills; model.ifc's storeys are the floors), the
    same for model.ifc, model.obj and model.glb; export.json's ``world_frame.offset`` and
    ``storeys`` say so (``storeys.rows``: the rows of windows, geometry.storey_rows).
    doors: the doors' results (indices of their own: pipeline.session.Opening), each placed like a
    window and written as an IfcDoor in its wall (``door_walls`` {door index: wall id}; model.ifc
    only), ``door_properties`` their Fenestra_Door property sets; export.json's ``doors``.
    gps: (latitude deg, longitude deg[, elevation m]) of the camera: model.ifc's site reference and
    map conversion (pipeline.export.ifc.write_ifc). thickness_m: the walls' thickness, m (model.ifc's
    layer and extrusion, the OBJ/GLB slabs; export.json ``wall_thickness_m``). source: the photo's
    file name, which model.ifc's provenance names.
    Bounded cost: when the padded texture would exceed ``max_px`` (EXPORT_MAX_PX) along its longer
    side, the photo is inpainted and textured at the reduced size that fits (inpaint.capped_size;
    export.json's ``texture``: ``photo_width``/``photo_height``, the size the texture's photo
    region has, and ``scale``); the overlay stays at the photo's size.
    """
    t_start = time.perf_counter()
    image = check_image(image)
    K = check_K(K)
    if not isinstance(results, (list, tuple)):
        raise PipelineError(f"results must be a list of WindowResult, got {type(results).__name__}")
    style = get_style(substitute if substitute is not None else DEFAULT_STYLE)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = written_model(list(results), style, exclude, walls, gravity, doors=list(doors))
    placed, skipped, gravity, levels = list(model.placed), list(model.skipped), model.gravity, model.levels
    floors, door_pw, ground_z = model.floors, list(model.doors), model.ground_z_m
    timings: dict[str, float] = {}

    def _timed(name, fn, *args, **kw):
        t0 = time.perf_counter()
        value = fn(*args, **kw)
        timings[name] = 1000.0 * (time.perf_counter() - t0)
        return value

    def layout_of(K_tex: np.ndarray, shape: tuple[int, ...]):
        layout = texture_layout(K_tex, shape, placed)
        for wall in facade_walls(placed, walls, K_tex, (shape[1], shape[0])):  # the walls' slabs need it too
            layout = union_layout(layout, texture_layout(K_tex, shape, [wall.frame], wall.margin_m))
        return layout

    photo_size = (image.shape[1], image.shape[0])
    layout = layout_of(K, image.shape)  # geometry only: cheap at any size
    size = capped_size(photo_size, (layout.width, layout.height), int(max_px))
    K_tex = scaled_K(K, photo_size, size) if size != photo_size else K  # the texture's photo region's K
    if size != photo_size:
        layout = layout_of(K_tex, (size[1], size[0]))
    inpainted, _ = _timed("inpaint_ms", inpaint_voids, image, list(results), size=size)
    texture = layout.pad(inpainted)
    paths = {"inpainted": write_image(out / "inpainted.png", inpainted)}
    if texture.shape == inpainted.shape:  # no padding: the same image, the same file (no second encode)
        paths["texture"] = Path(shutil.copyfile(paths["inpainted"], out / "texture.png"))
    else:
        paths["texture"] = write_image(out / "texture.png", texture)
    ids, door_ids, doors_unwalled = _timed(
        "ifc_ms", write_ifc, out / "model.ifc", K_tex, placed, layout, "texture.png", style, walls=walls,
        properties=properties, wall_properties=wall_properties, levels=floors, gps=gps, thickness_m=thickness_m,
        source=source, doors=door_pw, door_walls=door_walls, door_properties=door_properties)
    paths["ifc"] = out / "model.ifc"
    parts = model_parts(K_tex, placed, layout, style, walls=walls, thickness_m=thickness_m)
    paths["obj"], paths["mtl"] = _timed("obj_ms", write_obj, out / "model.obj", parts, style, "texture.png")
    if parts:  # glTF cannot hold an empty scene: no GLB when no window could be exported
        paths["glb"] = _timed("glb_ms", write_glb, out / "model.glb", parts, texture, style)
    if overlay:  # (pipeline.photo draws its own, with the detections and a header: overlay=False)
        paths["overlay"] = write_image(out / "overlay.png", _timed("overlay_ms", draw_overlay, image, K, list(results),
                                                                  {e["index"]: e["reason"] for e in skipped}))
    if substitute is not None:
        from fenestra.pipeline.export.substitute import composite  # noqa: PLC0415 (a cycle: fenestra.pipeline.export.substitute imports this module)

        paths["substituted"] = write_image(out / "substituted.png",
                                          _timed("substitute_ms", composite, inpainted, K_tex, placed, style))
    timings["total_ms"] = 1000.0 * (time.perf_counter() - t_start)
    manifest = {
        "style": style.name,
        "wall_thickness_m": float(thickness_m),
        "world_frame": {"camera_to_export": model.camera_to_export.tolist(), "gravity": gravity.to_json(),
                        "offset_m": [0.0, 0.0, -model.ground_z_m],
                        "glb_root": "model.glb's root node turns this z-up world y-up (x, y, z) -> (x, z, -y)",
                        "note": "export world X_E = camera_to_export @ X_C + offset_m: the OpenCV camera frame "
                                "turned upright (z = gravity's up), the ground plane at z = 0, the camera above "
                                "the origin, its heading along +y; the same in model.ifc, model.obj and model.glb"},
        "storeys": {**floors.to_json(), "row_tolerance_m": levels.tol_m,
                    "rows": [{"row": r, "sill_m": s, "windows": w}
                             for r, (s, w) in enumerate(zip(levels.sills_m, model.rows()))]},
        "texture": {"file": "texture.png", "pad_left": layout.pad_left, "pad_top": layout.pad_top,
                    "pad_right": layout.pad_right, "pad_bottom": layout.pad_bottom,
                    "width": layout.width, "height": layout.height, "photo_width": size[0], "photo_height": size[1],
                    "scale": size[0] / photo_size[0], "max_px": int(max_px)},
        "exported": [{"index": pw.index, "width_m": pw.width_m, "height_m": pw.height_m, **ids[pw.index],
                      "style_scaled": fitted_style(style, pw.width_m, pw.height_m) != style}
                     for pw in placed],
        "skipped": skipped,
        "doors": {"exported": [{"index": d.index, "width_m": d.width_m, "height_m": d.height_m, **door_ids[d.index]}
                               for d in door_pw if d.index in door_ids],
                  "skipped": list(model.doors_skipped) + doors_unwalled},
        "timings_ms": timings,
    }
    paths["manifest"] = out / "export.json"
    paths["manifest"].write_text(json.dumps(manifest, indent=2))
    return paths


__all__ = ["WrittenModel", "written_model", "write_outputs", "write_overlay", "split_results", "export_decision", "export_gravity", "DEFAULT_STYLE", "EXPORT_MAX_PX"]
