"""pyrender (OpenGL over EGL) backend: daylight RGB, exact window-void instance maps, depth.

Two offscreen renderers live for the renderer's lifetime:
- the RGB renderer (pyrender's 4x MSAA): textured material groups, sun + fill light, shadows,
  composited over a sky gradient;
- the occluder renderer, with multisampling switched off, draws every element in a flat colour
  that encodes its element code; its depth and codes feed :func:`renders.gt.void_instances`, which
  rasterises the void rectangles exactly at pixel centres.
Use as a context manager or call ``close()`` (a live OffscreenRenderer at exit can segfault).
"""
from __future__ import annotations

import atexit
from contextlib import contextmanager
from typing import Callable

import cv2

import numpy as np

from fenestra.compat import import_pyrender
from fenestra.conventions import PYRENDER_PIXEL_OFFSET, cv_to_gl_pose
from renders.base import RenderOutput, RenderSettings
from renders.camera import Camera, distort_image
from renders.gt import void_instances, window_views
from renders.materials import (Look, face_normals, group_scene, ground_z, lighting, sample_look, sky_colour,
                               sun_direction)
from scenes.model import Scene

ZNEAR, ZFAR = 0.1, 2000.0
SHADE_LEVELS = 16  # shadow-ratio quantisation levels


@contextmanager
def _single_sample(pyrender):
    """While active, pyrender creates its framebuffers without multisampling (exact flat colours)."""
    mod = pyrender.renderer
    orig = mod.glRenderbufferStorageMultisample
    mod.glRenderbufferStorageMultisample = lambda tgt, samples, fmt, w, h: orig(tgt, 0, fmt, w, h)
    try:
        yield
    finally:
        mod.glRenderbufferStorageMultisample = orig


def pyrender_camera(pyrender, cam: Camera):
    """pyrender IntrinsicsCamera + 4x4 OpenGL pose for a pinhole Camera (pixel offset applied)."""
    if cam.dist is not None:
        raise ValueError("pyrender draws pinhole cameras only; pass camera.canvas()")
    K = cam.K
    pc = pyrender.IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2] + PYRENDER_PIXEL_OFFSET, K[1, 2] + PYRENDER_PIXEL_OFFSET,
                                   znear=ZNEAR, zfar=ZFAR)
    return pc, cv_to_gl_pose(cam.R, cam.t)


def element_codes(scene: Scene) -> tuple[dict[str, int], np.ndarray]:
    """Element code per GlobalId (window i's element -> i + 1, everything else 0) and the
    (n_windows,) array of each window's own code."""
    codes = {w.id: i + 1 for i, w in enumerate(scene.windows)}
    return codes, np.arange(1, len(scene.windows) + 1)


def ground_quad(scene: Scene, half_size_m: float = 200.0) -> tuple[np.ndarray, np.ndarray]:
    """Ground plane square (4, 3) vertices, (2, 3) faces (upward), centred under the scene."""
    gz = ground_z(scene) - 0.002
    c, h = scene.bounds().mean(axis=0), half_size_m
    v = np.array([[c[0] - h, c[1] - h, gz], [c[0] + h, c[1] - h, gz], [c[0] + h, c[1] + h, gz], [c[0] - h, c[1] + h, gz]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


class GLContext:
    """One process-wide EGL context (pyrender OffscreenRenderer) shared by all backends.

    pyrender's EGL teardown terminates the display, so two OffscreenRenderers cannot be closed
    independently; instead each user gets its own pyrender ``Renderer`` (framebuffers, shaders,
    uploaded meshes) inside this single context. Reference counted; closed with its last user.
    """

    _shared: "GLContext | None" = None

    def __init__(self):
        self.pr = import_pyrender()
        self.osr = self.pr.OffscreenRenderer(64, 64)
        self.users = 0

    @classmethod
    def acquire(cls) -> "GLContext":
        if cls._shared is None:
            cls._shared = GLContext()
        cls._shared.users += 1
        return cls._shared

    def new_renderer(self, single_sample: bool):
        r = self.pr.renderer.Renderer(64, 64)
        r._fenestra_single_sample = single_sample
        return r

    def render(self, renderer, scene, width: int, height: int, flags, seg_node_map=None):
        """Render ``scene`` with one of this context's renderers at width x height."""
        plat = self.osr._platform
        plat.make_current()
        try:
            renderer.viewport_width, renderer.viewport_height = width, height
            flags |= self.pr.RenderFlags.OFFSCREEN
            if renderer._fenestra_single_sample:
                with _single_sample(self.pr):
                    return renderer.render(scene, flags, seg_node_map)
            return renderer.render(scene, flags, seg_node_map)
        finally:
            plat.make_uncurrent()

    def release(self, renderer) -> None:
        """Free one renderer's GL resources; close the context when its last user is gone."""
        self.osr._platform.make_current()
        renderer.delete()
        self.osr._platform.make_uncurrent()
        self.users -= 1
        if self.users <= 0 and GLContext._shared is self:
            self.osr.delete()
            GLContext._shared = None


@atexit.register
def _close_shared_context() -> None:
    if GLContext._shared is not None:
        GLContext._shared.osr.delete()
        GLContext._shared = None


class OccluderPass:
    """Exact depth + element-code images (no antialiasing) of a scene, for ground truth.

    The colour of a pixel encodes the element code (window i's element = i + 1, other geometry 0)
    in R + 256 G; B is 1 + 254 * the face's shadow ratio when ``shade`` is given (else 255).
    """

    def __init__(self, scene: Scene, shade: Callable[[np.ndarray], np.ndarray] | None = None):
        self.pr = pr = import_pyrender()
        self.scene = scene
        self.codes, self.window_codes = element_codes(scene)
        self._scene = pr.Scene(bg_color=(0, 0, 0, 0))
        self._seg = {}
        parts: dict[tuple[int, int], list] = {}
        gv, gf = ground_quad(scene)
        items = [(self.codes.get(m.global_id, 0), m.vertices, m.faces) for m in scene.meshes] + [(0, gv, gf)]
        for code, v, f in items:
            if shade is None:
                bins = np.full(len(f), 255)
            else:
                q = np.rint(SHADE_LEVELS * np.clip(shade(face_normals(v, f)), 0, 1)) / SHADE_LEVELS
                bins = 1 + np.rint(254 * q).astype(int)  # few distinct bins: few draw calls
            for b in np.unique(bins):
                parts.setdefault((code, int(b)), []).append((v, f[bins == b]))
        for (code, b), vfs in sorted(parts.items()):
            V, F, off = [], [], 0
            for v, f in vfs:
                V.append(v); F.append(f + off); off += len(v)  # noqa: E702
            F = np.concatenate(F)
            # pyrender culls back faces in SEG mode whatever the material says, and IFC winding
            # varies: draw every triangle in both windings.
            prim = pr.Primitive(positions=np.concatenate(V).astype(np.float32),
                                indices=np.concatenate([F, F[:, ::-1]]).astype(np.uint32), mode=4)
            node = self._scene.add(pr.Mesh([prim]))
            self._seg[node] = np.array([code % 256, code // 256, b], np.uint8)
        self._cam_node = None
        self._gl = GLContext.acquire()
        self._renderer = self._gl.new_renderer(single_sample=True)

    def _set_camera(self, camera, pose) -> None:
        if self._cam_node is not None:
            self._scene.remove_node(self._cam_node)
        self._cam_node = self._scene.add(camera, pose=pose)

    def render_full(self, cam: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pinhole camera -> depth (H, W) float32 m (0 = nothing), element codes (H, W) int32
        (-1 = nothing) and the B channel (H, W) uint8 (shadow-ratio bin, 0 = nothing)."""
        pc, pose = pyrender_camera(self.pr, cam)
        self._set_camera(pc, pose)
        col, depth = self._gl.render(self._renderer, self._scene, cam.width, cam.height,
                                     self.pr.RenderFlags.SEG, self._seg)
        code = col[..., 0].astype(np.int32) + 256 * col[..., 1].astype(np.int32)
        code[col[..., 2] == 0] = -1
        return depth.astype(np.float32), code, col[..., 2]

    def render(self, cam: Camera) -> tuple[np.ndarray, np.ndarray]:
        """Pinhole camera -> depth (H, W) float32 m (0 = nothing) and element codes (H, W) int32."""
        depth, code, _ = self.render_full(cam)
        return depth, code

    def render_ortho_depth(self, pose: np.ndarray, half_extent: float, far: float, size: int) -> np.ndarray:
        """Orthographic depth map (size, size) float32, m along the view axis (0 = nothing).

        pose: 4x4 OpenGL camera-to-world (looks along its -z); covers +-half_extent m.
        """
        oc = self.pr.OrthographicCamera(xmag=half_extent, ymag=half_extent, znear=0.01, zfar=far)
        self._set_camera(oc, pose)
        _, d = self._gl.render(self._renderer, self._scene, size, size, self.pr.RenderFlags.SEG, self._seg)
        # pyrender linearises depth with the perspective formula; undo it for the orthographic camera.
        n, f = 0.01, far
        out = np.zeros_like(d)
        hit = d > 0
        ndc = (f + n - 2 * n * f / d[hit]) / (f - n)
        out[hit] = (ndc * (f - n) + (f + n)) / 2
        return out

    def close(self) -> None:
        if self._renderer is not None:
            self._gl.release(self._renderer)
            self._renderer = None


def ground_truth(occ: OccluderPass, camera: Camera):
    """Instance map (H, W) uint16, depth (H, W) float32, per-window views and the canvas pass."""
    canvas = camera.canvas()
    depth_c, code_c, shade_c = occ.render_full(canvas)
    maps = None if camera.dist is None else camera.canvas_maps()
    inst, _ = void_instances(canvas, occ.scene.windows, depth_c, code_c, occ.window_codes, maps)
    depth = distort_image(camera, depth_c, nearest=True)
    wins = window_views(camera, occ.scene.windows, inst, depth_c, code_c, occ.window_codes)
    return inst, depth, wins, (depth_c, shade_c)


def sky_image(cam: Camera, look: Look, step: int = 8) -> np.ndarray:
    """(H, W, 3) float32 sky gradient seen by a pinhole camera (computed on a coarse grid)."""
    W, H = cam.width, cam.height
    us, vs = np.meshgrid(np.arange(0, W + step, step, dtype=np.float64), np.arange(0, H + step, step, dtype=np.float64))
    rays = np.stack([us, vs, np.ones_like(us)], -1) @ np.linalg.inv(cam.K).T @ cam.R  # world dirs
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    coarse = sky_colour(rays, look).astype(np.float32)
    return cv2.resize(coarse, (us.shape[1] * step, us.shape[0] * step), interpolation=cv2.INTER_LINEAR)[:H, :W]


class SunShadow:
    """A sun shadow map rendered once per scene; tells which camera pixels lie in shadow."""

    def __init__(self, occ: OccluderPass, sun: np.ndarray, size: int = 2048, bias_m: float = 0.04):
        lo, hi = occ.scene.bounds()
        centre = (lo + hi) / 2
        self.radius = float(np.linalg.norm(hi - lo) / 2) + 1.0
        z = sun / np.linalg.norm(sun)
        x = np.cross([0.0, 0.0, 1.0], z)
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0.0, 0.0])
        self.axes = np.stack([x, np.cross(z, x), z], axis=1)  # columns: camera x, y, z in world
        self.origin = centre + 2 * self.radius * z
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = self.axes, self.origin
        self.size, self.bias = size, bias_m
        self.map = occ.render_ortho_depth(pose, self.radius, 4 * self.radius, size)

    def in_shadow(self, cam: Camera, depth: np.ndarray) -> np.ndarray:
        """(H, W) bool for a pinhole camera's exact depth map (m, 0 = sky)."""
        H, W = depth.shape
        uu, vv = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
        Kinv = np.linalg.inv(cam.K).astype(np.float32)
        xc = (Kinv[0, 0] * uu + Kinv[0, 1] * vv + Kinv[0, 2]) * depth
        yc = (Kinv[1, 1] * vv + Kinv[1, 2]) * depth
        # world = R^T (Xc - t); then sun-camera coordinates = axes^T (world - origin)
        M = (self.axes.T @ cam.R.T).astype(np.float32)
        o = (self.axes.T @ (-cam.R.T @ cam.t - self.origin)).astype(np.float32)
        sx = M[0, 0] * xc + M[0, 1] * yc + M[0, 2] * depth + o[0]
        sy = M[1, 0] * xc + M[1, 1] * yc + M[1, 2] * depth + o[1]
        sz = -(M[2, 0] * xc + M[2, 1] * yc + M[2, 2] * depth + o[2])
        col = np.rint((sx / self.radius + 1) / 2 * self.size - 0.5).astype(np.int32)
        row = np.rint((1 - sy / self.radius) / 2 * self.size - 0.5).astype(np.int32)
        ok = (depth > 0) & (col >= 0) & (col < self.size) & (row >= 0) & (row < self.size)
        occ_d = np.zeros_like(depth)
        occ_d[ok] = self.map[row[ok], col[ok]]
        return ok & (occ_d > 0) & (sz > occ_d + self.bias)


class RasterRenderer:
    """pyrender backend: ``render(camera) -> RenderOutput``; one set of GL resources reused.

    RGB: textured material groups with baked daylight (sky ambient + sun, per face) drawn unlit
    with 4x MSAA, sun shadows from a shadow map applied per pixel, over a sky gradient.
    """

    name = "pyrender"

    def __init__(self, scene: Scene, settings: RenderSettings = RenderSettings()):
        self.pr = pr = import_pyrender()
        self.scene, self.settings = scene, settings
        rng = np.random.default_rng(settings.seed)
        self.look = look = sample_look(rng)
        self.groups = group_scene(scene, look, rng)
        self._scene = pr.Scene(bg_color=(0, 0, 0, 0))
        for g in self.groups:
            m = g.material
            mult, _ = lighting(face_normals(g.vertices, g.faces), look)
            colour = np.ones((len(g.vertices), 4), np.float32)
            colour[g.faces.ravel(), :3] = np.repeat(mult, 3, axis=0)
            kw = dict(baseColorFactor=(*m.rgb, 1.0), metallicFactor=0.0, roughnessFactor=1.0, doubleSided=True)
            if m.texture is not None:
                kw["baseColorTexture"] = pr.Texture(source=m.texture, source_channels="RGB")
            prim = pr.Primitive(positions=g.vertices.astype(np.float32), texcoord_0=g.uvs.astype(np.float32),
                                color_0=colour, indices=g.faces.astype(np.uint32),
                                material=pr.MetallicRoughnessMaterial(**kw), mode=4)
            self._scene.add(pr.Mesh([prim]))
        self._cam_node = None
        self.occluders = OccluderPass(scene, shade=lambda n: lighting(n, look)[1])
        self.shadow = SunShadow(self.occluders, sun_direction(look)) if settings.shadows else None
        self._gl = GLContext.acquire()
        self._renderer = self._gl.new_renderer(single_sample=False)
        self._shadow_tint = np.array([0.92, 0.96, 1.08], np.float32)

    def render_rgb(self, camera: Camera, gt_canvas=None) -> np.ndarray:
        """(H, W, 3) uint8 antialiased daylight image for the camera (distortion applied).

        gt_canvas: (depth, shade) of the occluder pass for ``camera.canvas()`` if already made.
        """
        pr = self.pr
        canvas = camera.canvas()
        pc, pose = pyrender_camera(pr, canvas)
        if self._cam_node is not None:
            self._scene.remove_node(self._cam_node)
        self._cam_node = self._scene.add(pc, pose=pose)
        rgba, _ = self._gl.render(self._renderer, self._scene, canvas.width, canvas.height,
                                  pr.RenderFlags.RGBA | pr.RenderFlags.FLAT)
        img = rgba[..., :3].astype(np.float32) * (1.0 / 255.0)
        if self.shadow is not None:
            if gt_canvas is None:
                d, _, b = self.occluders.render_full(canvas)
            else:
                d, b = gt_canvas
            sh = self.shadow.in_shadow(canvas, d) & (b < 255)
            ratio = (b.astype(np.float32) - 1.0) / 254.0
            img[sh] *= ratio[sh, None] * self._shadow_tint
        see_sky = rgba[..., 3] < 255
        if see_sky.any():
            a = rgba[see_sky, 3:4].astype(np.float32) * (1.0 / 255.0)
            img[see_sky] += (1.0 - a) * sky_image(canvas, self.look)[see_sky]
        rgb = np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
        return distort_image(camera, rgb, nearest=False)

    def render(self, camera: Camera) -> RenderOutput:
        inst, depth, wins, gt_canvas = ground_truth(self.occluders, camera)
        rgb = self.render_rgb(camera, gt_canvas)
        return RenderOutput(camera, rgb, inst, depth, wins)

    def close(self) -> None:
        if self._renderer is not None:
            self._gl.release(self._renderer)
            self._renderer = None
        self.occluders.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
