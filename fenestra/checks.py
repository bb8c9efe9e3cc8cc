"""The one place that checks the values every stage passes around: an image, an intrinsics matrix
K, an image quadrilateral, a rotation and an instance map.

Each check takes the value and a ``name`` (what the caller calls it), returns the value as the
documented array (shape, dtype), and raises ValueError naming ``name`` and the bad value
otherwise (:class:`ImageError` for an image: a PipelineError too, so the CLI prints it as one
line). Shapes, units and orders follow :mod:`fenestra.conventions`.
"""
from __future__ import annotations

import numpy as np

from fenestra.errors import PipelineError

MIN_IMAGE_SIDE_PX = 8
INSTANCE_DTYPE = np.int32  # the one dtype of an instance map in memory (0 = none, k = instance k)
ROTATION_ATOL = 1e-6  # R R^T = I to this (absolute, per entry)


class ImageError(PipelineError, ValueError):
    """An image that is not (H, W, 3) uint8 RGB of at least MIN_IMAGE_SIDE_PX per side."""


def check_image(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Validate an RGB image (H, W, 3) uint8 and return it (as an array, not copied).

    Raises :class:`ImageError` (a PipelineError and a ValueError) naming ``name`` and the problem:
    wrong shape, dtype other than uint8, or a side shorter than MIN_IMAGE_SIDE_PX.
    """
    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ImageError(f"{name} must be (H, W, 3) RGB, got shape {a.shape}")
    if a.dtype != np.uint8:
        raise ImageError(f"{name} must be uint8, got dtype {a.dtype}")
    if min(a.shape[:2]) < MIN_IMAGE_SIDE_PX:
        raise ImageError(f"{name} too small: {a.shape[1]}x{a.shape[0]} px (at least {MIN_IMAGE_SIDE_PX} per side)")
    return a


_K_LAST_ROW = np.array([0.0, 0.0, 1.0])
_EYE3 = np.eye(3)


def _allclose(a: np.ndarray, b: np.ndarray, rtol: float = 1e-05, atol: float = 1e-08) -> bool:
    """np.allclose(a, b, rtol, atol) of a finite array a and finite b (|a - b| <= atol + rtol |b|
    everywhere), without np.isclose's generality: the checks run on every small array the
    pipeline passes, thousands of times per photo in the bench."""
    return bool((np.abs(a - b) <= atol + rtol * np.abs(b)).all())


def _det3(M: np.ndarray) -> float:
    """Determinant of a 3x3 matrix by its cofactor expansion (for a sign: the checks ask det < 0
    of a matrix already orthonormal to ROTATION_ATOL, whose determinant is +-1 to ~1e-5)."""
    (a, b, c), (d, e, f), (g, h, i) = M.tolist()
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def check_K(K: np.ndarray, name: str = "K") -> np.ndarray:
    """Validate an intrinsics matrix; return it as float64 (3, 3).

    Raises ValueError naming the bad value: wrong shape, non-finite, non-positive focal lengths,
    or a last row other than (0, 0, 1).
    """
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3):
        raise ValueError(f"{name} must be 3x3, got shape {K.shape}")
    if not np.isfinite(K).all():
        raise ValueError(f"{name} has non-finite entries: {K.tolist()}")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ValueError(f"{name} focal lengths must be positive, got fx={K[0, 0]}, fy={K[1, 1]}")
    if not _allclose(K[2], _K_LAST_ROW):
        raise ValueError(f"{name} last row must be [0, 0, 1], got {K[2].tolist()}")
    return K


def check_quad(quad: np.ndarray, name: str = "quad") -> np.ndarray:
    """Validate an image quadrilateral: (4, 2) finite px, TL TR BR BL; return it as float64.

    Raises ValueError naming ``name`` and the bad value.
    """
    q = np.asarray(quad, dtype=np.float64)
    if q.shape != (4, 2):
        raise ValueError(f"{name} must have shape (4, 2) (TL, TR, BR, BL px), got {q.shape}")
    if not np.isfinite(q).all():
        raise ValueError(f"{name} has non-finite entries: {q.tolist()}")
    return q


def check_rotation(R: np.ndarray, name: str = "R", atol: float = ROTATION_ATOL) -> np.ndarray:
    """Validate a rotation matrix: (3, 3), finite, orthonormal (R R^T = I to ``atol``) with
    det +1; return it as float64. Raises ValueError naming ``name`` and the bad value."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape != (3, 3):
        raise ValueError(f"{name} must have shape (3, 3), got {R.shape}")
    if not np.isfinite(R).all():
        raise ValueError(f"{name} has non-finite entries: {R.tolist()}")
    if not _allclose(R @ R.T, _EYE3, atol=atol) or _det3(R) < 0:
        raise ValueError(f"{name} is not a rotation matrix (R R^T != I or det < 0; det = "
                         f"{np.linalg.det(R):.4f}): {R.tolist()}")
    return R


def check_instances(instances: np.ndarray | None, image_shape: tuple[int, ...] | None = None,
                    name: str = "instances") -> np.ndarray:
    """Validate an instance map: (H, W) integers in [0, 2**31 - 1] (0 = none, k = instance k), of
    the image's (H, W) when ``image_shape`` is given; return it as int32 (:data:`INSTANCE_DTYPE`).

    Raises ValueError naming ``name`` and the bad value (None included).
    """
    if instances is None:
        raise ValueError(f"{name} must be an (H, W) instance map (0 = none), got None")
    inst = np.asarray(instances)
    if inst.ndim != 2:
        raise ValueError(f"{name} must be (H, W), got shape {inst.shape}")
    if not np.issubdtype(inst.dtype, np.integer):
        raise ValueError(f"{name} must be an integer array, got dtype {inst.dtype}")
    if image_shape is not None and tuple(inst.shape) != tuple(image_shape[:2]):
        raise ValueError(f"{name} shape {inst.shape} does not match image shape {tuple(image_shape[:2])}")
    if inst.size and inst.min() < 0:
        raise ValueError(f"{name} must be >= 0, got min {inst.min()}")
    if inst.size and inst.max() > np.iinfo(INSTANCE_DTYPE).max:
        raise ValueError(f"{name} ids must be <= {np.iinfo(INSTANCE_DTYPE).max}, got max {inst.max()}")
    return inst.astype(INSTANCE_DTYPE, copy=False)
