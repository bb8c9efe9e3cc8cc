"""Exact per-view ground truth of window voids: instance map, corners, visibility; and the
ignore regions (curtain-wall glazing, glazed doors: neither window nor background).

The instance map is defined at pixel centres: pixel (u, v) belongs to window i when the ray
through (u, v) hits window i's void rectangle (on the wall's exterior face) before any other
geometry, where a window's own element (frame, glass) never hides its own void. The void
rectangles are rasterised here analytically (pixel-centre inside test, ray/plane depth); the
occluders come from a renderer's exact (non-antialiased) depth + element-id pass.

Ignore regions (:func:`ignore_regions`): the glazing faces (alpha < :data:`GLAZING_MAX_ALPHA`) of
IfcCurtainWall / IfcPlate elements (kind ``curtain_wall``, one region per IfcCurtainWall: its
panels together) and of IfcDoor elements (kind ``glazed_door``, one per door). They take their own
codes in the same element-id pass; :func:`ignore_map` marks a pixel where that glazing is the
nearest surface and no window void is (a window in front keeps its pixels; glazing behind a wall
is hidden like any surface).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.renders.camera import Camera
from fenestra.scenes.model import ElementMesh, Scene, WindowGT

NEAR_M = 1e-3
IGNORE_KINDS = {"IfcCurtainWall": "curtain_wall", "IfcPlate": "curtain_wall", "IfcDoor": "glazed_door"}
GLAZING_MAX_ALPHA = 0.9  # a face below this alpha is glazing (renders.materials' glass threshold)


@dataclass(frozen=True, eq=False)
class WindowView:
    """Ground truth of one window in one view (a ``windows`` entry of view.json)."""

    id: str
    instance_id: int
    corners_world: np.ndarray  # (4, 3) m
    corners_px: np.ndarray  # (4, 2) px, distortion included, may lie outside the image
    corner_visible: tuple[bool, bool, bool, bool]
    visible_fraction: float
    visible_px: int
    incidence_deg: float
    distance_m: float

    def to_dict(self) -> dict:
        return {"id": self.id, "instance_id": self.instance_id, "corners_world": self.corners_world.tolist(),
                "corners_px": self.corners_px.tolist(), "corner_visible": list(self.corner_visible),
                "visible_fraction": self.visible_fraction, "visible_px": self.visible_px,
                "incidence_deg": self.incidence_deg, "distance_m": self.distance_m}


def clip_near(Xc: np.ndarray, near: float = NEAR_M) -> np.ndarray:
    """Clip a convex polygon in camera coordinates (N, 3) to z >= near (Sutherland-Hodgman)."""
    out = []
    n = len(Xc)
    for i in range(n):
        a, b = Xc[i], Xc[(i + 1) % n]
        ina, inb = a[2] >= near, b[2] >= near
        if ina:
            out.append(a)
        if ina != inb:
            s = (near - a[2]) / (b[2] - a[2])
            out.append(a + s * (b - a))
    return np.array(out).reshape(-1, 3)


def polygon_area(p: np.ndarray) -> float:
    """Unsigned shoelace area of a polygon (N, 2)."""
    x, y = p[:, 0], p[:, 1]
    return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2)


def inside_convex(poly: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Boolean mask of points (u, v) (any shape) inside or on a convex polygon (N, 2), either winding."""
    sign = np.sign(np.dot(poly[:, 0], np.roll(poly[:, 1], -1)) - np.dot(poly[:, 1], np.roll(poly[:, 0], -1)))
    ok = np.ones(np.broadcast(u, v).shape, bool)
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        ok &= sign * ((b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0])) >= 0
    return ok


def occlusion_eps_m(z: np.ndarray) -> np.ndarray:
    """How much nearer (m) than a void an occluder must be to hide it, at void depth z (m):
    above the 24-bit depth-buffer precision, well below any real protrusion (sills: cm)."""
    return 0.002 + 2e-4 * z


def void_instances(cam: Camera, windows: tuple[WindowGT, ...], occ_depth: np.ndarray, occ_elem: np.ndarray,
                   window_elem: np.ndarray, sample_xy: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Instance map of window voids for a pinhole camera.

    occ_depth: (H, W) float32 camera z (m) of the nearest surface of all geometry, 0 = nothing;
    occ_elem: (H, W) int, the element code hit there (0 = non-window geometry);
    window_elem: (n_windows,) element code of each window's own element (-1 if it has none).
    sample_xy: optional float maps (Ho, Wo) of where each output pixel samples this camera's image
    (a distorted camera's inverse map): voids are then tested exactly at those points and
    occluders looked up at the nearest pixel. Default: the pixel centres of this camera.
    Returns instances uint16 (0 = none, i+1 = window i) and void depth float32 (0 = none).
    """
    if cam.dist is not None:
        raise ValueError("void_instances needs a pinhole camera (use camera.canvas())")
    H, W = cam.height, cam.width
    if sample_xy is None:
        shape = (H, W)
    else:
        shape = sample_xy[0].shape
        sx, sy = sample_xy[0].astype(np.float64), sample_xy[1].astype(np.float64)
        ix = np.clip(np.rint(sx), 0, W - 1).astype(np.int64)
        iy = np.clip(np.rint(sy), 0, H - 1).astype(np.int64)
    inst = np.zeros(shape, np.uint16)
    zbuf = np.full(shape, np.inf, np.float32)
    Kinv = np.linalg.inv(cam.K)
    for i, w in enumerate(windows):
        Xc = w.corners_world @ cam.R.T + cam.t
        poly3 = clip_near(Xc)
        if len(poly3) < 3:
            continue
        q = poly3 @ cam.K.T
        p = q[:, :2] / q[:, 2:3]
        if sample_xy is None:
            x0, y0 = np.maximum(np.floor(p.min(axis=0)), 0).astype(int)
            x1, y1 = np.minimum(np.ceil(p.max(axis=0)), [W - 1, H - 1]).astype(int)
            if x1 < x0 or y1 < y0:
                continue
            sel = (slice(y0, y1 + 1), slice(x0, x1 + 1))
            uu, vv = np.meshgrid(np.arange(x0, x1 + 1, dtype=np.float64), np.arange(y0, y1 + 1, dtype=np.float64))
            od, oe = occ_depth[sel], occ_elem[sel]
        else:
            lo, hi = p.min(axis=0), p.max(axis=0)
            rows = np.nonzero(((sy >= lo[1]) & (sy <= hi[1]) & (sx >= lo[0]) & (sx <= hi[0])).any(axis=1))[0]
            cols = np.nonzero(((sy >= lo[1]) & (sy <= hi[1]) & (sx >= lo[0]) & (sx <= hi[0])).any(axis=0))[0]
            if len(rows) == 0:
                continue
            sel = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
            uu, vv = sx[sel], sy[sel]
            od, oe = occ_depth[iy[sel], ix[sel]], occ_elem[iy[sel], ix[sel]]
        m = inside_convex(p, uu, vv)
        n_c = cam.R @ w.normal
        d = float(n_c @ Xc[0])
        ray_dot = (Kinv[0, 0] * uu + Kinv[0, 1] * vv + Kinv[0, 2]) * n_c[0] + (Kinv[1, 1] * vv + Kinv[1, 2]) * n_c[1] + n_c[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (d / ray_dot).astype(np.float32)
        free = (od <= 0) | (od >= z - occlusion_eps_m(z)) | (oe == window_elem[i])
        zb = zbuf[sel]
        m &= free & (z > 0) & (z < zb)
        zb[m] = z[m]
        inst[sel][m] = i + 1
    zbuf[inst == 0] = 0
    return inst, zbuf


def void_area_px(camera: Camera, corners_world: np.ndarray, samples_per_edge: int = 32) -> float:
    """Area (px^2) of a void's image on an unbounded sensor (near-clipped, distortion included)."""
    Xc = corners_world @ camera.R.T + camera.t
    if camera.dist is None:  # straight edges stay straight: the clipped corners are exact
        poly = clip_near(Xc, near=0.05)
        if len(poly) < 3:
            return 0.0
        q = poly @ camera.K.T
        return polygon_area(q[:, :2] / q[:, 2:3])
    dense = np.concatenate([Xc[i] + np.linspace(0, 1, samples_per_edge, endpoint=False)[:, None] * (Xc[(i + 1) % 4] - Xc[i])
                            for i in range(4)])
    dense = clip_near(dense, near=0.05)
    if len(dense) < 3:
        return 0.0
    Xw = (dense - camera.t) @ camera.R  # back to world for Camera.project
    return polygon_area(camera.project(Xw))


def window_views(camera: Camera, windows: tuple[WindowGT, ...], instances: np.ndarray, depth_canvas: np.ndarray,
                 elem_canvas: np.ndarray, window_elem: np.ndarray) -> tuple[WindowView, ...]:
    """Per-window ground truth for a rendered view.

    instances: final (H, W) map of ``camera``; depth_canvas / elem_canvas: the occluder pass of
    ``camera.canvas()`` (used for corner occlusion tests at the pinhole corner positions).
    """
    canvas = camera.canvas()
    counts = np.bincount(instances.ravel(), minlength=len(windows) + 1)
    C = camera.center
    out = []
    if not windows:
        return ()
    allc = np.concatenate([w.corners_world for w in windows])  # (4 n, 3): one projection call each
    px_all, z_all = camera.project(allc), camera.depths(allc)
    pin_all = px_all if camera.dist is None else canvas.project(allc)
    for i, w in enumerate(windows):
        px, z, pin = px_all[4 * i:4 * i + 4].copy(), z_all[4 * i:4 * i + 4], pin_all[4 * i:4 * i + 4]
        vis = []
        for k in range(4):
            ok = z[k] > 0 and -0.5 <= px[k, 0] <= camera.width - 0.5 and -0.5 <= px[k, 1] <= camera.height - 0.5
            if ok:
                u = int(np.clip(np.rint(pin[k, 0]), 0, canvas.width - 1))
                v = int(np.clip(np.rint(pin[k, 1]), 0, canvas.height - 1))
                od, oe = depth_canvas[v, u], elem_canvas[v, u]
                ok = bool(od <= 0 or od >= z[k] - occlusion_eps_m(z[k]) or oe == window_elem[i])
            vis.append(bool(ok))
        area = void_area_px(camera, w.corners_world)
        frac = float(min(1.0, counts[i + 1] / area)) if area > 0 else 0.0
        to_cam = C - w.center
        dist = float(np.linalg.norm(to_cam))
        inc = float(np.degrees(np.arccos(np.clip(to_cam @ w.normal / dist, -1, 1))))
        out.append(WindowView(w.id, i + 1, np.asarray(w.corners_world, float), px, tuple(vis), frac,
                              int(counts[i + 1]), inc, dist))
    return tuple(out)


# ---------------------------------------------------------------- ignore regions

@dataclass(frozen=True, eq=False)
class IgnoreRegion:
    """Glazing of a scene that is neither window nor background (an ``ignore`` entry of view.json).

    id: GlobalId of the IfcCurtainWall a panel is aggregated into (else the element's own), or of
    the IfcDoor; kind: "curtain_wall" | "glazed_door"; faces: GlobalId of each of its elements ->
    (M,) bool, which of that mesh's faces are glazing.
    """

    id: str
    kind: str
    faces: dict[str, np.ndarray]


def glazing_faces(mesh: ElementMesh) -> np.ndarray:
    """(M,) bool: faces whose alpha (per-face style, else the element's) is below GLAZING_MAX_ALPHA
    (a NaN alpha counts as opaque)."""
    alpha = (np.full(len(mesh.faces), mesh.rgba[3], np.float64) if mesh.face_rgba is None
             else np.asarray(mesh.face_rgba, np.float64)[:, 3])
    with np.errstate(invalid="ignore"):
        return alpha < GLAZING_MAX_ALPHA


def ignore_regions(scene: Scene) -> tuple[IgnoreRegion, ...]:
    """The scene's ignore regions, in mesh order: every IfcCurtainWall / IfcPlate / IfcDoor mesh
    with glazing faces; elements aggregated into one whole (the panels of a curtain wall) form one
    region; doors are one region each."""
    faces: dict[str, dict[str, np.ndarray]] = {}
    kinds: dict[str, str] = {}
    for m in scene.meshes:
        kind = IGNORE_KINDS.get(m.kind)  # IfcDoorStandardCase is a door (scenes.model.ElementMesh.kind)
        if kind is None:
            continue
        glass = glazing_faces(m)
        if not glass.any():
            continue
        key = m.parent_id if kind == "curtain_wall" and m.parent_id else m.global_id
        kinds.setdefault(key, kind)
        faces.setdefault(key, {})[m.global_id] = glass
    return tuple(IgnoreRegion(k, kinds[k], faces[k]) for k in faces)


def ignore_map(occ_elem: np.ndarray, instances: np.ndarray, first_code: int, n_regions: int,
               sample_xy: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(Ho, Wo) uint16 ignore-region map: r + 1 where the nearest surface is region r's glazing
    (element code ``first_code + r`` in ``occ_elem``, the (H, W) int element-code pass of a
    pinhole canvas) and ``instances`` (Ho, Wo) holds no window; 0 elsewhere.

    sample_xy: as in :func:`void_instances` (a distorted camera's inverse map): the code is then
    looked up at the nearest canvas pixel, as void_instances looks up occluders.
    """
    code = np.asarray(occ_elem)
    if sample_xy is not None:
        H, W = code.shape
        ix = np.clip(np.rint(sample_xy[0]), 0, W - 1).astype(np.int64)
        iy = np.clip(np.rint(sample_xy[1]), 0, H - 1).astype(np.int64)
        code = code[iy, ix]
    if code.shape != instances.shape:
        raise ValueError(f"element codes {code.shape} and instances {instances.shape} differ in shape")
    r = code.astype(np.int64) - first_code + 1
    out = np.where((r >= 1) & (r <= n_regions) & (instances == 0), r, 0)
    return out.astype(np.uint16)


def ignore_entries(regions: tuple[IgnoreRegion, ...], ignore: np.ndarray) -> list[dict]:
    """view.json's ``ignore`` list: per region with pixels in ``ignore`` (its map, region r = r + 1),
    ``{"id", "instance_id", "kind", "visible_px"}``, in region order."""
    counts = np.bincount(ignore.ravel(), minlength=len(regions) + 1)
    return [{"id": g.id, "instance_id": r + 1, "kind": g.kind, "visible_px": int(counts[r + 1])}
            for r, g in enumerate(regions) if counts[r + 1]]
