"""A small catalogue of procedural window styles and their 3D geometry.

Geometry is built in the window frame of :class:`pipeline.types.WindowResult`: x along the wall,
y up, z outward (towards the street), origin at the bottom-left corner of the void on the wall's
exterior face; the void spans x in [0, w], y in [0, h]. A window body fills the void with its front
face flush with the facade (z = 0) and extends ``frame_depth_m`` into the wall (z < 0).

    style = CATALOGUE["two-by-two-mullion"]
    mesh = window_mesh(style, w=1.2, h=1.5)      # WindowMesh: vertices (N, 3) m, faces (M, 3)
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class WindowStyle:
    """One catalogue window. Lengths in metres, colours linear-ish sRGB in [0, 1]."""

    name: str
    frame_width_m: float = 0.06  # outer frame, seen from outside
    frame_depth_m: float = 0.07  # frame thickness into the wall
    mullions: int = 0  # vertical bars, evenly spaced
    transoms: int = 0  # horizontal bars, evenly spaced
    bar_width_m: float = 0.05  # mullion / transom width
    bar_depth_m: float = 0.05
    glass_setback_m: float = 0.035  # glass plane at z = -glass_setback_m
    frame_rgb: tuple[float, float, float] = (0.93, 0.93, 0.91)
    glass_rgb: tuple[float, float, float] = (0.22, 0.30, 0.36)
    glass_alpha: float = 0.35  # opacity used by IFC/GLB materials


CATALOGUE: dict[str, WindowStyle] = {
    "casement-white": WindowStyle("casement-white"),
    "two-by-two-mullion": WindowStyle("two-by-two-mullion", mullions=1, transoms=1),
    "dark-frame": WindowStyle("dark-frame", frame_width_m=0.05, mullions=1,
                              frame_rgb=(0.16, 0.17, 0.18), glass_rgb=(0.15, 0.20, 0.24)),
    "sash-cross": WindowStyle("sash-cross", frame_width_m=0.08, mullions=1, transoms=1,
                              bar_width_m=0.03, frame_rgb=(0.95, 0.94, 0.88)),
}


@dataclass(frozen=True)
class WindowMesh:
    """Triangle mesh of a window body in the window frame.

    vertices (N, 3) m; faces (M, 3) int vertex indices, counter-clockwise seen from outside the
    solid; part (M,) str "frame" or "glass"; face_rgb (M, 3) in [0, 1].
    """

    vertices: np.ndarray
    faces: np.ndarray
    part: np.ndarray
    face_rgb: np.ndarray

    def select(self, part: str) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, faces) of one part, re-indexed compactly."""
        keep = self.faces[self.part == part]
        used, inverse = np.unique(keep, return_inverse=True)
        return self.vertices[used], inverse.reshape(-1, 3)


# Triangles of a unit box [0,1]^3, counter-clockwise seen from outside (outward normals).
_BOX_CORNERS = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float64)
_BOX_FACES = np.array([
    [0, 2, 1], [1, 2, 3],  # z = 0 (normal -z)
    [4, 5, 6], [5, 7, 6],  # z = 1 (normal +z)
    [0, 1, 4], [1, 5, 4],  # y = 0 (normal -y)
    [2, 6, 3], [3, 6, 7],  # y = 1 (normal +y)
    [0, 4, 2], [2, 4, 6],  # x = 0 (normal -x)
    [1, 3, 5], [3, 7, 5],  # x = 1 (normal +x)
], dtype=np.int64)


def box_mesh(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed axis-aligned box from corner ``lo`` (3,) to ``hi`` (3,) m: (8, 3) vertices, (12, 3) faces."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    if lo.shape != (3,) or hi.shape != (3,) or np.any(hi <= lo):
        raise ValueError(f"box_mesh needs lo < hi component-wise, got lo={lo.tolist()}, hi={hi.tolist()}")
    return lo + _BOX_CORNERS * (hi - lo), _BOX_FACES.copy()


def _merge(boxes: list[tuple[np.ndarray, np.ndarray, str, tuple]]) -> WindowMesh:
    verts, faces, parts, rgbs, offset = [], [], [], [], 0
    for v, f, part, rgb in boxes:
        verts.append(v)
        faces.append(f + offset)
        parts += [part] * len(f)
        rgbs.append(np.tile(np.asarray(rgb, dtype=np.float64), (len(f), 1)))
        offset += len(v)
    return WindowMesh(np.concatenate(verts), np.concatenate(faces), np.array(parts), np.concatenate(rgbs))


def get_style(style: str | WindowStyle) -> WindowStyle:
    """Look a style up by name (or pass a WindowStyle through); ValueError names unknown styles."""
    if isinstance(style, WindowStyle):
        return style
    if style not in CATALOGUE:
        raise ValueError(f"unknown window style {style!r}; choose one of {sorted(CATALOGUE)}")
    return CATALOGUE[style]


FIT_MAX_FRACTION = 0.5  # a style scaled to fit a small void: frame and bars take at most half its width/height


def fitted_style(style: str | WindowStyle, w: float, h: float) -> WindowStyle:
    """The style as it is when its frame and bars take at most FIT_MAX_FRACTION of a ``w`` x ``h`` m
    void, else the style scaled down uniformly (frame, bars, depths, glass setback) until they do:
    a window smaller than the style's smallest (a 1:25 model's 9 cm panes) still gets its frame."""
    s = get_style(style)
    need_w = 2 * s.frame_width_m + s.mullions * s.bar_width_m
    need_h = 2 * s.frame_width_m + s.transoms * s.bar_width_m
    k = min(1.0, FIT_MAX_FRACTION * float(w) / need_w, FIT_MAX_FRACTION * float(h) / need_h)
    if k >= 1.0 or not k > 0:
        return s
    return replace(s, frame_width_m=s.frame_width_m * k, frame_depth_m=s.frame_depth_m * k,
                   bar_width_m=s.bar_width_m * k, bar_depth_m=s.bar_depth_m * k,
                   glass_setback_m=s.glass_setback_m * k)


def window_mesh(style: str | WindowStyle, w: float, h: float, fit: bool = True) -> WindowMesh:
    """Frame boxes, mullion/transom boxes and one glass pane for a ``w`` x ``h`` m void.

    The frame's outer outline is exactly the void rectangle [0, w] x [0, h] at z = 0 .. -depth.
    fit: a void too small for the style gets the style scaled down (:func:`fitted_style`); with
    fit False that is a ValueError. Raises ValueError when the size is not positive.
    """
    w, h = float(w), float(h)
    if not (np.isfinite(w) and np.isfinite(h) and w > 0 and h > 0):
        raise ValueError(f"window size must be positive and finite, got w={w}, h={h}")
    s = fitted_style(style, w, h) if fit else get_style(style)
    fw, d = s.frame_width_m, s.frame_depth_m
    inner_w = w - 2 * fw - s.mullions * s.bar_width_m
    inner_h = h - 2 * fw - s.transoms * s.bar_width_m
    if inner_w <= 0 or inner_h <= 0:
        raise ValueError(f"window {w:.3f} x {h:.3f} m is too small for style {s.name!r} "
                         f"(frame {fw} m, {s.mullions} mullions, {s.transoms} transoms)")
    F = s.frame_rgb
    parts = [
        (*box_mesh([0, 0, -d], [fw, h, 0]), "frame", F),  # left
        (*box_mesh([w - fw, 0, -d], [w, h, 0]), "frame", F),  # right
        (*box_mesh([fw, 0, -d], [w - fw, fw, 0]), "frame", F),  # bottom (sill side)
        (*box_mesh([fw, h - fw, -d], [w - fw, h, 0]), "frame", F),  # top
    ]
    bz = (-(d + s.bar_depth_m) / 2, -(d - s.bar_depth_m) / 2)  # bars centred in the frame depth
    for i in range(1, s.mullions + 1):
        xc = fw + (w - 2 * fw) * i / (s.mullions + 1)
        parts.append((*box_mesh([xc - s.bar_width_m / 2, fw, bz[0]], [xc + s.bar_width_m / 2, h - fw, bz[1]]),
                      "frame", F))
    for j in range(1, s.transoms + 1):
        yc = fw + (h - 2 * fw) * j / (s.transoms + 1)
        parts.append((*box_mesh([fw, yc - s.bar_width_m / 2, bz[0]], [w - fw, yc + s.bar_width_m / 2, bz[1]]),
                      "frame", F))
    g = s.glass_setback_m
    parts.append((*box_mesh([fw, fw, -g - 0.004], [w - fw, h - fw, -g + 0.004]), "glass", s.glass_rgb))
    return _merge(parts)
