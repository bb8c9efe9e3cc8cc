"""The paper's calibration step (OpenCV): K and lens distortion from photos of a chessboard, with
the RMS reprojection error (:func:`calibrate_chessboard`), and the K.json that ``--K`` reads
(:func:`calibration_json`)."""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fenestra.errors import PipelineError


@dataclass(frozen=True)
class Calibration:
    """A chessboard calibration.

    K: (3, 3) px; distortion: (5,) OpenCV k1 k2 p1 p2 k3; rms_px: RMS reprojection error (px) over
    all corners; image_size: (W, H) px; n_images: photos where the board was found, of n_given.
    """

    K: np.ndarray
    distortion: np.ndarray
    rms_px: float
    image_size: tuple[int, int]
    n_images: int
    n_given: int


def board_points(pattern: tuple[int, int], square_m: float) -> np.ndarray:
    """(cols*rows, 3) float32 inner-corner coordinates (m) of a chessboard of ``pattern`` (cols, rows)
    inner corners and squares ``square_m`` (m) wide, z = 0, OpenCV's row-major order."""
    cols, rows = pattern
    g = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2)
    return np.hstack([g * float(square_m), np.zeros((len(g), 1))]).astype(np.float32)


def find_corners(gray: np.ndarray, pattern: tuple[int, int]) -> np.ndarray | None:
    """Sub-pixel inner corners (cols*rows, 2) px of a chessboard of ``pattern`` (cols, rows) in an
    (H, W) uint8 gray image, or None where the board is not found."""
    ok, c = cv2.findChessboardCorners(gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        return None
    c = cv2.cornerSubPix(gray, c, (5, 5), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4))
    return c.reshape(-1, 2)


def calibrate_chessboard(images: list[np.ndarray], pattern: tuple[int, int], square_m: float = 1.0,
                         fix_aspect: bool = False) -> Calibration:
    """Calibrate a camera from chessboard photos.

    Args:
        images: (H, W) uint8 gray or (H, W, 3) RGB photos, one size.
        pattern: inner corners (cols, rows), each >= 2.
        square_m: a square's side (m): the unit of the board's poses.
        fix_aspect: keep fx / fy fixed (OpenCV's CALIB_FIX_ASPECT_RATIO).
    Returns:
        The :class:`Calibration`.
    Raises:
        PipelineError for a bad pattern, photos of several sizes, or a board found in fewer than 3.
    """
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
