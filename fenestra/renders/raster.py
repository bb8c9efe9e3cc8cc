"""OpenGL (EGL, via pyrender's headless context) backend: daylight RGB, exact window-void
instance maps, depth.

Geometry is uploaded once per renderer into vertex buffers (merged by material: one draw range
per material group) and every view only sets a camera matrix:
- the RGB pass: textured material groups with baked daylight (sky ambient + sun, per face), a
  per-pixel sky gradient where nothing was drawn; sun shadows come from a shadow map rendered once
  per scene and tested per fragment in the shader. Antialiasing (RenderSettings.antialias): FXAA
  post filter (default) or 4x MSAA (~2.5x slower on llvmpipe) or none;
- the occluder pass, single-sampled, draws every element in a flat colour that encodes its
  element code; its depth and codes feed :func:`renders.gt.void_instances`, which rasterises
  the void rectangles exactly at pixel centres. It is drawn once per view: the sampler's
  visibility test draws it for a candidate camera and the render of the accepted view takes
  that ground truth (:meth:`OccluderPass.truth`); the RGB pass draws colour only.
Draw order is fixed (sorted groups, never pyrender's set order), so coincident faces resolve the
same way in every GL context and the same seed gives byte-identical images. pyrender is only used
for its headless EGL context (llvmpipe here).
Use as a context manager or call ``close()`` (a live EGL context at exit can segfault).
The OpenGL plumbing (context, buffers, textures, framebuffers, read-back) lives in
:mod:`renders.gl`, the GLSL sources in :mod:`renders.shaders`; this module holds the passes.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from fenestra.conventions import PYRENDER_PIXEL_OFFSET, cv_to_gl_pose
from fenestra.renders.base import RenderOutput, RenderSettings
from fenestra.renders.camera import Camera, distort_image
from fenestra.renders.gl import (GLContext, Geometry, begin, encode, end_prepass, read_depth, read_rgba,
                        texture_rgb, texture_u16, uniform)
from fenestra.renders.gt import (IgnoreRegion, WindowView, ignore_entries, ignore_map, ignore_regions, void_instances,
                        window_views)
from fenestra.renders.materials import (SceneGeometry, face_normals, group_scene, ground_z, lighting, sample_look,
                                        sun_direction)
from fenestra.scenes.model import Scene

ZNEAR, ZFAR = 0.1, 2000.0
SHADE_LEVELS = 16  # shadow-ratio quantisation levels
MSAA_SAMPLES = 4
SHADOW_TINT = (0.92, 0.96, 1.08)


def gl_projection(K: np.ndarray, width: int, height: int, znear: float = ZNEAR, zfar: float = ZFAR) -> np.ndarray:
    """4x4 OpenGL projection of a pinhole K (pyrender IntrinsicsCamera's, pixel offset applied)."""
    cx, cy = K[0, 2] + PYRENDER_PIXEL_OFFSET, K[1, 2] + PYRENDER_PIXEL_OFFSET
    P = np.zeros((4, 4))
    P[0, 0], P[1, 1] = 2.0 * K[0, 0] / width, 2.0 * K[1, 1] / height
    P[0, 2], P[1, 2] = 1.0 - 2.0 * cx / width, 2.0 * cy / height - 1.0
    P[3, 2] = -1.0
    P[2, 2], P[2, 3] = (zfar + znear) / (znear - zfar), 2 * zfar * znear / (znear - zfar)
    return P


def gl_view_projection(cam: Camera) -> np.ndarray:
    """4x4 world -> clip matrix of a pinhole Camera."""
    if cam.dist is not None:
        raise ValueError("the raster passes draw pinhole cameras only; pass camera.canvas()")
    return gl_projection(cam.K, cam.width, cam.height) @ np.linalg.inv(cv_to_gl_pose(cam.R, cam.t))


def element_codes(scene: Scene) -> tuple[dict[str, int], np.ndarray]:
    """Element code per GlobalId (window i's element -> i + 1, everything else 0) and the
    (n_windows,) array of each window's own code."""
    codes = {w.id: i + 1 for i, w in enumerate(scene.windows)}
    return codes, np.arange(1, len(scene.windows) + 1)


def ignore_face_codes(scene: Scene, regions: tuple[IgnoreRegion, ...]) -> dict[str, np.ndarray]:
    """Element codes of the ignore regions' faces: per element GlobalId, (M,) int per face, region
    r's glazing ``len(scene.windows) + 1 + r``, the element's other faces 0 (like any non-window
    geometry). ValueError when the codes do not fit the pass's 16 bits."""
    first = len(scene.windows) + 1
    if first + len(regions) > 65536:
        raise ValueError(f"{len(scene.windows)} windows + {len(regions)} ignore regions exceed the occluder "
                         "pass's 16-bit element codes")
    return {gid: np.where(glass, first + r, 0) for r, g in enumerate(regions) for gid, glass in g.faces.items()}


def ground_quad(scene: Scene, half_size_m: float = 200.0) -> tuple[np.ndarray, np.ndarray]:
    """Ground plane square (4, 3) vertices, (2, 3) faces (upward), centred under the scene."""
    gz = ground_z(scene) - 0.002
    c, h = scene.bounds().mean(axis=0), half_size_m
    v = np.array([[c[0] - h, c[1] - h, gz], [c[0] + h, c[1] - h, gz], [c[0] + h, c[1] + h, gz], [c[0] - h, c[1] + h, gz]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])



class OccluderPass:
    """Exact depth + element-code images (no antialiasing) of a scene, for ground truth.

    The colour of a pixel encodes the element code (window i's element = i + 1, ignore region r's
    glazing = n_windows + 1 + r (:func:`ignore_face_codes`), other geometry 0) in R + 256 G;
    B is never 0 where a face was drawn (255, or the raster backend's shadow-ratio level).
    All triangles are one vertex buffer drawn in one call, two-sided, in a fixed order: the scene's
    sorted by code, or ``triangles`` (positions (3M, 3), :func:`encode`-d colours (3M, 4)) in their
    order when given. Where coplanar faces tie in depth the first drawn wins, so the raster backend
    passes its RGB pass's own triangles in that pass's order: its ground truth then matches its
    image, and its RGB pass takes this pass's depth as an exact pre-pass (:meth:`depth_of`).
    """

    def __init__(self, scene: Scene, triangles: tuple[np.ndarray, np.ndarray] | None = None):
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        self.scene = scene
        self.users = 1  # the renderers drawing with this pass (:meth:`share`); the last close() frees it
        self._kept = None  # (camera, ground truth) of the last view the visibility test kept (truth())
        self._token = object()  # marks the framebuffers this pass drew (Framebuffers.mark)
        self.codes, self.window_codes = element_codes(scene)
        self.ignore_regions = ignore_regions(scene)
        self.first_ignore_code = len(scene.windows) + 1
        self.face_codes = ignore_face_codes(scene, self.ignore_regions)
        P, C = self._triangles() if triangles is None else triangles
        self.positions = P  # (3M, 3) float32, in draw order: what another look's renderer may share (:meth:`share`)
        self._gl = GLContext.acquire()
        self._gl.make_current()
        self._geom = Geometry(P, np.zeros((len(P), 2), np.float32), C,
                               np.arange(len(P), dtype=np.uint32), [(0, len(P), 0, (1.0, 1.0, 1.0))])
        GL.glFinish()

    def _triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """The scene's triangles (3M, 3) float32 (and the ground quad) sorted by code, with their
        colours (3M, 4) (B = 255)."""
        scene = self.scene
        parts: dict[int, list[np.ndarray]] = {}
        gv, gf = ground_quad(scene)
        items = []
        for m in scene.meshes:
            fc = self.face_codes.get(m.global_id)
            if fc is None:
                items.append((self.codes.get(m.global_id, 0), m.vertices, m.faces))
            else:
                items += [(int(c), m.vertices, m.faces[fc == c]) for c in np.unique(fc)]
        items.append((0, gv, gf))
        for code, v, f in items:
            parts.setdefault(code, []).append(np.asarray(v, np.float64)[f].reshape(-1, 3))
        P, C = [], []
        for code, tris in sorted(parts.items()):
            p = np.concatenate(tris)
            P.append(p)
            C.append(np.broadcast_to(encode([code % 256, code // 256, 255, 255]), (len(p), 4)))
        return np.concatenate(P).astype(np.float32), np.concatenate(C)

    def _draw(self, PV: np.ndarray, width: int, height: int) -> int:
        """Issue the pass (GL renders it asynchronously); return its framebuffer."""
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        gl = self._gl
        gl.make_current()
        fb = gl.fbs.bind(width, height, 0, tag="occluders")
        begin(width, height)
        prog = gl.program("code")
        GL.glUseProgram(prog)
        GL.glUniformMatrix4fv(uniform(prog, "PV"), 1, GL.GL_TRUE, PV.astype(np.float32))
        self._geom.draw()
        GL.glUseProgram(0)
        GL.glFlush()
        gl.fbs.mark(fb, (self._token, PV.tobytes()))
        return fb

    def depth_of(self, cam: Camera) -> int:
        """The framebuffer holding this pass for a pinhole camera: drawn now unless the last pass
        in that framebuffer (shared by every OccluderPass of the GL context) was this one's of it."""
        PV = gl_view_projection(cam)
        self._gl.make_current()
        fb = self._gl.fbs.bind(cam.width, cam.height, 0, tag="occluders")
        return fb if self._gl.fbs.holds(fb, (self._token, PV.tobytes())) else self._draw(PV, cam.width, cam.height)

    def render_full(self, cam: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pinhole camera -> depth (H, W) float32 m (0 = nothing), element codes (H, W) int32
        (-1 = nothing) and the B channel (H, W) uint8 (shadow-ratio bin, 0 = nothing)."""
        return self._read(cam, self._draw(gl_view_projection(cam), cam.width, cam.height))

    def _read(self, cam: Camera, fb: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self._gl.make_current()
        return read_occluder_pass(fb, cam.width, cam.height)

    def truth(self, camera: Camera, keep: bool = False, meanwhile: Callable[[], None] | None = None):
        """:func:`ground_truth` of ``camera``, drawn once per view: with ``keep`` (the sampler's
        visibility test) the result is also kept, and the next call for the same Camera object
        (the render of the view the sampler accepted) takes it instead of drawing the pass again.
        meanwhile: as in :func:`ground_truth` (when the pass is drawn)."""
        kept, self._kept = self._kept, None
        if kept is not None and kept[0] is camera:
            out = kept[1]
        else:
            out = ground_truth(self, camera, meanwhile)
        if keep:
            self._kept = (camera, out)
        return out

    def render(self, cam: Camera) -> tuple[np.ndarray, np.ndarray]:
        """Pinhole camera -> depth (H, W) float32 m (0 = nothing) and element codes (H, W) int32."""
        depth, code, _ = self.render_full(cam)
        return depth, code

    def render_ortho_depth(self, pose: np.ndarray, half_extent: float, far: float, size: int) -> np.ndarray:
        """Orthographic depth map (size, size) float32, m along the view axis (0 = nothing).

        pose: 4x4 OpenGL camera-to-world (looks along its -z); covers +-half_extent m.
        """
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        n, f = 0.01, far
        P = np.zeros((4, 4))
        P[0, 0] = P[1, 1] = 1.0 / half_extent
        P[2, 2], P[2, 3], P[3, 3] = 2.0 / (n - f), (f + n) / (n - f), 1.0
        fb = self._draw(P @ np.linalg.inv(pose), size, size)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, fb)
        d = read_depth(size, size)
        # ((2 d - 1) (f - n) + (f + n)) / 2 in float32, in place; 0 where nothing was drawn
        out = np.multiply(d, 2.0, dtype=np.float32)
        out -= 1.0
        out *= f - n
        out += f + n
        out /= 2
        out[d >= 1.0] = 0.0
        return out

    def share(self, positions: np.ndarray) -> "OccluderPass | None":
        """This pass for another renderer of the same scene whose occluder triangles are
        ``positions`` (3M, 3) float32 in its draw order (another look: the element codes and depth
        do not depend on it), or None when they differ (a look that draws its groups in another
        order: coplanar faces may then resolve otherwise). A shared pass is closed by its last user;
        the ground truth the sampler kept (:meth:`truth`) is the sharer's too: one pass per view."""
        if self._geom is None or not np.array_equal(self.positions, positions):
            return None
        self.users += 1
        return self

    def close(self) -> None:
        self.users -= 1
        if self._geom is not None and self.users <= 0:
            self._gl.make_current()
            self._geom.delete()
            self._geom = None
            self._gl.release()


def read_occluder_pass(fb: int, W: int, H: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a finished occluder pass (colour + depth of ``fb``): depth (H, W) float32 m
    (0 = nothing), element codes (H, W) int32 (-1 = nothing), B channel uint8."""
    from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, fb)
    col = read_rgba(W, H)
    d = read_depth(W, H)
    rgba = np.ascontiguousarray(col).view(np.uint32)[..., 0]  # little endian: R + 256 G + 65536 B ...
    code = (rgba & 0xFFFF).astype(np.int32)
    shade = np.ascontiguousarray(col[..., 2])
    code[shade == 0] = -1
    # window depth -> camera z (float32, pyrender's formula); 0 where nothing was drawn
    n, f = np.float32(ZNEAR), np.float32(ZFAR)
    depth = (2 * n * f) / (f + n - (2 * d - 1) * (f - n))
    depth[d >= 1] = 0
    return depth, code, shade


def ground_truth(occ: OccluderPass, camera: Camera, meanwhile: Callable[[], None] | None = None):
    """Instance map (H, W) uint16, depth (H, W) float32, per-window views and the ignore regions:
    (ignore map (H, W) uint16, region r = r + 1 (renders.gt.ignore_map), its view.json entries).
    meanwhile: called once the pass is read, before the ground truth is computed from it (GL
    work issued there overlaps the computation)."""
    canvas = camera.canvas()
    depth_c, code_c, _ = occ.render_full(canvas)
    if meanwhile is not None:
        meanwhile()
    maps = None if camera.dist is None else camera.canvas_maps()
    inst, _ = void_instances(canvas, occ.scene.windows, depth_c, code_c, occ.window_codes, maps)
    depth = distort_image(camera, depth_c, nearest=True)
    wins = window_views(camera, occ.scene.windows, inst, depth_c, code_c, occ.window_codes)
    ign = ignore_map(code_c, inst, occ.first_ignore_code, len(occ.ignore_regions), maps)
    return inst, depth, wins, (ign, tuple(ignore_entries(occ.ignore_regions, ign)))


class SunShadow:
    """A sun shadow map rendered once per scene; tells which points lie in shadow.

    The raster RGB pass applies the same test per sample in its fragment shader
    (``sun_from_world``, ``radius``, ``size``, ``bias``); :meth:`in_shadow` is the numpy version.
    """

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
        self.far = 4 * self.radius
        self.map = occ.render_ortho_depth(pose, self.radius, self.far, size)
        self.sun_from_world = np.eye(4)
        self.sun_from_world[:3, :3], self.sun_from_world[:3, 3] = self.axes.T, -self.axes.T @ self.origin

    def map_u16(self) -> np.ndarray:
        """The map quantised for the GPU: uint16 levels of ``far / 65535`` m (0 = nothing),
        rounded up so that a surface never shadows itself; ~1 mm steps, far below the bias."""
        q = np.divide(self.map, self.far, dtype=np.float32)
        q *= 65535.0
        np.ceil(q, out=q)
        np.minimum(q, 65535, out=q)
        return q.astype(np.uint16)

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


def shadow_ratio_levels(ratio: np.ndarray) -> np.ndarray:
    """Shadow ratio (M,) in [0, 1] -> the value the occluder pass's B channel encodes ((b-1)/254)."""
    q = np.rint(SHADE_LEVELS * np.clip(ratio, 0, 1)) / SHADE_LEVELS
    return np.rint(254 * q) / 254


DRAW_FIRST = ("brick", "plaster", "roof")  # material names, drawn in this order before the rest


def draw_priority(g) -> int:
    """Draw order of a material group: walls and roof first (early depth rejection of what they
    hide), the ground last; ties keep ``group_scene``'s order (sort is stable)."""
    name = g.material.name
    if name in DRAW_FIRST:
        return DRAW_FIRST.index(name)
    return len(DRAW_FIRST) + (name == "ground")


class RasterRenderer:
    """OpenGL backend: ``render(camera) -> RenderOutput``; geometry uploaded once, reused.

    RGB: textured material groups with baked daylight (sky ambient + sun, per face) drawn unlit
    over a per-pixel sky gradient, antialiased as ``settings.antialias`` says; a face in the sun's
    shadow (shadow map test per fragment) keeps its quantised shadow ratio of the light, tinted blue.

    like: another renderer of the same scene (another look) whose look-free parts this one takes
    instead of computing them again: its materials.SceneGeometry (glass panes, planar coordinates) and,
    when its triangles come out in the same draw order, its occluder pass (:meth:`OccluderPass.share`:
    one ground-truth pass per view, the sampler's). The images are those of a renderer built alone.
    """

    name = "pyrender"

    def __init__(self, scene: Scene, settings: RenderSettings = RenderSettings(), like: "RasterRenderer | None" = None):
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        self.scene, self.settings = scene, settings
        rng = np.random.default_rng(settings.seed)
        self.look = look = sample_look(rng, settings.look)
        self.geometry = SceneGeometry(scene) if like is None else like.geometry
        self.groups = group_scene(scene, look, rng, self.geometry)
        self._gl = GLContext.acquire()
        self._gl.make_current()
        codes, _ = element_codes(scene)
        glazing = ignore_face_codes(scene, ignore_regions(scene))
        P, UV, C, I, ranges, textures = [], [], [], [], [], []
        occ_colours = []  # per face: the occluder pass's colour (element code, shade bin)
        off = first = 0
        for g in sorted(self.groups, key=draw_priority):  # big occluders first: less overdraw
            m = g.material
            mult, ratio = lighting(face_normals(g.vertices, g.faces), look)
            r = shadow_ratio_levels(ratio)
            fcode = np.array([codes.get(e, 0) for e in g.element_ids])[g.face_element]
            for k, e in enumerate(g.element_ids):  # ignore regions' glazing: per face
                fc = glazing.get(e)
                if fc is not None:  # group_scene keeps a non-window mesh's faces whole, in order
                    fcode[g.face_element == k] = fc
            occ_colours.append(encode(np.stack([fcode % 256, fcode // 256, 1 + np.rint(254 * r),
                                                np.full(len(r), 255)], axis=1)))
            colour = np.ones((len(g.vertices), 4), np.float32)
            colour[g.faces.ravel(), :3] = np.repeat(mult, 3, axis=0)
            colour[g.faces.ravel(), 3] = np.repeat(np.where(r < 1, r, 2.0), 3)  # >= 1: never shaded
            tex = 0
            if m.texture is not None:
                tex = texture_rgb(m.texture)
                textures.append(tex)
            P.append(g.vertices); UV.append(g.uvs); C.append(colour); I.append(g.faces.ravel() + off)  # noqa: E702
            ranges.append((first, g.faces.size, tex, tuple(float(x) for x in m.rgb)))
            off += len(g.vertices)
            first += g.faces.size
        P, I = np.concatenate(P).astype(np.float32), np.concatenate(I)
        self._geom = Geometry(P, np.concatenate(UV), np.concatenate(C), I, ranges)
        self._geom.textures = textures
        # the occluder pass draws these very triangles in this order: coplanar faces resolve alike
        tris = P[I]
        shared = None if like is None else like.occluders.share(tris)
        self.occluders = shared or OccluderPass(scene, triangles=(tris, np.repeat(np.concatenate(occ_colours), 3, axis=0)))
        self.shadow = SunShadow(self.occluders, sun_direction(look)) if settings.shadows else None
        self._shadow_tex = texture_u16(self.shadow.map_u16()) if self.shadow is not None else 0
        self._empty_vao = GL.glGenVertexArrays(1)
        self._issued = None  # (camera, framebuffer) of the RGB pass visibility() issued
        GL.glFinish()

    def render_rgb(self, camera: Camera, prepass: bool = True) -> np.ndarray:
        """(H, W, 3) uint8 antialiased daylight image for the camera (distortion applied).
        prepass=False: without the occluder pass's depth as a pre-pass (plain GL_LESS depth test:
        the image the pre-pass must reproduce exactly)."""
        return self._read_rgb(camera, self._draw_rgb(camera, prepass))

    def _read_rgb(self, camera: Camera, fb: int) -> np.ndarray:
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        canvas = camera.canvas()
        self._gl.make_current()
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, fb)
        rgb = np.ascontiguousarray(read_rgba(canvas.width, canvas.height, 3))
        return distort_image(camera, rgb, nearest=False)

    def _draw_rgb(self, camera: Camera, prepass: bool = True) -> int:
        """Draw the RGB pass of ``camera.canvas()`` (the triangles and sky issued by
        :meth:`visibility` for this camera, else issued now; then antialiasing); return the
        framebuffer to read it from."""
        issued, self._issued = self._issued, None
        ready = prepass and issued is not None and issued[0] is camera
        fb = issued[1] if ready else self._issue_rgb(camera, prepass)
        return self._antialias(camera, fb)

    def _issue_rgb(self, camera: Camera, prepass: bool = True) -> int:
        """Issue the triangles and the sky of ``camera.canvas()``'s RGB pass (GL draws them
        asynchronously); return their framebuffer. Single-sampled, the occluder pass's depth (the
        same triangles in the same order) is its depth pre-pass unless ``prepass`` is False."""
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        gl, look, sh, aa = self._gl, self.look, self.shadow, self.settings.antialias
        canvas = camera.canvas()
        W, H = canvas.width, canvas.height
        gl.make_current()
        samples = MSAA_SAMPLES if aa == "msaa4" else 0
        # single-sampled: the occluder pass's depth (the same triangles) is the depth pre-pass
        depth = None if samples or not prepass else self.occluders.depth_of(canvas)
        fb = gl.fbs.bind(W, H, samples, texture=aa == "fxaa")
        if depth is not None:
            gl.fbs.copy_depth(depth, fb, W, H)
        begin(W, H, prepass=depth is not None)
        (GL.glEnable if samples else GL.glDisable)(GL.GL_MULTISAMPLE)
        # the house and the ground
        prog = gl.program("mesh")
        GL.glUseProgram(prog)
        GL.glUniformMatrix4fv(uniform(prog, "PV"), 1, GL.GL_TRUE, gl_view_projection(canvas).astype(np.float32))
        GL.glUniform1i(uniform(prog, "tex"), 0)
        GL.glUniform1i(uniform(prog, "shadow_map"), 1)
        GL.glUniform1i(uniform(prog, "shadows"), int(sh is not None))
        if sh is not None:
            GL.glActiveTexture(GL.GL_TEXTURE1)
            GL.glBindTexture(GL.GL_TEXTURE_2D, self._shadow_tex)
            GL.glUniformMatrix4fv(uniform(prog, "sun_from_world"), 1, GL.GL_TRUE, sh.sun_from_world.astype(np.float32))
            GL.glUniform1f(uniform(prog, "radius"), sh.radius)
            GL.glUniform1f(uniform(prog, "far"), sh.far)
            GL.glUniform1i(uniform(prog, "size"), sh.size)
            GL.glUniform1f(uniform(prog, "bias"), sh.bias)
            GL.glUniform3f(uniform(prog, "tint"), *SHADOW_TINT)
        self._geom.draw(prog)
        if depth is not None:
            end_prepass()
        # the sky where nothing was drawn (depth still at the far plane): shaded only there
        prog = gl.program("sky")
        GL.glUseProgram(prog)
        Minv = (canvas.R.T @ np.linalg.inv(canvas.K)).astype(np.float32)  # pixel (u, v, 1) -> world ray
        GL.glUniformMatrix3fv(uniform(prog, "Minv"), 1, GL.GL_TRUE, Minv)
        GL.glUniform1f(uniform(prog, "height"), float(H))
        GL.glUniform3f(uniform(prog, "horizon"), *look.sky_horizon)
        GL.glUniform3f(uniform(prog, "zenith"), *look.sky_zenith)
        GL.glDepthFunc(GL.GL_LEQUAL)
        GL.glDepthMask(GL.GL_FALSE)
        GL.glBindVertexArray(self._empty_vao)
        GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glBindVertexArray(0)
        GL.glUseProgram(0)
        GL.glFlush()
        return fb

    def _antialias(self, camera: Camera, fb: int) -> int:
        """Resolve (msaa4) or post-filter (fxaa) the issued RGB pass in ``fb``; return the
        framebuffer to read the image from."""
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        gl, aa = self._gl, self.settings.antialias
        canvas = camera.canvas()
        W, H = canvas.width, canvas.height
        gl.make_current()
        if aa == "msaa4":  # resolve the samples
            ms, fb = fb, gl.fbs.bind(W, H, 0, GL.GL_DRAW_FRAMEBUFFER)  # (binding may create it)
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, ms)
            GL.glBlitFramebuffer(0, 0, W, H, 0, 0, W, H, GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
        elif aa == "fxaa":  # post filter the rendered texture into a plain framebuffer
            fb = gl.fbs.bind(W, H, 0)
            GL.glDisable(GL.GL_DEPTH_TEST)
            prog = gl.program("fxaa")
            GL.glUseProgram(prog)
            GL.glBindVertexArray(self._empty_vao)
            GL.glUniform1i(uniform(prog, "img"), 0)
            GL.glActiveTexture(GL.GL_TEXTURE0)
            GL.glBindTexture(GL.GL_TEXTURE_2D, gl.fbs.texture(W, H))
            GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
            GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
            GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glBindVertexArray(0)
        GL.glUseProgram(0)
        GL.glFlush()
        return fb

    def visibility(self, camera: Camera) -> tuple[WindowView, ...]:
        """The sampler's visibility test (RENDERERS["pyrender"]): the occluder pass's per-window
        ground truth, kept for :meth:`render` of this camera (OccluderPass.truth). As soon as the
        pass is read, the candidate's RGB triangles are issued with its depth as their pre-pass,
        so that GL draws them while Python computes the ground truth (wasted on a rejected one)."""
        def issue() -> None:
            self._issued = (camera, self._issue_rgb(camera))

        return self.occluders.truth(camera, keep=True, meanwhile=issue)[2]

    def render(self, camera: Camera) -> RenderOutput:
        """The view of ``camera``: the RGB pass, and the ground truth of the occluder pass (drawn by
        the sampler's visibility test when it accepted this camera: OccluderPass.truth), whose depth
        is the RGB pass's depth pre-pass."""
        inst, depth, wins, (ign, regions) = self.occluders.truth(camera)
        fb = self._draw_rgb(camera)
        return RenderOutput(camera, self._read_rgb(camera, fb), inst, depth, wins,
                            ign if regions else None, regions)

    def close(self) -> None:
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        if self._geom is not None:
            self._gl.make_current()
            self._geom.delete()
            if self._shadow_tex:
                GL.glDeleteTextures(1, [self._shadow_tex])
            GL.glDeleteVertexArrays(1, [self._empty_vao])
            self._geom = None
            self._gl.release()
        self.occluders.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
