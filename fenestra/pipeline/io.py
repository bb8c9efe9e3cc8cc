"""Reading the pipeline's inputs besides the pixels: intrinsics (JSON or fx/fy/cx/cy), lens
distortion, and what the photo file says about itself (EXIF orientation, damage). The photo and an
instance map (``--masks``) are read by the one reader of every stage, :mod:`fenestra.images`.

Every problem raises :class:`fenestra.errors.PipelineError` naming the file or the bad value.

An intrinsics JSON may carry OpenCV distortion coefficients beside K (``"distortion": [k1, k2, p1,
p2[, k3[, ...]]]``, 4, 5, 8, 12 or 14 numbers, or null): :func:`read_camera` returns both, and
:func:`undistort_photo` resamples a photo to the pinhole image of the *same* K, so K stays valid.
"""
from __future__ import annotations

import contextlib
import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fenestra.checks import check_K
from fenestra.conventions import LIMITS, make_K
from fenestra.errors import PipelineError, bounded
from PIL import Image


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
    size: tuple[int, int] | None = None  # (W, H) px the K file states it is for, if it does

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
        raise PipelineError(f"distortion must be a list of numbers, got {bounded(repr(values))}") from e
    if d.ndim != 1 or d.size not in DISTORTION_SIZES:
        raise PipelineError(f"distortion must be a flat list of {', '.join(map(str, DISTORTION_SIZES))} "
                            f"OpenCV coefficients (k1, k2, p1, p2, k3, ...), got {bounded(repr(values))}")
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
    return Camera(K=K, distortion=dist, size=_stated_size(path, data))


def _stated_size(path: str | Path, data: dict) -> tuple[int, int] | None:
    """(W, H) from an intrinsics JSON's optional "width"/"height"; PipelineError if malformed."""
    if "width" not in data and "height" not in data:
        return None
    w, h = data.get("width"), data.get("height")
    if not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in (w, h)):
        raise PipelineError(f"{Path(path)}: 'width' and 'height' must both be positive integers (px), got {w!r}, {h!r}")
    return w, h


SWAPS_AXES = (5, 6, 7, 8)  # EXIF orientations that rotate by 90 degrees (width and height swap)


@contextlib.contextmanager
def pil_open(path: str | Path):
    """PIL's Image.open without its DecompressionBombWarning (the photo's size was checked before
    decoding: fenestra.images.check_size)."""

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)
        with Image.open(path) as im:
            yield im


def photo_orientation(path: str | Path) -> int:
    """EXIF orientation tag (1-8) of an image file; 1 when absent or unreadable."""

    try:
        with pil_open(path) as im:
            v = im.getexif().get(0x0112, 1)
    except (OSError, ValueError, Image.DecompressionBombError):
        return 1
    return v if isinstance(v, int) and 1 <= v <= 8 else 1


def photo_warnings(path: str | Path) -> list[str]:
    """Problems cv2 decodes through silently: a truncated file (the rest comes out grey)."""

    try:
        with pil_open(path) as im:
            im.load()
    except Image.DecompressionBombError:  # beyond PIL's own bound (--max-pixels raised): not checked
        return []
    except OSError as e:
        return [f"photo {Path(path)} is damaged ({' '.join(str(e).split())}): part of it decodes as grey"]
    return []


def fit_camera_to_photo(camera: Camera, size: tuple[int, int], orientation: int = 1) -> tuple[Camera, list[str]]:
    """The camera for a photo of ``size`` (W, H) px as displayed (EXIF ``orientation`` applied, as
    cv2.imread does), and warnings.

    If the K file states its size: the same size passes; the size before an EXIF 90-degree
    rotation is an error (K would have to rotate too); another size with the same aspect ratio
    rescales K (pixel centres at integers) with a warning; anything else is an error.
    """
    if camera.size is None or tuple(camera.size) == tuple(size):
        return camera, []
    (w, h), (W, H) = camera.size, size
    if orientation in SWAPS_AXES and (h, w) == (W, H):
        raise PipelineError(f"K is for a {w}x{h} image but the photo's EXIF orientation {orientation} turns it "
                            f"to {W}x{H}; give K for the upright {W}x{H} photo")
    s = W / w
    if abs(H / h - s) > 1e-3 * s:
        raise PipelineError(f"K is for a {w}x{h} image but the photo is {W}x{H} (another aspect ratio)")
    K = camera.K.copy()
    K[:2, :2] *= s
    K[:2, 2] = (K[:2, 2] + 0.5) * s - 0.5
    warning = f"K is for a {w}x{h} image; rescaled by {s:.4g} to the {W}x{H} photo"
    return Camera(K=K, distortion=camera.distortion, size=(W, H)), [warning]


def intrinsics_warnings(K: np.ndarray, size: tuple[int, int]) -> list[str]:
    """Warnings for a K that does not look like this (W, H) photo's: principal point outside the
    image, or a field of view outside LIMITS.fov_min_deg .. fov_max_deg (focal length wrong?)."""
    W, H = size
    cx, cy = K[0, 2], K[1, 2]
    out = []
    if not (-0.5 <= cx <= W - 0.5 and -0.5 <= cy <= H - 0.5):
        out.append(f"principal point ({cx:.1f}, {cy:.1f}) px lies outside the {W}x{H} photo")
    for axis, n, f in (("horizontal", W, K[0, 0]), ("vertical", H, K[1, 1])):
        fov = float(np.degrees(2 * np.arctan2(n / 2.0, f)))
        if not LIMITS.fov_min_deg <= fov <= LIMITS.fov_max_deg:
            out.append(f"{axis} field of view {fov:.3g} deg (f = {f:.4g} px over {n} px) is outside "
                       f"{LIMITS.fov_min_deg:g}..{LIMITS.fov_max_deg:g} deg: is the focal length right?")
    return out


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
        if p.stat().st_size > LIMITS.max_json_bytes:  # refused before reading (LIMITS states the bound)
            raise PipelineError(f"intrinsics file {p} is {p.stat().st_size / 2**20:.1f} MB, more than the "
                                f"{LIMITS.max_json_bytes / 2**20:.0f} MB limit (fenestra.conventions.LIMITS)")
        if not p.is_file():
            raise PipelineError(f"intrinsics file {p} is not a regular file")
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError as e:
        raise PipelineError(f"intrinsics file not found: {p}") from e
    except UnicodeDecodeError as e:  # a binary file: JSON is UTF-8 text
        raise PipelineError(f"intrinsics file {p} is not JSON (not UTF-8 text: byte {e.object[e.start]:#04x} "
                            f"at offset {e.start})") from e
    except (OSError, ValueError, RecursionError) as e:  # ValueError: not JSON, or a number of > 4300 digits
        why = "nested too deeply" if isinstance(e, RecursionError) else bounded(e)
        raise PipelineError(f"cannot read intrinsics JSON {p}: {why}") from e
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
