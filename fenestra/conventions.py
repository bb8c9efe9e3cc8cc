"""The one place that states Fenestra's conventions and tolerances.

Every other module imports from here; tests in ``tests/test_conventions.py`` pin them.

Units
    Metres, degrees for reported angles, pixels for image quantities.
World frame
    The IFC model's, z up.
Camera
    OpenCV: x right, y down, z forward. A pose is world-to-camera ``R`` (3x3), ``t`` (3,):
    ``X_cam = R @ X_world + t``. ``K`` is the 3x3 pinhole matrix.
    pyrender and mitsuba use OpenGL-style cameras (x right, y up, z backward); convert only with
    :func:`cv_to_gl_pose` / :data:`CV_TO_GL`.
Pixels
    The centre of pixel (u, v) is at coordinate (u, v); an image of width W spans [-0.5, W-0.5].
    pyrender's ``IntrinsicsCamera`` puts pixel centres at half-integers: pass it
    ``cx + PYRENDER_PIXEL_OFFSET`` and ``cy + PYRENDER_PIXEL_OFFSET``.
Corner order
    TL, TR, BR, BL in the image (clockwise on screen). In the window's own frame the same corners
    are (0, h), (w, h), (w, 0), (0, 0)  -- x along the wall, y up, seen from outside -- so the
    image TL corner is the window's top-left as seen from outside.
Ground-truth window
    The void rectangle on the wall's exterior face, from IfcWindow + its IfcOpeningElement.
    Aspect ratio = width / height.
Colour order
    RGB at every API boundary (a photo, a render, ``detect()``, ``reconstruct()``); BGR only inside
    calls to OpenCV's reading/writing/drawing functions.
Default strategies
    :data:`DEFAULTS` (what a user gets: `make bench`'s best with a learned detector's masks, README
    "The answer") and :data:`PAPER` (the paper's method: the reference rows of comparisons).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.methods import Method

# Corner names in the documented order.
CORNER_NAMES: tuple[str, ...] = ("TL", "TR", "BR", "BL")

# OpenCV camera axes -> OpenGL camera axes (flip y and z).
CV_TO_GL = np.diag([1.0, -1.0, -1.0])

# pyrender IntrinsicsCamera draws 0.5 px up-left of OpenCV's convention; add this to cx, cy.
PYRENDER_PIXEL_OFFSET = 0.5


# One choice per pluggable stage is a fenestra.methods.Method: the same type for the defaults, the
# bench's methods and the reports' rows.


# What `fenestra reconstruct` and ReconstructConfig() use: the README's measured best for a learned
# detector's masks (line-based snapping, the per-wall shared plane with the façade's line segments).
DEFAULTS = Method(detector="default", snapper="linefit", pose="wall+lines")
# The paper's method (Mask R-CNN, Harris snapping, per-window iterative PnP): the reference in comparisons.
PAPER = Method(detector="maskrcnn", snapper="harris", pose="lm")


@dataclass(frozen=True)
class Tolerances:
    """Numerical tolerances used by checks and tests (units in the names)."""

    gt_size_vs_ifc_m: float = 0.005  # loader width/height vs IfcWindow OverallWidth/Height
    gt_right_angle_deg: float = 0.01  # ground-truth rectangle corners
    gt_coplanar_m: float = 1e-6  # corners vs wall face plane
    generator_roundtrip_m: float = 1e-6  # procedural house: loader vs generator parameters
    projection_vs_mask_px: float = 0.1  # projected GT corners vs instance-map edges
    distortion_roundtrip_px: float = 1e-3
    backend_instance_iou: float = 0.99  # pyrender vs mitsuba instance maps
    exact_aspect_rel: float = 1e-6  # aspect ratio from an exact synthetic quad
    exact_rotation_deg: float = 1e-4  # pose from an exact synthetic quad
    parallel_sides_deg: float = 0.05  # opposite image sides closer than this count as parallel
    match_iou: float = 0.5  # detection <-> ground truth matching
    recall_thresholds_px: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0)
    # façade geometry (pipeline/facade.py, pipeline/walls.py)
    wall_vp_angle_deg: float = 1.5  # a side points at its wall's vanishing point within this ...
    wall_corner_noise_px: float = 1.5  # ... plus the angle that this corner noise makes on its length
    wall_sigma_px: float = 0.5  # prior corner sigma (px) pooled with the wall fit's residuals
    wall_sigma_prior_dof: float = 4.0  # pseudo-observations given to that prior
    ill_conditioned_aspect_rel: float = 0.05  # 90 % half-width of w/h above this: ill-conditioned
    ill_conditioned_rot_deg: float = 5.0  # 90 % bound of the rotation error above this: ill-conditioned
    wall_outlier_factor: float = 3.0  # a window whose corner RMS in its wall fit exceeds this x the median ...
    wall_outlier_px: float = 1.0  # ... and this (px) is split off into a wall of its own
    manhattan_deg: float = 8.0  # walls this close to k x 90 deg about a shared vertical are tied
    focal_max_rel_sd: float = 0.25  # a wall's focal estimate with larger relative sd is not used
    interval_level: float = 0.90  # the reported uncertainty intervals


TOL = Tolerances()


def check_K(K: np.ndarray) -> np.ndarray:
    """Validate an intrinsics matrix; return it as float64 (3, 3).

    Raises ValueError naming the bad value: wrong shape, non-finite, non-positive focal lengths,
    or a last row other than (0, 0, 1).
    """
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3):
        raise ValueError(f"K must be 3x3, got shape {K.shape}")
    if not np.all(np.isfinite(K)):
        raise ValueError(f"K has non-finite entries: {K.tolist()}")
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ValueError(f"K focal lengths must be positive, got fx={K[0, 0]}, fy={K[1, 1]}")
    if not np.allclose(K[2], [0.0, 0.0, 1.0]):
        raise ValueError(f"K last row must be [0, 0, 1], got {K[2].tolist()}")
    return K


def check_quad(quad: np.ndarray, name: str = "quad") -> np.ndarray:
    """Validate an image quadrilateral: (4, 2) finite px, TL TR BR BL; return it as float64.

    Raises ValueError naming ``name`` and the bad value.
    """
    q = np.asarray(quad, dtype=np.float64)
    if q.shape != (4, 2):
        raise ValueError(f"{name} must have shape (4, 2) (TL, TR, BR, BL px), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError(f"{name} has non-finite entries: {q.tolist()}")
    return q


def make_K(fx: float, fy: float | None = None, cx: float = 0.0, cy: float = 0.0) -> np.ndarray:
    """3x3 pinhole matrix from focal lengths (px) and principal point (px)."""
    fy = fx if fy is None else fy
    return check_K(np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]))


def K_from_fov(width: int, height: int, hfov_deg: float) -> np.ndarray:
    """Square-pixel K for an image of ``width`` x ``height`` px with horizontal FOV in degrees.

    The principal point is the image centre, ((W-1)/2, (H-1)/2) under the pixel-centre convention.
    """
    if not 0.0 < hfov_deg < 180.0:
        raise ValueError(f"hfov_deg must be in (0, 180), got {hfov_deg}")
    f = 0.5 * width / np.tan(np.radians(hfov_deg) / 2.0)
    return make_K(f, f, (width - 1) / 2.0, (height - 1) / 2.0)


def project(K: np.ndarray, R: np.ndarray, t: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Pinhole projection of world points X (N, 3) m -> pixels (N, 2); no distortion.

    Points behind the camera still project (with flipped sign); check depth separately.
    """
    X = np.asarray(X, dtype=np.float64).reshape(-1, 3)
    Xc = X @ np.asarray(R, dtype=np.float64).T + np.asarray(t, dtype=np.float64).reshape(1, 3)
    x = Xc @ np.asarray(K, dtype=np.float64).T
    return x[:, :2] / x[:, 2:3]


def camera_depths(R: np.ndarray, t: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Depth (camera z, m) of world points X (N, 3)."""
    X = np.asarray(X, dtype=np.float64).reshape(-1, 3)
    return X @ np.asarray(R)[2] + float(np.asarray(t).reshape(3)[2])


def cv_to_gl_pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """World-to-camera OpenCV pose -> 4x4 camera-to-world pose of an OpenGL camera (pyrender)."""
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    T = np.eye(4)
    T[:3, :3] = R.T @ CV_TO_GL
    T[:3, 3] = -R.T @ t
    return T


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = (0.0, 0.0, 1.0),
            roll_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV world-to-camera (R, t) for a camera at ``eye`` looking at ``target``.

    ``up`` is the world direction that appears upward in the image (default world z); ``roll_deg``
    rotates the camera about its optical axis (positive = image content turns clockwise).
    """
    eye = np.asarray(eye, dtype=np.float64)
    z = np.asarray(target, dtype=np.float64) - eye
    n = np.linalg.norm(z)
    if n < 1e-12:
        raise ValueError(f"look_at: eye {eye.tolist()} equals target")
    z /= n
    x = np.cross(z, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(x) < 1e-9:
        raise ValueError(f"look_at: view direction {z.tolist()} is parallel to up {list(up)}")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    if roll_deg:
        c, s = np.cos(np.radians(roll_deg)), np.sin(np.radians(roll_deg))
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R
    return R, -R @ eye


def rotation_error_deg(R_est: np.ndarray, R_gt: np.ndarray) -> float:
    """Geodesic angle (deg) between two rotation matrices."""
    c = (np.trace(np.asarray(R_est) @ np.asarray(R_gt).T) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


@dataclass(frozen=True)
class InputLimits:
    """Bounds on one photo's input, so memory and time stay bounded (pipeline/, issue 16).

    max_windows_per_photo: instance ids (or detections) per photo; beyond it reconstruct stops with
        an error naming the count (each window costs ~10 ms and its share of the IFC export).
    detector_max_side_px: learned detectors see the photo resized so its long side is at most
        this (INTER_AREA); their masks and boxes are mapped back to full resolution.
    fov_min_deg / fov_max_deg: a horizontal or vertical field of view outside this range
        (from K and the photo size) is reported as a warning: the focal length is probably wrong.
    max_json_bytes: a JSON input (annotations.json, K.json) larger than this is refused before it
        is read (json.loads of a 400 MB file takes several GB).
    """

    max_windows_per_photo: int = 1000
    detector_max_side_px: int = 1024
    fov_min_deg: float = 1.0
    fov_max_deg: float = 170.0
    max_json_bytes: int = 64 * 2**20


LIMITS = InputLimits()
