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
  the void rectangles exactly at pixel centres. Without MSAA the RGB pass writes it as a second
  render target (same triangles, same depth); :class:`OccluderPass` draws it on its own.
Draw order is fixed (sorted groups, never pyrender's set order), so coincident faces resolve the
same way in every GL context and the same seed gives byte-identical images. pyrender is only used
for its headless EGL context (llvmpipe here).
Use as a context manager or call ``close()`` (a live EGL context at exit can segfault).
"""
from __future__ import annotations

import atexit
import ctypes

import numpy as np

from fenestra.compat import import_pyrender
from fenestra.conventions import PYRENDER_PIXEL_OFFSET, cv_to_gl_pose
from renders.base import RenderOutput, RenderSettings
from renders.camera import Camera, distort_image
from renders.gt import void_instances, window_views
from renders.materials import face_normals, group_scene, ground_z, lighting, sample_look, sun_direction
from scenes.model import Scene

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


def ground_quad(scene: Scene, half_size_m: float = 200.0) -> tuple[np.ndarray, np.ndarray]:
    """Ground plane square (4, 3) vertices, (2, 3) faces (upward), centred under the scene."""
    gz = ground_z(scene) - 0.002
    c, h = scene.bounds().mean(axis=0), half_size_m
    v = np.array([[c[0] - h, c[1] - h, gz], [c[0] + h, c[1] - h, gz], [c[0] + h, c[1] + h, gz], [c[0] - h, c[1] + h, gz]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


# ------------------------------------------------------------------------------------ GL plumbing
_MESH_VS = """#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec2 texcoord;
layout(location = 2) in vec4 colour;
layout(location = 3) in vec4 code;
uniform mat4 PV;
uniform mat4 sun_from_world;
out vec3 spos;
out vec2 uv;
out vec4 col;
flat out vec4 vcode;
void main() {
    gl_Position = PV * vec4(position, 1.0);
    vcode = code;
    spos = (sun_from_world * vec4(position, 1.0)).xyz;  // affine: interpolates exactly
    uv = texcoord;
    col = colour;
}
"""
# col.rgb: baked light multiplier; col.a: quantised shadow ratio (>= 1: never shaded)
_MESH_FS = """#version 330 core
in vec3 spos;
in vec2 uv;
in vec4 col;
flat in vec4 vcode;
uniform sampler2D tex;
uniform int textured;
uniform vec3 base;
uniform sampler2D shadow_map;
uniform int shadows;
uniform float radius;
uniform float far;
uniform int size;
uniform float bias;
uniform vec3 tint;
layout(location = 0) out vec4 frag;
layout(location = 1) out vec4 code_out;  // the occluder pass's colour (element code, shade bin)
void main() {
    code_out = vcode;
    vec3 c = base * col.rgb;
    if (textured != 0) c *= texture(tex, uv).rgb;
    if (shadows != 0 && col.a < 1.0) {
        vec3 s = spos;
        ivec2 ij = ivec2(floor(vec2((s.x / radius + 1.0) * 0.5 * float(size) - 0.5,
                                    (1.0 - s.y / radius) * 0.5 * float(size) - 0.5) + 0.5));
        if (all(greaterThanEqual(ij, ivec2(0))) && all(lessThan(ij, ivec2(size)))) {
            float d = texelFetch(shadow_map, ij, 0).r * far;
            if (d > 0.0 && -s.z > d + bias) c *= col.a * tint;
        }
    }
    frag = vec4(clamp(c, 0.0, 1.0), 1.0);
}
"""
_CODE_VS = """#version 330 core
layout(location = 0) in vec3 position;
layout(location = 2) in vec4 colour;
uniform mat4 PV;
flat out vec4 col;
void main() { gl_Position = PV * vec4(position, 1.0); col = colour; }
"""
_CODE_FS = """#version 330 core
flat in vec4 col;
out vec4 frag;
void main() { frag = col; }
"""
# full-screen sky: world direction of pixel (u, v) = Minv (u, v, 1); u, v OpenCV pixel coordinates
_SKY_VS = """#version 330 core
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2)) * 2.0 - 1.0;
    gl_Position = vec4(p, 1.0, 1.0);
}
"""
_SKY_FS = """#version 330 core
uniform mat3 Minv;
uniform float height;
uniform vec3 horizon;
uniform vec3 zenith;
out vec4 frag;
void main() {
    vec3 d = normalize(Minv * vec3(gl_FragCoord.x - 0.5, height - 0.5 - gl_FragCoord.y, 1.0));
    float w = pow(clamp(d.z, 0.0, 1.0), 0.6);
    frag = vec4(clamp((1.0 - w) * horizon + w * zenith, 0.0, 1.0), 1.0);
}
"""


# FXAA (Lottes' FXAA 3 "console" variant): where the local luma contrast exceeds FXAA's edge
# threshold, average 2 or 4 taps along the edge direction; elsewhere the pixel is left as rendered
_FXAA_FS = """#version 330 core
uniform sampler2D img;
out vec4 frag;
void main() {
    ivec2 size = textureSize(img, 0);
    vec2 inv = 1.0 / vec2(size);
    vec2 p = gl_FragCoord.xy * inv;
    ivec2 ij = ivec2(gl_FragCoord.xy), lo = max(ij - 1, ivec2(0)), hi = min(ij + 1, size - 1);
    vec3 nw = texelFetch(img, ivec2(lo.x, lo.y), 0).rgb;  // the four diagonal neighbours, clamped
    vec3 ne = texelFetch(img, ivec2(hi.x, lo.y), 0).rgb;
    vec3 sw = texelFetch(img, ivec2(lo.x, hi.y), 0).rgb;
    vec3 se = texelFetch(img, ivec2(hi.x, hi.y), 0).rgb;
    vec3 m = texelFetch(img, ij, 0).rgb;
    vec3 w = vec3(0.299, 0.587, 0.114);
    float lnw = dot(nw, w), lne = dot(ne, w), lsw = dot(sw, w), lse = dot(se, w), lm = dot(m, w);
    float lmin = min(lm, min(min(lnw, lne), min(lsw, lse)));
    float lmax = max(lm, max(max(lnw, lne), max(lsw, lse)));
    if (lmax - lmin < max(1.0 / 32.0, lmax / 8.0)) { frag = vec4(m, 1.0); return; }  // no edge here
    vec2 dir = vec2(-((lnw + lne) - (lsw + lse)), (lnw + lsw) - (lne + lse));
    float reduce = max((lnw + lne + lsw + lse) * (0.25 / 8.0), 1.0 / 128.0);
    float rcp = 1.0 / (min(abs(dir.x), abs(dir.y)) + reduce);
    dir = clamp(dir * rcp, vec2(-8.0), vec2(8.0)) * inv;
    vec3 a = 0.5 * (texture(img, p + dir * (1.0 / 3.0 - 0.5)).rgb + texture(img, p + dir * (2.0 / 3.0 - 0.5)).rgb);
    vec3 b = a * 0.5 + 0.25 * (texture(img, p - dir * 0.5).rgb + texture(img, p + dir * 0.5).rgb);
    float lb = dot(b, w);
    frag = vec4((lb < lmin || lb > lmax) ? a : b, 1.0);
}
"""


class GLContext:
    """One process-wide EGL context (from a pyrender OffscreenRenderer) shared by all passes.

    pyrender's EGL teardown terminates the display, so the context is reference counted and
    closed with its last user. Programs are compiled once per context.
    """

    _shared: "GLContext | None" = None

    def __init__(self):
        self.pr = import_pyrender()
        self.osr = self.pr.OffscreenRenderer(64, 64)
        self.users = 0
        self._programs: dict[str, int] = {}
        self.fbs = _Framebuffers()

    @classmethod
    def acquire(cls) -> "GLContext":
        if cls._shared is None:
            cls._shared = GLContext()
        cls._shared.users += 1
        return cls._shared

    def make_current(self) -> None:
        self.osr._platform.make_current()

    def program(self, name: str) -> int:
        from OpenGL.GL import GL_FRAGMENT_SHADER, GL_VERTEX_SHADER
        from OpenGL.GL.shaders import compileProgram, compileShader

        if name not in self._programs:
            vs, fs = {"mesh": (_MESH_VS, _MESH_FS), "code": (_CODE_VS, _CODE_FS), "sky": (_SKY_VS, _SKY_FS),
                      "fxaa": (_SKY_VS, _FXAA_FS)}[name]
            # validate=False: core profile needs a bound VAO to validate, and none is bound yet
            self._programs[name] = int(compileProgram(compileShader(vs, GL_VERTEX_SHADER),
                                                      compileShader(fs, GL_FRAGMENT_SHADER), validate=False))
        return self._programs[name]

    def release(self) -> None:
        """One user is done; close the context when the last one is gone."""
        self.users -= 1
        if self.users <= 0 and GLContext._shared is self:
            self.osr.delete()
            GLContext._shared = None


@atexit.register
def _close_shared_context() -> None:
    if GLContext._shared is not None:
        GLContext._shared.osr.delete()
        GLContext._shared = None


def _uniform(prog: int, name: str):
    from OpenGL.GL import glGetUniformLocation

    return glGetUniformLocation(prog, name)


class _Geometry:
    """Triangles uploaded once: positions (N, 3), uvs (N, 2), colours (N, 4), optional codes
    (N, 4) float32 (attribute locations 0-3) and uint32 indices, drawn as ranges
    ``(first index, count, texture id or 0, base rgb)`` in list order."""

    def __init__(self, positions, uvs, colours, indices, ranges, codes=None):
        from OpenGL import GL

        self.vao = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(self.vao)
        attrs = (positions, uvs, colours) if codes is None else (positions, uvs, colours, codes)
        self.buffers = [int(b) for b in GL.glGenBuffers(len(attrs) + 1)]
        for loc, (buf, arr) in enumerate(zip(self.buffers[:-1], attrs)):
            arr = np.ascontiguousarray(arr, np.float32)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, buf)
            GL.glBufferData(GL.GL_ARRAY_BUFFER, arr.nbytes, arr, GL.GL_STATIC_DRAW)
            GL.glEnableVertexAttribArray(loc)
            GL.glVertexAttribPointer(loc, arr.shape[1], GL.GL_FLOAT, GL.GL_FALSE, 0, ctypes.c_void_p(0))
        idx = np.ascontiguousarray(indices, np.uint32).ravel()
        GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, self.buffers[-1])
        GL.glBufferData(GL.GL_ELEMENT_ARRAY_BUFFER, idx.nbytes, idx, GL.GL_STATIC_DRAW)
        GL.glBindVertexArray(0)
        self.ranges = ranges
        self.textures: list[int] = []

    def draw(self, prog: int | None = None) -> None:
        from OpenGL import GL

        GL.glBindVertexArray(self.vao)
        for first, count, tex, base in self.ranges:
            if prog is not None:
                GL.glUniform1i(_uniform(prog, "textured"), int(tex != 0))
                GL.glUniform3f(_uniform(prog, "base"), *base)
                GL.glActiveTexture(GL.GL_TEXTURE0)
                GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
            GL.glDrawElements(GL.GL_TRIANGLES, count, GL.GL_UNSIGNED_INT, ctypes.c_void_p(4 * first))
        GL.glBindVertexArray(0)

    def delete(self) -> None:
        from OpenGL import GL

        GL.glDeleteBuffers(len(self.buffers), self.buffers)
        GL.glDeleteVertexArrays(1, [self.vao])
        if self.textures:
            GL.glDeleteTextures(len(self.textures), self.textures)


def _texture_rgb(img: np.ndarray) -> int:
    """Upload an (H, W, 3) uint8 texture, mipmapped and repeating (pyrender's orientation: row 0 of
    the image at v = 1)."""
    from OpenGL import GL

    tex = GL.glGenTextures(1)
    GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
    GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
    data = np.ascontiguousarray(img[::-1], np.uint8)
    GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, GL.GL_RGB, img.shape[1], img.shape[0], 0, GL.GL_RGB, GL.GL_UNSIGNED_BYTE, data)
    GL.glGenerateMipmap(GL.GL_TEXTURE_2D)
    GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_MAG_FILTER, GL.GL_LINEAR)
    GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR_MIPMAP_LINEAR)
    GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_WRAP_S, GL.GL_REPEAT)
    GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_WRAP_T, GL.GL_REPEAT)
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
    return int(tex)


def _texture_u16(img: np.ndarray) -> int:
    """Upload an (H, W) uint16 map as a nearest-sampled R16 texture (texel (x, y) = img[y, x])."""
    from OpenGL import GL

    tex = GL.glGenTextures(1)
    GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
    GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 2)
    data = np.ascontiguousarray(img, np.uint16)
    GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, GL.GL_R16, img.shape[1], img.shape[0], 0, GL.GL_RED, GL.GL_UNSIGNED_SHORT,
                    data)
    for p, v in ((GL.GL_TEXTURE_MAG_FILTER, GL.GL_NEAREST), (GL.GL_TEXTURE_MIN_FILTER, GL.GL_NEAREST),
                 (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
        GL.glTexParameteri(GL.GL_TEXTURE_2D, p, v)
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
    return int(tex)


class _Framebuffers:
    """Offscreen framebuffers (RGBA8 colour + 24-bit depth) by (width, height, samples, texture):
    colour in a renderbuffer, or in a texture (single-sampled, for post filters)."""

    def __init__(self):
        self._fbs: dict[tuple, tuple[int, list[int], int]] = {}

    def bind(self, width: int, height: int, samples: int = 0, target=None, texture: bool = False,
             tag: str = "", codes: bool = False) -> int:
        """Bind (creating it if needed) the framebuffer of this size, kind and user tag; return it.
        codes: add a second RGBA8 colour attachment (COLOR_ATTACHMENT1) for element codes."""
        from OpenGL import GL

        key = (width, height, samples, texture, tag, codes)
        if key not in self._fbs:
            if len(self._fbs) >= 8:  # canvases of distorted cameras vary in size: keep this size only
                self.delete(keep=(width, height))
            fmts = (GL.GL_RGBA8, GL.GL_DEPTH_COMPONENT24) + ((GL.GL_RGBA8,) if codes else ())
            rbs = [int(x) for x in GL.glGenRenderbuffers(len(fmts))]
            for rb, fmt in zip(rbs, fmts):
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, samples, fmt, width, height)
            fb = int(GL.glGenFramebuffers(1))
            GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fb)
            tex = 0
            if texture:
                tex = int(GL.glGenTextures(1))
                GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
                GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, GL.GL_RGBA8, width, height, 0, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE,
                                None)
                for p, v in ((GL.GL_TEXTURE_MAG_FILTER, GL.GL_LINEAR), (GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR),
                             (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
                    GL.glTexParameteri(GL.GL_TEXTURE_2D, p, v)
                GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
                GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D, tex, 0)
            else:
                GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, rbs[0])
            GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, rbs[1])
            if codes:
                GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT1, GL.GL_RENDERBUFFER, rbs[2])
            if GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER) != GL.GL_FRAMEBUFFER_COMPLETE:
                raise RuntimeError(f"incomplete framebuffer {key}")
            self._fbs[key] = (fb, rbs, tex)
        fb = self._fbs[key][0]
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER if target is None else target, fb)
        return fb

    def texture(self, width: int, height: int, codes: bool = False) -> int:
        """The colour texture of the (width, height) texture framebuffer (after bind)."""
        return self._fbs[(width, height, 0, True, "", codes)][2]

    def delete(self, keep: tuple[int, int] | None = None) -> None:
        """Delete the framebuffers (but those of size ``keep``)."""
        from OpenGL import GL

        for key in [k for k in self._fbs if k[:2] != keep]:
            fb, rbs, tex = self._fbs.pop(key)
            GL.glDeleteFramebuffers(1, [fb])
            GL.glDeleteRenderbuffers(len(rbs), rbs)
            if tex:
                GL.glDeleteTextures(1, [tex])


def _begin(width: int, height: int) -> None:
    from OpenGL import GL

    GL.glViewport(0, 0, width, height)
    GL.glEnable(GL.GL_DEPTH_TEST)
    GL.glDepthMask(GL.GL_TRUE)
    GL.glDepthFunc(GL.GL_LESS)
    GL.glDisable(GL.GL_CULL_FACE)  # IFC winding varies: every triangle is two-sided
    GL.glDisable(GL.GL_BLEND)
    GL.glClearColor(0.0, 0.0, 0.0, 0.0)
    GL.glClearDepth(1.0)
    GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)


def _read_rgba(width: int, height: int, channels: int = 4) -> np.ndarray:
    """(H, W, channels) uint8 of the bound read framebuffer, top row first."""
    from OpenGL import GL

    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
    fmt = GL.GL_RGBA if channels == 4 else GL.GL_RGB
    buf = GL.glReadPixels(0, 0, width, height, fmt, GL.GL_UNSIGNED_BYTE)
    return np.frombuffer(buf, np.uint8).reshape(height, width, channels)[::-1]


def _read_depth(width: int, height: int) -> np.ndarray:
    """(H, W) float32 window depth in [0, 1] of the bound read framebuffer, top row first."""
    from OpenGL import GL

    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 4)
    buf = GL.glReadPixels(0, 0, width, height, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT)
    return np.frombuffer(buf, np.float32).reshape(height, width)[::-1]


def _encode(k: np.ndarray) -> np.ndarray:
    """uint8 levels -> floats that any float-to-unorm8 conversion (rounding or truncating) maps back."""
    return (np.asarray(k, np.float32) + 0.25) / 255.0


class OccluderPass:
    """Exact depth + element-code images (no antialiasing) of a scene, for ground truth.

    The colour of a pixel encodes the element code (window i's element = i + 1, other geometry 0)
    in R + 256 G; B is 1 + 254 * the face's shadow ratio when ``shade`` is given (else 255).
    All triangles are one vertex buffer drawn in one call, two-sided, in a fixed order.
    """

    def __init__(self, scene: Scene, shade=None):
        from OpenGL import GL

        self.scene = scene
        self.codes, self.window_codes = element_codes(scene)
        parts: dict[tuple[int, int], list[np.ndarray]] = {}
        gv, gf = ground_quad(scene)
        items = [(self.codes.get(m.global_id, 0), m.vertices, m.faces) for m in scene.meshes] + [(0, gv, gf)]
        for code, v, f in items:
            if shade is None:
                bins = np.full(len(f), 255)
            else:
                q = np.rint(SHADE_LEVELS * np.clip(shade(face_normals(v, f)), 0, 1)) / SHADE_LEVELS
                bins = 1 + np.rint(254 * q).astype(int)
            for b in np.unique(bins):
                parts.setdefault((code, int(b)), []).append(np.asarray(v, np.float64)[f[bins == b]].reshape(-1, 3))
        P, C = [], []
        for (code, b), tris in sorted(parts.items()):
            p = np.concatenate(tris)
            P.append(p)
            C.append(np.broadcast_to(_encode([code % 256, code // 256, b, 255]), (len(p), 4)))
        P = np.concatenate(P).astype(np.float32)
        self._gl = GLContext.acquire()
        self._gl.make_current()
        self._geom = _Geometry(P, np.zeros((len(P), 2), np.float32), np.concatenate(C),
                               np.arange(len(P), dtype=np.uint32), [(0, len(P), 0, (1.0, 1.0, 1.0))])
        GL.glFinish()

    def _draw(self, PV: np.ndarray, width: int, height: int) -> int:
        """Issue the pass (GL renders it asynchronously); return its framebuffer."""
        from OpenGL import GL

        gl = self._gl
        gl.make_current()
        fb = gl.fbs.bind(width, height, 0, tag="occluders")
        _begin(width, height)
        prog = gl.program("code")
        GL.glUseProgram(prog)
        GL.glUniformMatrix4fv(_uniform(prog, "PV"), 1, GL.GL_TRUE, PV.astype(np.float32))
        self._geom.draw()
        GL.glUseProgram(0)
        GL.glFlush()
        return fb

    def render_full(self, cam: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pinhole camera -> depth (H, W) float32 m (0 = nothing), element codes (H, W) int32
        (-1 = nothing) and the B channel (H, W) uint8 (shadow-ratio bin, 0 = nothing)."""
        return self._read(cam, self._draw(gl_view_projection(cam), cam.width, cam.height))

    def _read(self, cam: Camera, fb: int, attachment: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self._gl.make_current()
        return read_occluder_pass(fb, cam.width, cam.height, attachment)

    def render(self, cam: Camera) -> tuple[np.ndarray, np.ndarray]:
        """Pinhole camera -> depth (H, W) float32 m (0 = nothing) and element codes (H, W) int32."""
        depth, code, _ = self.render_full(cam)
        return depth, code

    def render_ortho_depth(self, pose: np.ndarray, half_extent: float, far: float, size: int) -> np.ndarray:
        """Orthographic depth map (size, size) float32, m along the view axis (0 = nothing).

        pose: 4x4 OpenGL camera-to-world (looks along its -z); covers +-half_extent m.
        """
        from OpenGL import GL

        n, f = 0.01, far
        P = np.zeros((4, 4))
        P[0, 0] = P[1, 1] = 1.0 / half_extent
        P[2, 2], P[2, 3], P[3, 3] = 2.0 / (n - f), (f + n) / (n - f), 1.0
        fb = self._draw(P @ np.linalg.inv(pose), size, size)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, fb)
        d = _read_depth(size, size)
        out = np.zeros((size, size), np.float32)
        hit = d < 1.0
        out[hit] = ((2.0 * d[hit] - 1.0) * (f - n) + (f + n)) / 2
        return out

    def close(self) -> None:
        if self._geom is not None:
            self._gl.make_current()
            self._geom.delete()
            self._geom = None
            self._gl.release()


def read_occluder_pass(fb: int, W: int, H: int, attachment: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a finished occluder pass (colour attachment ``attachment`` + depth of ``fb``):
    depth (H, W) float32 m (0 = nothing), element codes (H, W) int32 (-1 = nothing), B channel uint8."""
    from OpenGL import GL

    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, fb)
    GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0 + attachment)
    col = _read_rgba(W, H)
    GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0)
    d = _read_depth(W, H)
    rgba = np.ascontiguousarray(col).view(np.uint32)[..., 0]  # little endian: R + 256 G + 65536 B ...
    code = (rgba & 0xFFFF).astype(np.int32)
    shade = np.ascontiguousarray(col[..., 2])
    code[shade == 0] = -1
    # window depth -> camera z (float32, pyrender's formula); 0 where nothing was drawn
    n, f = np.float32(ZNEAR), np.float32(ZFAR)
    depth = (2 * n * f) / (f + n - (2 * d - 1) * (f - n))
    depth[d >= 1] = 0
    return depth, code, shade


def ground_truth(occ: OccluderPass, camera: Camera):
    """Instance map (H, W) uint16, depth (H, W) float32, per-window views and the canvas pass."""
    return _ground_truth(occ, camera, *occ.render_full(camera.canvas()))


def _ground_truth(occ: OccluderPass, camera: Camera, depth_c, code_c, shade_c):
    canvas = camera.canvas()
    maps = None if camera.dist is None else camera.canvas_maps()
    inst, _ = void_instances(canvas, occ.scene.windows, depth_c, code_c, occ.window_codes, maps)
    depth = distort_image(camera, depth_c, nearest=True)
    wins = window_views(camera, occ.scene.windows, inst, depth_c, code_c, occ.window_codes)
    return inst, depth, wins, (depth_c, shade_c)


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
        return np.minimum(np.ceil(self.map / self.far * 65535.0), 65535).astype(np.uint16)

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
    """

    name = "pyrender"

    def __init__(self, scene: Scene, settings: RenderSettings = RenderSettings()):
        from OpenGL import GL

        self.scene, self.settings = scene, settings
        rng = np.random.default_rng(settings.seed)
        self.look = look = sample_look(rng)
        self.groups = group_scene(scene, look, rng)
        self.occluders = OccluderPass(scene, shade=lambda n: lighting(n, look)[1])
        self.shadow = SunShadow(self.occluders, sun_direction(look)) if settings.shadows else None
        self._gl = GLContext.acquire()
        self._gl.make_current()
        P, UV, C, I, ranges, textures = [], [], [], [], [], []
        off = first = 0
        codes = []  # per vertex: the occluder pass's colour, for the single-sample passes (MRT)
        for g in sorted(self.groups, key=draw_priority):  # big occluders first: less overdraw
            m = g.material
            mult, ratio = lighting(face_normals(g.vertices, g.faces), look)
            r = shadow_ratio_levels(ratio)
            fcode = np.array([self.occluders.codes.get(e, 0) for e in g.element_ids])[g.face_element]
            enc = np.zeros((len(g.vertices), 4), np.float32)
            enc[g.faces.ravel()] = np.repeat(_encode(np.stack([fcode % 256, fcode // 256, 1 + np.rint(254 * r),
                                                               np.full(len(r), 255)], axis=1)), 3, axis=0)
            codes.append(enc)
            colour = np.ones((len(g.vertices), 4), np.float32)
            colour[g.faces.ravel(), :3] = np.repeat(mult, 3, axis=0)
            colour[g.faces.ravel(), 3] = np.repeat(np.where(r < 1, r, 2.0), 3)  # >= 1: never shaded
            tex = 0
            if m.texture is not None:
                tex = _texture_rgb(m.texture)
                textures.append(tex)
            P.append(g.vertices); UV.append(g.uvs); C.append(colour); I.append(g.faces.ravel() + off)  # noqa: E702
            ranges.append((first, g.faces.size, tex, tuple(float(x) for x in m.rgb)))
            off += len(g.vertices)
            first += g.faces.size
        self._geom = _Geometry(np.concatenate(P), np.concatenate(UV), np.concatenate(C), np.concatenate(I), ranges,
                               codes=np.concatenate(codes))
        self._geom.textures = textures
        self._shadow_tex = _texture_u16(self.shadow.map_u16()) if self.shadow is not None else 0
        self._empty_vao = GL.glGenVertexArrays(1)
        GL.glFinish()

    def render_rgb(self, camera: Camera) -> np.ndarray:
        """(H, W, 3) uint8 antialiased daylight image for the camera (distortion applied)."""
        return self._read_rgb(camera, self._draw_rgb(camera))

    def _read_rgb(self, camera: Camera, fb: int) -> np.ndarray:
        from OpenGL import GL

        canvas = camera.canvas()
        self._gl.make_current()
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, fb)
        rgb = np.ascontiguousarray(_read_rgba(canvas.width, canvas.height, 3))
        return distort_image(camera, rgb, nearest=False)

    def _draw_rgb(self, camera: Camera) -> int:
        """Issue the RGB pass of ``camera.canvas()`` (GL renders it asynchronously); return the
        framebuffer to read it from."""
        from OpenGL import GL

        gl, look, sh, aa = self._gl, self.look, self.shadow, self.settings.antialias
        canvas = camera.canvas()
        W, H = canvas.width, canvas.height
        gl.make_current()
        samples = MSAA_SAMPLES if aa == "msaa4" else 0
        codes = samples == 0  # single-sampled: the occluder pass comes along as a second target
        fb = gl.fbs.bind(W, H, samples, texture=aa == "fxaa", codes=codes)
        self._codes_fb = fb if codes else None
        if codes:
            GL.glDrawBuffers(2, [GL.GL_COLOR_ATTACHMENT0, GL.GL_COLOR_ATTACHMENT1])
        _begin(W, H)
        (GL.glEnable if samples else GL.glDisable)(GL.GL_MULTISAMPLE)
        # the house and the ground
        prog = gl.program("mesh")
        GL.glUseProgram(prog)
        GL.glUniformMatrix4fv(_uniform(prog, "PV"), 1, GL.GL_TRUE, gl_view_projection(canvas).astype(np.float32))
        GL.glUniform1i(_uniform(prog, "tex"), 0)
        GL.glUniform1i(_uniform(prog, "shadow_map"), 1)
        GL.glUniform1i(_uniform(prog, "shadows"), int(sh is not None))
        if sh is not None:
            GL.glActiveTexture(GL.GL_TEXTURE1)
            GL.glBindTexture(GL.GL_TEXTURE_2D, self._shadow_tex)
            GL.glUniformMatrix4fv(_uniform(prog, "sun_from_world"), 1, GL.GL_TRUE, sh.sun_from_world.astype(np.float32))
            GL.glUniform1f(_uniform(prog, "radius"), sh.radius)
            GL.glUniform1f(_uniform(prog, "far"), sh.far)
            GL.glUniform1i(_uniform(prog, "size"), sh.size)
            GL.glUniform1f(_uniform(prog, "bias"), sh.bias)
            GL.glUniform3f(_uniform(prog, "tint"), *SHADOW_TINT)
        self._geom.draw(prog)
        if codes:
            GL.glDrawBuffers(1, [GL.GL_COLOR_ATTACHMENT0])
        # the sky where nothing was drawn (depth still at the far plane): shaded only there
        prog = gl.program("sky")
        GL.glUseProgram(prog)
        Minv = (canvas.R.T @ np.linalg.inv(canvas.K)).astype(np.float32)  # pixel (u, v, 1) -> world ray
        GL.glUniformMatrix3fv(_uniform(prog, "Minv"), 1, GL.GL_TRUE, Minv)
        GL.glUniform1f(_uniform(prog, "height"), float(H))
        GL.glUniform3f(_uniform(prog, "horizon"), *look.sky_horizon)
        GL.glUniform3f(_uniform(prog, "zenith"), *look.sky_zenith)
        GL.glDepthFunc(GL.GL_LEQUAL)
        GL.glDepthMask(GL.GL_FALSE)
        GL.glBindVertexArray(self._empty_vao)
        GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        if aa == "msaa4":  # resolve the samples
            ms, fb = fb, gl.fbs.bind(W, H, 0, GL.GL_DRAW_FRAMEBUFFER)  # (binding may create it)
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, ms)
            GL.glBlitFramebuffer(0, 0, W, H, 0, 0, W, H, GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
        elif aa == "fxaa":  # post filter the rendered texture into a plain framebuffer
            fb = gl.fbs.bind(W, H, 0)
            GL.glDisable(GL.GL_DEPTH_TEST)
            prog = gl.program("fxaa")
            GL.glUseProgram(prog)
            GL.glUniform1i(_uniform(prog, "img"), 0)
            GL.glActiveTexture(GL.GL_TEXTURE0)
            GL.glBindTexture(GL.GL_TEXTURE_2D, gl.fbs.texture(W, H, codes))
            GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
            GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
            GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glBindVertexArray(0)
        GL.glUseProgram(0)
        GL.glFlush()
        return fb

    def render(self, camera: Camera) -> RenderOutput:
        occ, canvas = self.occluders, camera.canvas()
        if self.settings.antialias == "msaa4":  # the occluder pass separately, single-sampled
            occ_pass = occ.render_full(canvas)
            fb = self._draw_rgb(camera)
        else:  # the RGB pass wrote the occluder pass's codes and depth too
            fb = self._draw_rgb(camera)
            self._gl.make_current()
            occ_pass = read_occluder_pass(self._codes_fb, canvas.width, canvas.height, attachment=1)
        inst, depth, wins, _ = _ground_truth(occ, camera, *occ_pass)
        return RenderOutput(camera, self._read_rgb(camera, fb), inst, depth, wins)

    def close(self) -> None:
        from OpenGL import GL

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
