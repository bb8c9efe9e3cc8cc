"""Intrinsics when the user gives none: from the façade, from EXIF, or from chessboard photos.

Order used by ``fenestra reconstruct`` without --K/--fx (:func:`resolve_K`):

1. ``vanishing points``: the focal length from the walls' two orthogonal vanishing directions,
   refined over all their windows' corners (pipeline.walls.focal_from_walls); principal point at
   the image centre, square pixels.
2. ``exif``: FocalLengthIn35mmFilm (f_px = f35 / 36 mm * max(W, H)), else FocalLength (mm) with
   FocalPlaneXResolution (px per unit of FocalPlaneResolutionUnit) rescaled to the photo's width.
3. Otherwise a PipelineError saying what was tried.

:func:`calibrate_chessboard` is the paper's calibration step (OpenCV): K and distortion from
photos of a chessboard, with the RMS reprojection error; :func:`calibration_json` writes the
K.json that ``--K`` reads.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from fenestra.errors import PipelineError

if TYPE_CHECKING:  # annotations only; pipeline.walls is imported lazily below
    from pipeline.segments import SegmentCache
    from pipeline.walls import WallParams

FULL_FRAME_WIDTH_MM = 36.0  # the 35 mm-equivalent focal length refers to a 36 x 24 mm frame
EXIF_IFD = 0x8769
TAG_FOCAL = 0x920A
TAG_FOCAL_35 = 0xA405
TAG_PLANE_XRES = 0xA20E
TAG_PLANE_UNIT = 0xA210
PLANE_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0}  # inch, cm, mm


def centred_K(focal_px: float, image_size: tuple[int, int]) -> np.ndarray:
    """Square-pixel K (3, 3) with focal ``focal_px`` and the principal point at the centre of an
    image of ``image_size`` (W, H) px."""
    W, H = image_size
    if not (np.isfinite(focal_px) and focal_px > 0):
        raise PipelineError(f"focal length must be positive, got {focal_px}")
    return np.array([[focal_px, 0.0, (W - 1) / 2.0], [0.0, focal_px, (H - 1) / 2.0], [0.0, 0.0, 1.0]])


def focal_from_exif_tags(tags: dict, image_size: tuple[int, int]) -> tuple[float, str] | None:
    """(focal px, how) from EXIF tags {tag id: value}, or None if they do not give it.

    tags: FocalLengthIn35mmFilm (0xA405, mm), FocalLength (0x920A, mm), FocalPlaneXResolution
    (0xA20E, px per unit), FocalPlaneResolutionUnit (0xA210: 2 inch, 3 cm, 4 mm). image_size (W, H).
    """
    W, H = image_size
    f35 = tags.get(TAG_FOCAL_35)
    if f35 and float(f35) > 0:
        return float(f35) / FULL_FRAME_WIDTH_MM * max(W, H), f"exif FocalLengthIn35mmFilm {float(f35):g} mm"
    f_mm, xres = tags.get(TAG_FOCAL), tags.get(TAG_PLANE_XRES)
    unit = PLANE_UNIT_MM.get(int(tags.get(TAG_PLANE_UNIT, 2)))
    if f_mm and xres and unit and float(f_mm) > 0 and float(xres) > 0:
        px_per_mm = float(xres) / unit
        return float(f_mm) * px_per_mm, f"exif FocalLength {float(f_mm):g} mm x FocalPlaneXResolution {px_per_mm:g} px/mm"
    return None


def read_exif_tags(path: str | Path) -> dict:
    """{tag id: value} of a photo's EXIF (main IFD and the Exif sub-IFD); {} if it has none."""
    from PIL import Image  # noqa: PLC0415

    try:
        with Image.open(path) as im:
            exif = im.getexif()
            tags = dict(exif)
            tags.update(exif.get_ifd(EXIF_IFD))
    except (OSError, ValueError):
        return {}
    return tags


def focal_from_exif(path: str | Path, image_size: tuple[int, int]) -> tuple[float, str] | None:
    """(focal px, how) from the photo file's EXIF, or None. Note: FocalPlaneXResolution refers to
    the sensor's full resolution; it is used as is (photos resized after capture give a wrong f)."""
    return focal_from_exif_tags(read_exif_tags(path), image_size)


@dataclass(frozen=True)
class ResolvedK:
    """K (3, 3) and where it came from: source in "vanishing points" | "exif"; detail: how."""

    K: np.ndarray
    source: str
    detail: str


def resolve_K(photo: str | Path, quads: np.ndarray, image_size: tuple[int, int],
              wall: WallParams | None = None, segment_cache: SegmentCache | None = None) -> ResolvedK:
    """Intrinsics for a photo without --K: façade vanishing points, else EXIF, else PipelineError.

    quads: (N, 4, 2) px snapped window quads of the photo; image_size (W, H); wall: the per-wall
    strategy's parameters (default ``WallParams()``; with ``lines`` the photo's façade segments join
    the focal fit, which needs segment_cache, the photo's pipeline.segments.SegmentCache).
    """
    from pipeline.walls import WallParams, focal_from_walls  # noqa: PLC0415

    W, H = image_size
    why = "no window quads"
    if len(quads):
        try:
            f, sd = focal_from_walls(np.asarray(quads, dtype=np.float64), (H, W), wall or WallParams(), segment_cache)
            return ResolvedK(centred_K(f, image_size), "vanishing points",
                             f"f = {f:.1f} +- {sd:.1f} px from {len(quads)} window(s)"
                             f"{' and the facade line segments' if wall is not None and wall.lines else ''}, "
                             "principal point at the image centre")
        except PipelineError as e:
            why = str(e)
    exif = focal_from_exif(photo, image_size)
    if exif is not None:
        return ResolvedK(centred_K(exif[0], image_size), "exif", f"{exif[1]} (vanishing points: {why})")
    raise PipelineError(f"no intrinsics for {photo}: vanishing points failed ({why}) and the photo has no "
                        f"EXIF focal length; give --K K.json or --fx F (or `fenestra calibrate`)")


# ------------------------------------------------------------------ chessboard calibration

@dataclass(frozen=True)
class Calibration:
    """K (3, 3), distortion (5,) OpenCV k1 k2 p1 p2 k3, rms_px: RMS reprojection error over all
    corners; image_size (W, H); n_images: photos where the board was found, of n_given."""

    K: np.ndarray
    distortion: np.ndarray
    rms_px: float
    image_size: tuple[int, int]
    n_images: int
    n_given: int


def board_points(pattern: tuple[int, int], square_m: float) -> np.ndarray:
    """(cols*rows, 3) inner-corner coordinates (m) of a chessboard, z = 0, OpenCV's row-major order."""
    cols, rows = pattern
    g = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2)
    return np.hstack([g * float(square_m), np.zeros((len(g), 1))]).astype(np.float32)


def find_corners(gray: np.ndarray, pattern: tuple[int, int]) -> np.ndarray | None:
    """Sub-pixel inner corners (cols*rows, 2) px of a chessboard in a uint8 gray image, or None."""
    ok, c = cv2.findChessboardCorners(gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        return None
    c = cv2.cornerSubPix(gray, c, (5, 5), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4))
    return c.reshape(-1, 2)


def calibrate_chessboard(images: list[np.ndarray], pattern: tuple[int, int], square_m: float = 1.0,
                         fix_aspect: bool = False) -> Calibration:
    """Calibrate from chessboard photos (uint8 gray or RGB, one size) with ``pattern`` = inner
    corners (cols, rows). Needs the board in >= 3 photos; PipelineError otherwise."""
    if len(pattern) != 2 or min(pattern) < 2:
        raise PipelineError(f"pattern must be (cols, rows) inner corners >= 2, got {pattern}")
    sizes = {im.shape[:2] for im in images}
    if len(sizes) != 1:
        raise PipelineError(f"calibration photos must share one size, got {sorted(sizes)}")
    H, W = sizes.pop()
    obj, img = [], []
    for im in images:
        gray = im if im.ndim == 2 else cv2.cvtColor(im, cv2.COLOR_RGB2GRAY)
        c = find_corners(gray, pattern)
        if c is not None:
            obj.append(board_points(pattern, square_m))
            img.append(c.astype(np.float32))
    if len(img) < 3:
        raise PipelineError(f"chessboard {pattern[0]}x{pattern[1]} found in {len(img)} of {len(images)} photos; need >= 3")
    flags = cv2.CALIB_FIX_ASPECT_RATIO if fix_aspect else 0
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, (W, H), None, None, flags=flags)
    return Calibration(K=np.asarray(K, dtype=np.float64), distortion=np.asarray(dist, dtype=np.float64).ravel()[:5],
                       rms_px=float(rms), image_size=(W, H), n_images=len(img), n_given=len(images))


def calibration_json(cal: Calibration) -> dict:
    """The K.json document ``--K`` reads (pipeline.io.read_camera), with the calibration's quality."""
    W, H = cal.image_size
    return {"K": cal.K.tolist(), "distortion": cal.distortion.tolist(), "width": W, "height": H,
            "reprojection_rms_px": cal.rms_px, "n_images": cal.n_images, "n_given": cal.n_given,
            "source": "fenestra calibrate (OpenCV chessboard calibration)"}
