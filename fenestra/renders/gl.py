"""Low-level OpenGL plumbing of the raster backend (:mod:`renders.raster`): the process-wide EGL
context borrowed from pyrender with its compiled programs (:class:`GLContext`), vertex-buffer
geometry drawn in fixed ranges (:class:`Geometry`), texture uploads, cached offscreen framebuffers
(:class:`Framebuffers`), per-pass GL state (:func:`begin`), colour and depth read-back, and the
uint8-level encoding of element codes as colours (:func:`encode`). Nothing here knows about scenes,
cameras or materials.
"""
from __future__ import annotations

import atexit
import ctypes

import numpy as np

from fenestra.compat import import_pyrender
from fenestra.renders.shaders import CODE_FS, CODE_VS, FXAA_FS, MESH_FS, MESH_VS, SKY_FS, SKY_VS


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
        self.fbs = Framebuffers()

    @classmethod
    def acquire(cls) -> "GLContext":
        if cls._shared is None:
            cls._shared = GLContext()
        cls._shared.users += 1
        return cls._shared

    def make_current(self) -> None:
        self.osr._platform.make_current()

    def program(self, name: str) -> int:
        from OpenGL.GL import GL_FRAGMENT_SHADER, GL_VERTEX_SHADER  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)
        from OpenGL.GL.shaders import compileProgram, compileShader  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        if name not in self._programs:
            vs, fs = {"mesh": (MESH_VS, MESH_FS), "code": (CODE_VS, CODE_FS), "sky": (SKY_VS, SKY_FS),
                      "fxaa": (SKY_VS, FXAA_FS)}[name]
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


def uniform(prog: int, name: str):
    """Location of a uniform in a program."""
    from OpenGL.GL import glGetUniformLocation  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

    return glGetUniformLocation(prog, name)


class Geometry:
    """Triangles uploaded once: positions (N, 3), uvs (N, 2), colours (N, 4) float32 (attribute
    locations 0-2) and uint32 indices, drawn as ranges ``(first index, count, texture id or 0,
    base rgb)`` in list order."""

    def __init__(self, positions, uvs, colours, indices, ranges):
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        self.vao = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(self.vao)
        attrs = (positions, uvs, colours)
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
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        GL.glBindVertexArray(self.vao)
        for first, count, tex, base in self.ranges:
            if prog is not None:
                GL.glUniform1i(uniform(prog, "textured"), int(tex != 0))
                GL.glUniform3f(uniform(prog, "base"), *base)
                GL.glActiveTexture(GL.GL_TEXTURE0)
                GL.glBindTexture(GL.GL_TEXTURE_2D, tex)
            GL.glDrawElements(GL.GL_TRIANGLES, count, GL.GL_UNSIGNED_INT, ctypes.c_void_p(4 * first))
        GL.glBindVertexArray(0)

    def delete(self) -> None:
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        GL.glDeleteBuffers(len(self.buffers), self.buffers)
        GL.glDeleteVertexArrays(1, [self.vao])
        if self.textures:
            GL.glDeleteTextures(len(self.textures), self.textures)


def texture_rgb(img: np.ndarray) -> int:
    """Upload an (H, W, 3) uint8 texture, mipmapped and repeating (pyrender's orientation: row 0 of
    the image at v = 1)."""
    from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

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


def texture_u16(img: np.ndarray) -> int:
    """Upload an (H, W) uint16 map as a nearest-sampled R16 texture (texel (x, y) = img[y, x])."""
    from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

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


class Framebuffers:
    """Offscreen framebuffers (RGBA8 colour + 24-bit depth, 8-bit stencil) by (width, height, samples, texture):
    colour in a renderbuffer, or in a texture (single-sampled, for post filters)."""

    def __init__(self):
        self._fbs: dict[tuple, tuple[int, list[int], int]] = {}
        self._marks: dict[int, object] = {}  # framebuffer -> what its last pass drew (mark / holds)

    def mark(self, fb: int, what) -> None:
        """Record what was just drawn into ``fb`` (any value compared with ==)."""
        self._marks[fb] = what

    def holds(self, fb: int, what) -> bool:
        """True when the last pass :meth:`mark` ed into ``fb`` is ``what`` (a framebuffer deleted
        and created again holds nothing)."""
        return self._marks.get(fb, None) == what

    def bind(self, width: int, height: int, samples: int = 0, target=None, texture: bool = False,
             tag: str = "") -> int:
        """Bind (creating it if needed) the framebuffer of this size, kind and user tag; return it."""
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        key = (width, height, samples, texture, tag)
        if key not in self._fbs:
            if len(self._fbs) >= 8:  # canvases of distorted cameras vary in size: keep this size only
                self.delete(keep=(width, height))
            fmts = (GL.GL_RGBA8, GL.GL_DEPTH24_STENCIL8)
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
            GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT, GL.GL_RENDERBUFFER, rbs[1])
            if GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER) != GL.GL_FRAMEBUFFER_COMPLETE:
                raise RuntimeError(f"incomplete framebuffer {key}")
            self._fbs[key] = (fb, rbs, tex)
        fb = self._fbs[key][0]
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER if target is None else target, fb)
        return fb

    def copy_depth(self, src: int, dst: int, width: int, height: int) -> None:
        """Copy the depth-stencil buffer of framebuffer ``src`` into ``dst`` (both single-sampled,
        this size) bit for bit (glCopyImageSubData: a blit would convert the depth values)."""
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        rb = {fb: rbs[1] for fb, rbs, _ in self._fbs.values()}
        GL.glCopyImageSubData(rb[src], GL.GL_RENDERBUFFER, 0, 0, 0, 0, rb[dst], GL.GL_RENDERBUFFER, 0, 0, 0, 0,
                              width, height, 1)

    def texture(self, width: int, height: int) -> int:
        """The colour texture of the (width, height) texture framebuffer (after bind)."""
        return self._fbs[(width, height, 0, True, "")][2]

    def delete(self, keep: tuple[int, int] | None = None) -> None:
        """Delete the framebuffers (but those of size ``keep``)."""
        from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

        for key in [k for k in self._fbs if k[:2] != keep]:
            fb, rbs, tex = self._fbs.pop(key)
            self._marks.pop(fb, None)
            GL.glDeleteFramebuffers(1, [fb])
            GL.glDeleteRenderbuffers(len(rbs), rbs)
            if tex:
                GL.glDeleteTextures(1, [tex])


def begin(width: int, height: int, prepass: bool = False) -> None:
    """Viewport, depth test, two-sided triangles, no blending; clear colour (to 0), depth and
    stencil (to 0).

    prepass: the bound framebuffer holds the depth of the same triangles drawn by another pass
    (:meth:`Framebuffers.copy_depth`), an exact depth pre-pass: depth is kept, the depth test is
    GL_EQUAL without depth writes, and the stencil lets only the first fragment that passes it
    colour a pixel, as GL_LESS does where coplanar faces tie. Each pixel is then shaded once
    (:func:`end_prepass` after the triangles)."""
    from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

    GL.glViewport(0, 0, width, height)
    GL.glEnable(GL.GL_DEPTH_TEST)
    GL.glDepthMask(GL.GL_TRUE)
    GL.glDepthFunc(GL.GL_LESS)
    GL.glDisable(GL.GL_CULL_FACE)  # IFC winding varies: every triangle is two-sided
    GL.glDisable(GL.GL_BLEND)
    GL.glDisable(GL.GL_STENCIL_TEST)
    GL.glClearColor(0.0, 0.0, 0.0, 0.0)
    GL.glClearDepth(1.0)
    GL.glClearStencil(0)
    if not prepass:
        GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT | GL.GL_STENCIL_BUFFER_BIT)
        return
    GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_STENCIL_BUFFER_BIT)
    GL.glDepthFunc(GL.GL_EQUAL)
    GL.glDepthMask(GL.GL_FALSE)
    GL.glEnable(GL.GL_STENCIL_TEST)
    GL.glStencilFunc(GL.GL_EQUAL, 0, 0xFF)
    GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_INCR)


def end_prepass() -> None:
    """Back to begin()'s plain state after triangles drawn against a copied depth (depth_from)."""
    from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

    GL.glDisable(GL.GL_STENCIL_TEST)
    GL.glDepthFunc(GL.GL_LESS)
    GL.glDepthMask(GL.GL_TRUE)


def read_rgba(width: int, height: int, channels: int = 4) -> np.ndarray:
    """(H, W, channels) uint8 of the bound read framebuffer, top row first."""
    from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
    fmt = GL.GL_RGBA if channels == 4 else GL.GL_RGB
    buf = GL.glReadPixels(0, 0, width, height, fmt, GL.GL_UNSIGNED_BYTE)
    return np.frombuffer(buf, np.uint8).reshape(height, width, channels)[::-1]


def read_depth(width: int, height: int) -> np.ndarray:
    """(H, W) float32 window depth in [0, 1] of the bound read framebuffer, top row first."""
    from OpenGL import GL  # noqa: PLC0415 (PyOpenGL: imported when first used, not at the package's import)

    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 4)
    buf = GL.glReadPixels(0, 0, width, height, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT)
    return np.frombuffer(buf, np.float32).reshape(height, width)[::-1]


def encode(k: np.ndarray) -> np.ndarray:
    """uint8 levels -> floats that any float-to-unorm8 conversion (rounding or truncating) maps back."""
    return (np.asarray(k, np.float32) + 0.25) / 255.0
