"""Window pose from its quad: cv2.solvePnP on the w x h rectangle (the paper: iterative LM).

Window frame: x along the wall, y up, z outward (toward the viewer), origin at the bottom-left
corner. Image corners TL, TR, BR, BL are the object points (0,h,0), (w,h,0), (w,0,0), (0,0,0).
Single-image scale is unknown: h is a parameter (default 1 m), or the user gives the true height or
width. Solvers (:data:`SOLVERS`, registered as per-window pose strategies in the one registry
``fenestra.pipeline.poses.POSES``):

- ``lm``: ``cv2.SOLVEPNP_ITERATIVE`` (homography initialisation, Levenberg-Marquardt refinement).
- ``ippe``: ``cv2.SOLVEPNP_IPPE`` (infinitesimal plane-based pose; of its two solutions the one
  with the smaller reprojection error whose window faces the camera).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import cv2
import numpy as np

from fenestra.checks import check_K
from fenestra.conventions import PAPER
from fenestra.errors import PipelineError


class PoseError(PipelineError):
    """No valid pose (solver failed, or the window would be behind the camera)."""


@dataclass(frozen=True)
class PoseResult:
    """R (3, 3), t (3,) m: window frame -> camera (OpenCV); reprojected (4, 2) px TL TR BR BL;
    width_m, height_m: the rectangle used; rms_px: reprojection RMS error."""

    R: np.ndarray
    t: np.ndarray
    reprojected: np.ndarray
    width_m: float
    height_m: float
    rms_px: float


def object_points(width_m: float, height_m: float) -> np.ndarray:
    """(4, 3) window-frame corners for image corners TL, TR, BR, BL."""
    if not (np.isfinite(width_m) and np.isfinite(height_m) and width_m > 0 and height_m > 0):
        raise ValueError(f"window size must be positive and finite, got width={width_m}, height={height_m}")
    w, h = float(width_m), float(height_m)
    return np.array([[0.0, h, 0.0], [w, h, 0.0], [w, 0.0, 0.0], [0.0, 0.0, 0.0]])


def window_size(ratio: float, height_m: float | None = 1.0, width_m: float | None = None) -> tuple[float, float]:
    """(width, height) m from the aspect ratio w / h and one known dimension (width wins if given)."""
    if not (np.isfinite(ratio) and ratio > 0):
        raise ValueError(f"aspect ratio must be positive and finite, got {ratio}")
    if width_m is not None:
        return float(width_m), float(width_m) / ratio
    if height_m is None:
        raise ValueError("give height_m or width_m (the scale of the window)")
    return ratio * float(height_m), float(height_m)


def _faces_camera(R: np.ndarray, t: np.ndarray) -> bool:
    """Window in front of the camera (z > 0) with its outward normal pointing at the camera."""
    return bool(t[2] > 0 and R[:, 2] @ t < 0)


def _finish(rvec: np.ndarray, tvec: np.ndarray, obj: np.ndarray, img: np.ndarray, K: np.ndarray) -> tuple:
    R, _ = cv2.Rodrigues(rvec)
    t = np.asarray(tvec, dtype=np.float64).reshape(3)
    proj, _ = cv2.projectPoints(obj, rvec, tvec, K, None)
    proj = proj.reshape(4, 2)
    return R, t, proj, float(np.sqrt(np.mean(np.sum((proj - img.reshape(4, 2)) ** 2, axis=1))))


def solve_lm(obj: np.ndarray, img: np.ndarray, K: np.ndarray) -> tuple:
    """SOLVEPNP_ITERATIVE: returns R, t, reprojected, rms."""
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, None, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise PoseError(f"solvePnP (ITERATIVE) failed for quad {img.tolist()}")
    return _finish(rvec, tvec, obj, img, K)


def solve_ippe(obj: np.ndarray, img: np.ndarray, K: np.ndarray) -> tuple:
    """SOLVEPNP_IPPE: best-reprojecting of its solutions that faces the camera."""
    n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, K, None, flags=cv2.SOLVEPNP_IPPE)
    if n == 0:
        raise PoseError(f"solvePnP (IPPE) failed for quad {img.tolist()}")
    sols = [_finish(r, t, obj, img, K) for r, t in zip(rvecs, tvecs)]
    facing = [s for s in sols if _faces_camera(s[0], s[1])] or sols
    return min(facing, key=lambda s: s[3])


@dataclass(frozen=True)
class PoseSolver:
    """A registered per-window solver: ``solve(object_points (4, 3), image_points (4, 1, 2), K) ->
    (R, t, reprojected (4, 2), rms_px)``; description: one line for CLI help and docs."""

    name: str
    solve: Callable[[np.ndarray, np.ndarray, np.ndarray], tuple]
    description: str


SOLVERS: tuple[PoseSolver, ...] = (  # the built-in per-window solvers (entries of pipeline.poses.POSES)
    PoseSolver("lm", solve_lm, "per window, cv2.solvePnP iterative Levenberg-Marquardt, the paper's"),
    PoseSolver("ippe", solve_ippe, "per window, cv2.solvePnP IPPE, the solution facing the camera"),
)


def estimate_pose(quad: np.ndarray, K: np.ndarray, ratio: float, height_m: float | None = 1.0,
                  width_m: float | None = None, solver: str | PoseSolver = PAPER.pose) -> PoseResult:
    """Pose of the w x h window imaged as ``quad`` (4, 2) px TL TR BR BL, with intrinsics K (3, 3).

    w = ratio * h with h = ``height_m`` (default 1 m), or h = width_m / ratio if ``width_m`` is
    given. solver: a PoseSolver, or the name of a per-window strategy of pipeline.poses.POSES.
    Raises ValueError for bad input or an unknown solver, PoseError if no valid pose.
    """
    if isinstance(solver, str):
        from fenestra.pipeline.poses import POSES  # noqa: PLC0415  (the registry holds this module's solvers)

        name, solver = solver, POSES[solver].solver
        if solver is None:
            raise ValueError(f"pose strategy {name!r} is per wall, not a per-window solver")
    img = np.asarray(quad, dtype=np.float64)
    if img.shape != (4, 2) or not np.all(np.isfinite(img)):
        raise ValueError(f"quad must be finite with shape (4, 2), got {img.tolist()}")
    K = check_K(K)
    w, h = window_size(ratio, height_m, width_m)
    obj = object_points(w, h)
    R, t, proj, rms = solver.solve(obj, img.reshape(4, 1, 2), K)
    if not _faces_camera(R, t):
        raise PoseError(f"pose puts the window behind the camera or facing away (t={t.round(3).tolist()})")
    return PoseResult(R=R, t=t, reprojected=proj, width_m=w, height_m=h, rms_px=rms)
