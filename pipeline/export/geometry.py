"""Geometry shared by the exporters: frames, the wall fragment, photo texture coordinates.

Frames
    window frame  (W)  x along the wall, y up, z outward; origin at the void's bottom-left corner on
                       the facade; the void is [0, w] x [0, h] at z = 0 (see pipeline.types).
    camera frame  (C)  OpenCV: x right, y down, z forward. ``X_C = R @ X_W + t`` (WindowResult R, t).
    export world  (E)  the frame of model.ifc / model.obj / model.glb: the camera frame turned z-up,
                       camera at the origin looking along +y:
                           X_E = CAMERA_TO_EXPORT @ X_C,  x_E = x_C, y_E = z_C, z_E = -y_C.
                       A level camera therefore gives a vertical wall. Units: metres, at the scale
                       the pose was solved with (the window is ``height_m`` tall).

Texture
    The texture is the inpainted photo, padded by replication so that every wall vertex projects
    inside it. Texture coordinates (s, t) in [0, 1] have their origin at the texture's bottom-left
    (IFC IfcTextureVertex, OBJ vt, and glTF after trimesh's flip all agree on this):
        s = (u + 0.5 + pad_left) / tex_width,   t = 1 - (v + 0.5 + pad_top) / tex_height
    for a photo pixel coordinate (u, v) under the pixel-centre convention of fenestra.conventions.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fenestra.conventions import check_K, project
from pipeline.types import WindowResult

# Camera frame (OpenCV) -> export world (z up, camera looking along +y); a proper rotation.
CAMERA_TO_EXPORT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

WALL_MARGIN_M = 1.0  # wall fragment extends this far beyond the void on every side
WALL_THICKNESS_M = 0.30
MAX_PAD_FRACTION = 1.0  # texture padding per side, at most this fraction of the photo size


@dataclass(frozen=True)
class PlacedWindow:
    """A reconstructed window ready to export: size (m) and window-to-camera pose."""

    index: int
    width_m: float
    height_m: float
    R: np.ndarray  # (3, 3) window -> camera
    t: np.ndarray  # (3,) m

    def to_camera(self, X: np.ndarray) -> np.ndarray:
        """Window-frame points (N, 3) m -> camera frame (N, 3) m."""
        return np.asarray(X, dtype=np.float64).reshape(-1, 3) @ self.R.T + self.t

    def to_export(self, X: np.ndarray) -> np.ndarray:
        """Window-frame points (N, 3) m -> export world (N, 3) m."""
        return self.to_camera(X) @ CAMERA_TO_EXPORT.T

    def export_matrix(self) -> np.ndarray:
        """4x4 homogeneous window-frame -> export-world transform (the IFC object placement)."""
        T = np.eye(4)
        T[:3, :3] = CAMERA_TO_EXPORT @ self.R
        T[:3, 3] = CAMERA_TO_EXPORT @ self.t
        return T

    def void_corners(self) -> np.ndarray:
        """The void's corners TL, TR, BR, BL in the window frame, (4, 3) m."""
        w, h = self.width_m, self.height_m
        return np.array([[0, h, 0], [w, h, 0], [w, 0, 0], [0, 0, 0]], dtype=np.float64)


def place(result: WindowResult) -> PlacedWindow | str:
    """A PlacedWindow, or a one-line reason why ``result`` cannot be exported.

    Rejects results that failed upstream, miss pose or aspect ratio, have a rotation that is not
    proper/orthonormal, a non-positive size, or a void not entirely in front of the camera.
    """
    if not isinstance(result, WindowResult):
        return f"not a WindowResult: {type(result).__name__}"
    if result.failure:
        return f"upstream failure: {result.failure}"
    if result.R is None or result.t is None or result.aspect_ratio is None:
        return "missing pose or aspect ratio"
    R = np.asarray(result.R, dtype=np.float64)
    t = np.asarray(result.t, dtype=np.float64).reshape(-1)
    if R.shape != (3, 3) or t.shape != (3,) or not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
        return f"bad pose shapes/values: R {R.shape}, t {t.shape}"
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        return f"R is not a proper rotation (det={np.linalg.det(R):.4f})"
    h = float(result.height_m)
    w = float(result.aspect_ratio) * h
    if not (np.isfinite(w) and np.isfinite(h) and w > 0 and h > 0):
        return f"bad window size w={w}, h={h} (aspect_ratio={result.aspect_ratio}, height_m={result.height_m})"
    pw = PlacedWindow(int(result.index), w, h, R, t)
    if np.any(pw.to_camera(pw.void_corners())[:, 2] <= 1e-6):
        return "void is not in front of the camera"
    return pw


def wall_outline(pw: PlacedWindow, margin_m: float = WALL_MARGIN_M) -> np.ndarray:
    """Outer rectangle of the wall fragment on the facade, window frame, (4, 2) m: BL, BR, TR, TL."""
    x0, y0, x1, y1 = -margin_m, -margin_m, pw.width_m + margin_m, pw.height_m + margin_m
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def wall_box_mesh(pw: PlacedWindow, margin_m: float = WALL_MARGIN_M,
                  thickness_m: float = WALL_THICKNESS_M) -> tuple[np.ndarray, np.ndarray]:
    """The wall fragment as a closed box (no hole), window frame: (8, 3) vertices, (12, 3) faces.

    Exterior face at z = 0, interior face at z = -thickness_m. The IFC exporter cuts the void with
    an IfcOpeningElement; the OBJ/GLB exporter uses :func:`wall_holed_mesh` instead.
    """
    from pipeline.catalogue import box_mesh  # noqa: PLC0415  (catalogue is a sibling module)

    o = wall_outline(pw, margin_m)
    return box_mesh([o[0, 0], o[0, 1], -thickness_m], [o[2, 0], o[2, 1], 0.0])


def wall_holed_mesh(pw: PlacedWindow, margin_m: float = WALL_MARGIN_M,
                    thickness_m: float = WALL_THICKNESS_M) -> tuple[np.ndarray, np.ndarray]:
    """The wall fragment with the void cut out, window frame: (16, 3) vertices, (32, 3) faces.

    Vertices 0..3 outer ring and 4..7 void ring on the facade (z = 0), 8..15 the same at
    z = -thickness_m. Faces wind counter-clockwise seen from outside the solid.
    """
    o = wall_outline(pw, margin_m)
    w, h = pw.width_m, pw.height_m
    inner = np.array([[0, 0], [w, 0], [w, h], [0, h]], dtype=np.float64)
    ring = np.concatenate([o, inner])  # (8, 2)
    front = np.column_stack([ring, np.zeros(8)])
    back = np.column_stack([ring, np.full(8, -thickness_m)])
    V = np.concatenate([front, back])
    faces = []
    for i in range(4):  # front annulus: quad (outer i, outer i+1, inner i+1, inner i)
        j = (i + 1) % 4
        faces += [[i, j, 4 + j], [i, 4 + j, 4 + i]]
    for i in range(4):  # back annulus, reversed
        j = (i + 1) % 4
        faces += [[8 + i, 12 + j, 8 + j], [8 + i, 12 + i, 12 + j]]
    for i in range(4):  # outer sides (normals point away from the wall)
        j = (i + 1) % 4
        faces += [[i, 8 + i, 8 + j], [i, 8 + j, j]]
    for i in range(4):  # void reveals (normals point into the void)
        j = (i + 1) % 4
        faces += [[4 + i, 4 + j, 12 + j], [4 + i, 12 + j, 12 + i]]
    return V, np.array(faces, dtype=np.int64)


@dataclass(frozen=True)
class TextureLayout:
    """Where the photo lies inside the padded texture image (px)."""

    photo_width: int
    photo_height: int
    pad_left: int
    pad_top: int
    pad_right: int
    pad_bottom: int

    @property
    def width(self) -> int:
        return self.photo_width + self.pad_left + self.pad_right

    @property
    def height(self) -> int:
        return self.photo_height + self.pad_top + self.pad_bottom

    def uv(self, px: np.ndarray) -> np.ndarray:
        """Photo pixel coordinates (N, 2) -> texture coordinates (N, 2), origin bottom-left, clipped to [0, 1]."""
        px = np.asarray(px, dtype=np.float64).reshape(-1, 2)
        s = (px[:, 0] + 0.5 + self.pad_left) / self.width
        t = 1.0 - (px[:, 1] + 0.5 + self.pad_top) / self.height
        return np.clip(np.column_stack([s, t]), 0.0, 1.0)

    def pixel(self, uv: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`uv` (for checks): texture coordinates (N, 2) -> photo pixels (N, 2)."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        u = uv[:, 0] * self.width - 0.5 - self.pad_left
        v = (1.0 - uv[:, 1]) * self.height - 0.5 - self.pad_top
        return np.column_stack([u, v])

    def pad(self, image: np.ndarray) -> np.ndarray:
        """The padded texture image (edge pixels replicated)."""
        return cv2.copyMakeBorder(image, self.pad_top, self.pad_bottom, self.pad_left, self.pad_right,
                                  cv2.BORDER_REPLICATE)


def facade_pixels(K: np.ndarray, pw: PlacedWindow, xy: np.ndarray) -> np.ndarray:
    """Photo pixel positions (N, 2) of window-frame facade points (x, y, 0), xy (N, 2) m."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    X = np.column_stack([xy, np.zeros(len(xy))])
    return project(check_K(K), pw.R, pw.t, X)


def texture_layout(K: np.ndarray, image_shape: tuple[int, ...], placed: list[PlacedWindow],
                   margin_m: float = WALL_MARGIN_M) -> TextureLayout:
    """Padding that keeps every wall-fragment corner's projection inside the texture.

    Padding per side is capped at MAX_PAD_FRACTION of the photo size; corners that project further
    (grazing views, corners behind the camera) get clipped texture coordinates.
    """
    H, W = int(image_shape[0]), int(image_shape[1])
    pads = np.zeros(4)  # left, top, right, bottom
    for pw in placed:
        o = wall_outline(pw, margin_m)
        depth = pw.to_camera(np.column_stack([o, np.zeros(4)]))[:, 2]
        px = facade_pixels(K, pw, o)[depth > 1e-6]
        if len(px) == 0:
            continue
        pads = np.maximum(pads, [-(px[:, 0].min() + 0.5), -(px[:, 1].min() + 0.5),
                                 px[:, 0].max() + 0.5 - W, px[:, 1].max() + 0.5 - H])
    cap = np.array([W, H, W, H]) * MAX_PAD_FRACTION
    pads = np.ceil(np.clip(pads, 0.0, cap)).astype(int)
    return TextureLayout(W, H, *map(int, pads))
