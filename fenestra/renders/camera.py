"""A calibrated camera (OpenCV convention) and lens distortion applied to rendered images.

Renderers draw a *pinhole* image. A camera with distortion coefficients gets a larger pinhole
"canvas" (same focal length, shifted principal point) that covers every ray its distorted image
sees; :func:`distort_image` then resamples the canvas into the distorted image with an inverse map
(for each distorted pixel, the pinhole pixel it came from). Ground-truth corners go through the
same model with :meth:`Camera.project` (``cv2.projectPoints``), so images, masks and corners agree.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from fenestra.checks import check_K
from fenestra.conventions import K_from_fov, camera_depths

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)


def _check_dist(dist) -> tuple[float, ...] | None:
    """Validate OpenCV distortion coefficients (4, 5, 8, 12 or 14 numbers) or None."""
    if dist is None:
        return None
    d = np.asarray(dist, dtype=np.float64).ravel()
    if d.size not in (4, 5, 8, 12, 14):
        raise ValueError(f"dist must have 4, 5, 8, 12 or 14 coefficients, got {d.size}: {d.tolist()}")
    if not np.all(np.isfinite(d)):
        raise ValueError(f"dist has non-finite coefficients: {d.tolist()}")
    return None if not np.any(d) else tuple(float(x) for x in d)


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera with optional OpenCV lens distortion.

    K: (3, 3) px; width, height: image size px; R (3, 3), t (3,): world-to-camera,
    ``X_cam = R @ X_world + t`` (OpenCV axes, metres); dist: OpenCV coefficients or None.
    """

    K: np.ndarray
    width: int
    height: int
    R: np.ndarray
    t: np.ndarray
    dist: tuple[float, ...] | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "K", check_K(self.K))
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))
        R = np.asarray(self.R, dtype=np.float64)
        if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise ValueError(f"R must be a 3x3 rotation matrix, got {R.tolist()}")
        t = np.asarray(self.t, dtype=np.float64).reshape(-1)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise ValueError(f"t must be 3 finite numbers, got {np.asarray(self.t).tolist()}")
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "dist", _check_dist(self.dist))

    # ------------------------------------------------------------------ construction
    @staticmethod
    def from_fov(width: int, height: int, hfov_deg: float, R: np.ndarray, t: np.ndarray,
                 dist=None) -> "Camera":
        """Square pixels, principal point at the image centre, horizontal FOV in degrees."""
        return Camera(K_from_fov(width, height, hfov_deg), width, height, R, t, dist)

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world coordinates, m."""
        return -self.R.T @ self.t

    def to_dict(self) -> dict:
        """JSON-ready dict with the view.json keys K, width, height, R, t, distortion."""
        return {"K": self.K.tolist(), "width": self.width, "height": self.height,
                "R": self.R.tolist(), "t": self.t.tolist(),
                "distortion": None if self.dist is None else list(self.dist)}

    @staticmethod
    def from_dict(d: dict) -> "Camera":
        return Camera(np.array(d["K"]), d["width"], d["height"], np.array(d["R"]), np.array(d["t"]),
                      d.get("distortion"))

    # ------------------------------------------------------------------ projection
    def depths(self, X: np.ndarray) -> np.ndarray:
        """Camera z (m) of world points X (N, 3)."""
        return camera_depths(self.R, self.t, X)

    def project(self, X: np.ndarray) -> np.ndarray:
        """World points X (N, 3) m -> image pixels (N, 2), distortion included.

        Points behind the camera still return numbers; check :meth:`depths`.
        """
        X = np.asarray(X, dtype=np.float64).reshape(-1, 3)
        rvec, _ = cv2.Rodrigues(self.R)
        dist = np.zeros(5) if self.dist is None else np.array(self.dist)
        px, _ = cv2.projectPoints(X, rvec, self.t, self.K, dist)
        return px.reshape(-1, 2)

    def distort_px(self, px: np.ndarray) -> np.ndarray:
        """Pinhole pixels (N, 2) of this K -> distorted pixels (N, 2)."""
        px = np.asarray(px, dtype=np.float64).reshape(-1, 2)
        if self.dist is None:
            return px.copy()
        xn = (np.c_[px, np.ones(len(px))] @ np.linalg.inv(self.K).T)
        out, _ = cv2.projectPoints(xn, np.zeros(3), np.zeros(3), self.K, np.array(self.dist))
        return out.reshape(-1, 2)

    def undistort_px(self, px: np.ndarray) -> np.ndarray:
        """Distorted pixels (N, 2) -> pinhole pixels (N, 2) of the same K (iterative, ~1e-9 px)."""
        px = np.asarray(px, dtype=np.float64).reshape(-1, 1, 2)
        if self.dist is None:
            return px.reshape(-1, 2).copy()
        out = cv2.undistortPoints(px, self.K, np.array(self.dist), None, None, self.K,
                                  _UNDISTORT_CRITERIA)
        return out.reshape(-1, 2)

    # ------------------------------------------------------------------ rendering support
    def canvas(self) -> "Camera":
        """The pinhole camera a renderer should draw for this camera.

        Without distortion: the camera itself. With distortion: same f and R, t, no distortion,
        principal point shifted and size enlarged so that the canvas covers every pinhole pixel
        that some distorted pixel of this camera samples (plus a 2 px margin).
        """
        if self.dist is None:
            return self
        if "canvas" not in self._cache:
            W, H = self.width, self.height
            us = np.linspace(-0.5, W - 0.5, 64)
            vs = np.linspace(-0.5, H - 0.5, 48)
            border = np.concatenate([np.c_[us, np.full_like(us, -0.5)], np.c_[us, np.full_like(us, H - 0.5)],
                                     np.c_[np.full_like(vs, -0.5), vs], np.c_[np.full_like(vs, W - 0.5), vs]])
            p = self.undistort_px(border)
            lo = np.floor(p.min(axis=0)) - 2
            hi = np.ceil(p.max(axis=0)) + 2
            lo = np.minimum(lo, 0)
            hi = np.maximum(hi, [W - 1, H - 1])
            K = self.K.copy()
            K[0, 2] -= lo[0]
            K[1, 2] -= lo[1]
            size = (hi - lo + 1).astype(int)
            if np.any(size > 8 * np.array([W, H])):
                raise ValueError(f"distortion {self.dist} needs a pinhole canvas of {size.tolist()} px; too strong")
            self._cache["canvas"] = Camera(K, int(size[0]), int(size[1]), self.R, self.t, None)
        return self._cache["canvas"]

    def canvas_maps(self) -> tuple[np.ndarray, np.ndarray]:
        """float32 (H, W) maps: for each distorted pixel, its (x, y) in the canvas image."""
        if "maps" not in self._cache:
            W, H = self.width, self.height
            uu, vv = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
            p = self.undistort_px(np.c_[uu.ravel(), vv.ravel()])
            canvas = self.canvas()
            off = canvas.K[:2, 2] - self.K[:2, 2]
            p = p + off
            self._cache["maps"] = (p[:, 0].reshape(H, W).astype(np.float32),
                                   p[:, 1].reshape(H, W).astype(np.float32))
        return self._cache["maps"]


def distort_image(camera: Camera, canvas_image: np.ndarray, nearest: bool = False,
                  border_value=0) -> np.ndarray:
    """Resample a pinhole render of ``camera.canvas()`` into the distorted image of ``camera``.

    canvas_image: (Hc, Wc[, C]) any dtype; nearest=True for instance ids / depth (no mixing),
    linear otherwise. Returns (H, W[, C]). A camera without distortion returns the input.
    """
    if camera.dist is None:
        return canvas_image
    c = camera.canvas()
    if canvas_image.shape[:2] != (c.height, c.width):
        raise ValueError(f"canvas image has shape {canvas_image.shape[:2]}, expected {(c.height, c.width)}")
    mx, my = camera.canvas_maps()
    interp = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR
    return cv2.remap(canvas_image, mx, my, interp, borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)
