"""Synthetic window images with exact ground truth (a quad rasterised with exact area coverage), for
tests and ``tools/pipeline_timing.py``; the pipeline never imports it.

A known rectangle (w x h m) seen by a known camera (K, R, t) projects to an exact quad; the quad is
rasterised with exact area coverage (see :func:`coverage`) so every pixel's value is the fraction
of it covered. None of this uses the pipeline's
own geometry code, so it can serve as independent ground truth.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SyntheticWindow:
    """One synthetic view of a w x h m window.

    K (3, 3); R (3, 3), t (3,): window frame -> camera (x along the wall, y up, z outward, origin
    at the bottom-left corner); corners_px (4, 2) TL TR BR BL, exact projections.
    """

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width_m: float
    height_m: float
    corners_px: np.ndarray


def window_object_points(width_m: float, height_m: float) -> np.ndarray:
    """(4, 3) window-frame corners TL, TR, BR, BL: (0,h,0), (w,h,0), (w,0,0), (0,0,0)."""
    return np.array([[0.0, height_m, 0.0], [width_m, height_m, 0.0], [width_m, 0.0, 0.0], [0.0, 0.0, 0.0]])


def _rot(axis: str, deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def view_window(K: np.ndarray, width_m: float, height_m: float, yaw_deg: float, pitch_deg: float,
                roll_deg: float, distance_m: float, offset_px: tuple[float, float] = (0.0, 0.0)) -> SyntheticWindow:
    """Camera looking at the window centre from ``distance_m``; yaw/pitch turn the wall away.

    The window frame's y axis (up) maps to camera -y (image up) at zero angles; the window faces
    the camera (its +z points toward the camera). ``offset_px`` moves the window's centre in the
    image by that many pixels (approximately) from the principal point.
    """
    K = np.asarray(K, dtype=np.float64)
    base = np.diag([1.0, -1.0, -1.0])  # window x -> cam x, window y (up) -> cam -y, z out -> cam -z
    R = _rot("z", roll_deg) @ _rot("x", pitch_deg) @ _rot("y", yaw_deg) @ base
    centre = np.array([width_m / 2.0, height_m / 2.0, 0.0])
    shift = np.array([offset_px[0] / K[0, 0], offset_px[1] / K[1, 1], 1.0]) * distance_m
    t = shift - R @ centre
    X = window_object_points(width_m, height_m) @ R.T + t
    x = X @ K.T
    return SyntheticWindow(K=K, R=R, t=t, width_m=width_m, height_m=height_m, corners_px=x[:, :2] / x[:, 2:3])


def coverage(corners_px: np.ndarray, shape: tuple[int, int], ss: int = 16) -> np.ndarray:
    """Area coverage (H, W) float32 in [0, 1] of a convex polygon (N, 2) px (pixel centres at integers).

    Exact along x (each of ``ss`` sub-rows per pixel row is cut analytically by the polygon), midpoint
    rule along y: exact wherever the polygon's outline is straight within a pixel (all but the few
    pixels holding a vertex, which are off by well under 1 / ss).
    """
    H, W = shape
    q = np.asarray(corners_px, dtype=np.float64)
    y = (np.arange(H * ss) + 0.5) / ss - 0.5  # sub-row centres, pixel coordinates
    xs = []
    for a, b in zip(q, np.roll(q, -1, axis=0)):
        if a[1] == b[1]:
            continue
        s = (y - a[1]) / (b[1] - a[1])
        xs.append(np.where((s >= 0) & (s <= 1), a[0] + s * (b[0] - a[0]), np.nan))
    xs = np.array(xs)
    valid = np.sum(np.isfinite(xs), axis=0) >= 2
    xl = np.where(valid, np.nanmin(np.where(np.isfinite(xs), xs, np.inf), axis=0), 0.0)
    xr = np.where(valid, np.nanmax(np.where(np.isfinite(xs), xs, -np.inf), axis=0), 0.0)
    u = np.arange(W, dtype=np.float64)
    cov = np.clip(np.minimum(xr[:, None], u + 0.5) - np.maximum(xl[:, None], u - 0.5), 0.0, 1.0)
    return cov.reshape(H, ss, W).mean(axis=1).astype(np.float32)


def pixel_centre_mask(corners_px: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: pixels whose centre lies inside the convex polygon (N, 2), as a rasteriser would."""
    H, W = shape
    q = np.asarray(corners_px, dtype=np.float64)
    v, u = np.mgrid[0:H, 0:W]
    inside = np.ones((H, W), dtype=bool)
    sign = np.sign(np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1]))
    for a, b in zip(q, np.roll(q, -1, axis=0)):
        cross = (b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0])
        inside &= sign * cross >= 0
    return inside


def render_window_image(corners_px: np.ndarray, shape: tuple[int, int], wall: float = 200.0,
                        void: float = 40.0, noise_sigma: float = 0.0, seed: int = 0) -> np.ndarray:
    """(H, W, 3) uint8 RGB (gray) image: a dark void on a bright wall, antialiased, optional Gaussian noise."""
    c = coverage(corners_px, shape)
    img = wall + (void - wall) * c
    if noise_sigma > 0:
        img = img + np.random.default_rng(seed).normal(0.0, noise_sigma, img.shape)
    g = np.clip(np.round(img), 0, 255).astype(np.uint8)
    return np.repeat(g[:, :, None], 3, axis=2)
