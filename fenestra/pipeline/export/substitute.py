"""Window substitution ("photorealistic BIM"): render a catalogue window into the detected void.

The catalogue window's triangles are placed with the estimated pose, rasterised with a z-buffer
(perspective-correct depth, 2x2 supersampling for soft edges) and simple Lambert shading, then
composited over the photo with the voids inpainted. Pure numpy + OpenCV; no GPU, no GL context.

    out = substitute(image, K, result, "two-by-two-mullion")     # (H, W, 3) uint8 RGB
"""
from __future__ import annotations

import cv2
import numpy as np

from fenestra.checks import check_K, check_image
from fenestra.conventions import project
from fenestra.errors import PipelineError
from fenestra.pipeline.catalogue import WindowStyle, get_style, window_mesh
from fenestra.pipeline.export.geometry import PlacedWindow, place
from fenestra.pipeline.export.inpaint import inpaint_voids
from fenestra.pipeline.types import Unavailable, WindowResult

# Direction towards the light in the camera frame (up-left of the camera), and the ambient share.
LIGHT_DIR_CAM = np.array([-0.35, -0.6, -1.0]) / np.linalg.norm([-0.35, -0.6, -1.0])
AMBIENT = 0.45
NEAR_M = 1e-3


def supersampled_K(K: np.ndarray, factor: int) -> np.ndarray:
    """K for an image ``factor`` times larger, keeping the pixel-centre convention:
    u_big = factor * (u + 0.5) - 0.5."""
    S = np.array([[factor, 0, 0.5 * factor - 0.5], [0, factor, 0.5 * factor - 0.5], [0, 0, 1.0]])
    return S @ K


def rasterise(K: np.ndarray, shape: tuple[int, int], tris_cam: np.ndarray, colours: np.ndarray,
              factor: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Z-buffered rendering of camera-frame triangles.

    K (3, 3); shape (H, W) px; tris_cam (M, 3, 3) m, OpenCV camera frame; colours (M, 3) in [0, 1]
    (already shaded). Returns (colour (H, W, 3) float in [0, 1], coverage alpha (H, W) in [0, 1]).
    Triangles with a vertex closer than NEAR_M are skipped (the exporter only passes windows in
    front of the camera).
    """
    H, W = int(shape[0]), int(shape[1])
    Ks = supersampled_K(check_K(K), factor)
    Hs, Ws = H * factor, W * factor
    zbuf = np.full((Hs, Ws), np.inf)
    cbuf = np.zeros((Hs, Ws, 3))
    tris_cam = np.asarray(tris_cam, dtype=np.float64).reshape(-1, 3, 3)
    for tri, col in zip(tris_cam, np.asarray(colours, dtype=np.float64).reshape(-1, 3)):
        z = tri[:, 2]
        if np.any(z < NEAR_M):
            continue
        p = (tri @ Ks.T)[:, :2] / z[:, None]  # (3, 2) px
        x0, y0 = np.floor(p.min(axis=0)).astype(int)
        x1, y1 = np.ceil(p.max(axis=0)).astype(int)
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, Ws - 1), min(y1, Hs - 1)
        if x0 > x1 or y0 > y1:
            continue
        area = (p[1, 0] - p[0, 0]) * (p[2, 1] - p[0, 1]) - (p[2, 0] - p[0, 0]) * (p[1, 1] - p[0, 1])
        if abs(area) < 1e-12:
            continue
        xs, ys = np.meshgrid(np.arange(x0, x1 + 1, dtype=np.float64), np.arange(y0, y1 + 1, dtype=np.float64))
        b = np.empty((3,) + xs.shape)
        for i in range(3):  # barycentric weight of vertex i: edge function of the opposite edge
            a_, c_ = p[(i + 1) % 3], p[(i + 2) % 3]
            b[i] = ((c_[0] - a_[0]) * (ys - a_[1]) - (c_[1] - a_[1]) * (xs - a_[0])) / area
        inside = np.all(b >= -1e-9, axis=0)
        if not inside.any():
            continue
        depth = 1.0 / np.tensordot(1.0 / z, b, axes=1)  # perspective-correct depth
        region = zbuf[y0:y1 + 1, x0:x1 + 1]
        win = inside & (depth < region)
        region[win] = depth[win]
        cbuf[y0:y1 + 1, x0:x1 + 1][win] = col
    covered = np.isfinite(zbuf).astype(np.float64)
    alpha = covered.reshape(H, factor, W, factor).mean(axis=(1, 3))
    colour_sum = (cbuf * covered[..., None]).reshape(H, factor, W, factor, 3).sum(axis=(1, 3))
    colour = colour_sum / np.maximum(alpha * factor * factor, 1e-12)[..., None]
    return colour, alpha


def shade(tris_cam: np.ndarray, rgb: np.ndarray) -> np.ndarray:
    """Lambert shading (M, 3) in [0, 1] of camera-frame triangles (M, 3, 3) with base colours (M, 3)."""
    n = np.cross(tris_cam[:, 1] - tris_cam[:, 0], tris_cam[:, 2] - tris_cam[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    centre = tris_cam.mean(axis=1)
    n[np.einsum("ij,ij->i", n, centre) > 0] *= -1.0  # face the camera (two-sided)
    lambert = np.clip(n @ LIGHT_DIR_CAM, 0.0, 1.0)
    return np.clip(rgb * (AMBIENT + (1.0 - AMBIENT) * lambert)[:, None], 0.0, 1.0)


def void_coverage(K: np.ndarray, shape: tuple[int, int], placed: list[PlacedWindow],
                  factor: int = 4) -> np.ndarray:
    """Fraction (H, W) in [0, 1] of each pixel inside any void's projected outline on the facade."""
    H, W = int(shape[0]), int(shape[1])
    Ks = supersampled_K(check_K(K), factor)
    cover = np.zeros((H, W))
    for pw in placed:
        px = project(Ks, pw.R, pw.t, pw.void_corners())
        x0, y0 = np.clip(np.floor(px.min(axis=0) / factor).astype(int) - 1, 0, [W - 1, H - 1])
        x1, y1 = np.clip(np.ceil(px.max(axis=0) / factor).astype(int) + 1, 0, [W - 1, H - 1])
        big = np.zeros(((y1 - y0 + 1) * factor, (x1 - x0 + 1) * factor), dtype=np.uint8)
        local = (px - [x0 * factor, y0 * factor]) * 16
        cv2.fillPoly(big, [np.round(local).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
        part = big.reshape(y1 - y0 + 1, factor, x1 - x0 + 1, factor).mean(axis=(1, 3))
        cover[y0:y1 + 1, x0:x1 + 1] = np.maximum(cover[y0:y1 + 1, x0:x1 + 1], part)
    return cover


def window_triangles(pw: PlacedWindow, style: str | WindowStyle) -> tuple[np.ndarray, np.ndarray]:
    """Camera-facing triangles (M, 3, 3) m of the style's window for ``pw``, shaded RGB colours (M, 3).

    Back faces are culled: every catalogue part is a closed box, so they are always hidden.
    """
    mesh = window_mesh(style, pw.width_m, pw.height_m)
    tris = pw.to_camera(mesh.vertices)[mesh.faces]  # (M, 3, 3), winding kept (R is proper)
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    front = np.einsum("ij,ij->i", n, tris.mean(axis=1)) < 0
    return tris[front], shade(tris[front], mesh.face_rgb[front])


def render_windows(K: np.ndarray, shape: tuple[int, int], placed: list[PlacedWindow],
                   style: str | WindowStyle) -> tuple[np.ndarray, np.ndarray]:
    """Render the style's window into every placed void: (RGB float (H, W, 3) in [0, 1], alpha (H, W)).

    One z-buffer for all windows. Parts behind the facade are seen only through the void: alpha is
    clipped to the void outlines (the wall around a void occludes the frame's outer sides).
    """
    if not placed:
        return np.zeros((int(shape[0]), int(shape[1]), 3)), np.zeros((int(shape[0]), int(shape[1])))
    H, W = int(shape[0]), int(shape[1])
    K = check_K(K)
    parts = [window_triangles(pw, style) for pw in placed]
    tris = np.concatenate([p[0] for p in parts])
    colours = np.concatenate([p[1] for p in parts])
    # Render only the image region the voids cover (alpha is clipped to them anyway).
    px = np.concatenate([project(K, pw.R, pw.t, pw.void_corners()) for pw in placed])
    x0, y0 = np.clip(np.floor(px.min(axis=0)).astype(int) - 2, 0, [W - 1, H - 1])
    x1, y1 = np.clip(np.ceil(px.max(axis=0)).astype(int) + 2, 0, [W - 1, H - 1])
    K_crop = K.copy()
    K_crop[:2, 2] -= [x0, y0]
    crop = (y1 - y0 + 1, x1 - x0 + 1)
    c, a = rasterise(K_crop, crop, tris, colours)
    a = np.minimum(a, void_coverage(K_crop, crop, placed))
    colour, alpha = np.zeros((H, W, 3)), np.zeros((H, W))
    colour[y0:y1 + 1, x0:x1 + 1], alpha[y0:y1 + 1, x0:x1 + 1] = c, a
    return colour, alpha


def composite(background: np.ndarray, K: np.ndarray, placed: list[PlacedWindow],
              style: str | WindowStyle) -> np.ndarray:
    """Render every placed window in ``style`` over ``background`` (H, W, 3) uint8 RGB."""
    background = check_image(background)
    colour, alpha = render_windows(K, background.shape[:2], placed, style)
    out = background.astype(np.float64) / 255.0
    out = out * (1.0 - alpha[..., None]) + colour * alpha[..., None]
    return np.clip(np.round(out * 255.0), 0, 255).astype(np.uint8)


def substitute(image: np.ndarray, K: np.ndarray, result: WindowResult, style: str | WindowStyle,
               background: np.ndarray | None = None) -> np.ndarray:
    """The photo with ``result``'s window replaced by catalogue ``style``: (H, W, 3) uint8 RGB (like ``image``).

    ``background``: the photo with voids already inpainted (default: inpaint this result's void).
    Raises PipelineError when the result has no usable pose, ValueError for an unknown style.
    """
    image = check_image(image)
    style = get_style(style)
    pw = place(result)
    if isinstance(pw, Unavailable):
        raise PipelineError(f"cannot substitute window {getattr(result, 'index', '?')}: {pw}")
    if background is None:
        background, _ = inpaint_voids(image, [result])
    elif np.asarray(background).shape != image.shape:
        raise PipelineError(f"background shape {np.asarray(background).shape} != image shape {image.shape}")
    return composite(background, K, [pw], style)
