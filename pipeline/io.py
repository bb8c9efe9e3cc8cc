"""Reading the pipeline's inputs: photo, intrinsics (JSON or fx/fy/cx/cy), lens distortion, masks.

Every problem raises :class:`fenestra.errors.PipelineError` naming the file or the bad value.

An intrinsics JSON may carry OpenCV distortion coefficients beside K (``"distortion": [k1, k2, p1,
p2[, k3[, ...]]]``, 4, 5, 8, 12 or 14 numbers, or null): :func:`read_camera` returns both, and
:func:`undistort_photo` resamples a photo to the pinhole image of the *same* K, so K stays valid.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fenestra.conventions import check_K, make_K
from fenestra.errors import PipelineError


def read_photo(path: str | Path) -> np.ndarray:
    """(H, W, 3) uint8 **BGR** image from any format cv2 reads; PipelineError if unreadable."""
    p = Path(path)
    if not p.is_file():
        raise PipelineError(f"photo not found: {p}")
    img = cv2.imread(str(p), cv2.IMREAD_COLOR)
    if img is None or img.size == 0:
        raise PipelineError(f"cannot read photo {p} (not an image cv2 can decode)")
    return img


def K_from_values(fx: float, fy: float | None, cx: float | None, cy: float | None,
                  image_size: tuple[int, int]) -> np.ndarray:
    """K (3, 3) from focal lengths (px) and principal point (px); cx, cy default to the image centre.

    image_size: (W, H) px. fy defaults to fx. PipelineError naming a bad value.
    """
    W, H = image_size
    cx = (W - 1) / 2.0 if cx is None else cx
    cy = (H - 1) / 2.0 if cy is None else cy
    try:
        return make_K(float(fx), None if fy is None else float(fy), float(cx), float(cy))
    except (TypeError, ValueError) as e:
        raise PipelineError(f"bad intrinsics fx={fx}, fy={fy}, cx={cx}, cy={cy}: {e}") from e


DISTORTION_SIZES = (4, 5, 8, 12, 14)  # the coefficient counts OpenCV accepts


@dataclass(frozen=True, eq=False)
class Camera:
    """Intrinsics of the photo: K (3, 3) px and OpenCV distortion coefficients (n,) or None.

    ``distortion`` is None for a pinhole camera (also when every coefficient is zero).
    """

    K: np.ndarray
    distortion: np.ndarray | None = None

    @property
    def has_distortion(self) -> bool:
        return self.distortion is not None


def check_distortion(values) -> np.ndarray | None:
    """OpenCV distortion coefficients -> float64 (n,) array, or None for null / all zeros.

    n must be 4, 5, 8, 12 or 14 (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]); every
    coefficient finite. PipelineError naming the value otherwise.
    """
    if values is None:
        return None
    try:
        d = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise PipelineError(f"distortion must be a list of numbers, got {values!r}") from e
    if d.ndim != 1 or d.size not in DISTORTION_SIZES:
        raise PipelineError(f"distortion must be a flat list of {', '.join(map(str, DISTORTION_SIZES))} "
                            f"OpenCV coefficients (k1, k2, p1, p2, k3, ...), got {values!r}")
    if not np.all(np.isfinite(d)):
        raise PipelineError(f"distortion has non-finite coefficients: {d.tolist()}")
    return d if np.any(d) else None


def undistort_photo(image: np.ndarray, camera: Camera) -> np.ndarray:
    """The photo resampled to the pinhole image of the same K (``cv2.undistort``, bilinear).

    image: (H, W[, C]) any dtype cv2 handles. Returns the input itself without distortion.
    Pixels whose ray falls outside the photo are black.
    """
    if not camera.has_distortion:
        return image
    return cv2.undistort(image, camera.K, camera.distortion)


def read_camera(path: str | Path, image_size: tuple[int, int] | None = None) -> Camera:
    """K and lens distortion from a JSON file (see :func:`read_K`), plus an optional
    ``"distortion"`` key: OpenCV coefficients (4, 5, 8, 12 or 14 numbers) or null.

    PipelineError naming the file and the bad value.
    """
    K, data = _read_K_json(path, image_size)
    try:
        dist = check_distortion(data.get("distortion"))
    except PipelineError as e:
        raise PipelineError(f"{Path(path)}: bad distortion: {e}") from e
    return Camera(K=K, distortion=dist)


def read_K(path: str | Path, image_size: tuple[int, int] | None = None) -> np.ndarray:
    """K (3, 3) from a JSON file: ``{"K": [[...], [...], [...]]}`` or ``{"fx", "fy", "cx", "cy"}``.

    With fx only, fy = fx and the principal point is the image centre (needs ``image_size`` (W, H)).
    A ``"distortion"`` key is ignored here: use :func:`read_camera` to get it too.
    PipelineError naming the file and the bad value.
    """
    return _read_K_json(path, image_size)[0]


def _read_K_json(path: str | Path, image_size: tuple[int, int] | None) -> tuple[np.ndarray, dict]:
    """(K, the parsed JSON object) from an intrinsics file; PipelineError naming the bad value."""
    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except FileNotFoundError as e:
        raise PipelineError(f"intrinsics file not found: {p}") from e
    except (OSError, json.JSONDecodeError) as e:
        raise PipelineError(f"cannot read intrinsics JSON {p}: {e}") from e
    if not isinstance(data, dict):
        raise PipelineError(f"{p}: expected a JSON object with 'K' or 'fx', got {type(data).__name__}")
    try:
        if "K" in data:
            return check_K(np.asarray(data["K"], dtype=np.float64)), data
        if "fx" in data:
            if ("cx" not in data or "cy" not in data) and image_size is None:
                raise ValueError("cx/cy missing and no image size to default them to the centre")
            return K_from_values(data["fx"], data.get("fy"), data.get("cx"), data.get("cy"),
                                 image_size or (0, 0)), data
    except (TypeError, ValueError) as e:
        raise PipelineError(f"{p}: bad intrinsics: {e}") from e
    raise PipelineError(f"{p}: expected key 'K' (3x3) or 'fx' (+ 'fy', 'cx', 'cy'), got keys {sorted(data)}")


def read_instance_map(path: str | Path, image_size: tuple[int, int] | None = None) -> np.ndarray:
    """(H, W) uint16 instance ids from a single-channel 8- or 16-bit PNG (0 = background).

    image_size: (W, H) of the photo; the map must match it. PipelineError otherwise.
    """
    p = Path(path)
    if not p.is_file():
        raise PipelineError(f"instance map not found: {p}")
    m = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if m is None:
        raise PipelineError(f"cannot read instance map {p}")
    if m.ndim != 2:
        raise PipelineError(f"instance map {p} must be single-channel (16-bit ids), got shape {m.shape}")
    if m.dtype not in (np.uint8, np.uint16):
        raise PipelineError(f"instance map {p} must be 8- or 16-bit integer, got {m.dtype}")
    if image_size is not None and (m.shape[1], m.shape[0]) != tuple(image_size):
        raise PipelineError(f"instance map {p} is {m.shape[1]}x{m.shape[0]} but the photo is "
                            f"{image_size[0]}x{image_size[1]}")
    return m.astype(np.uint16)
