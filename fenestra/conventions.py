"""The one place that states Fenestra's conventions (tolerances: :mod:`fenestra.tolerances`; the
checks of values that follow them: :mod:`fenestra.checks`).

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

from fenestra.checks import check_K
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
# detector's masks (the learned corner refinement, the per-wall shared plane with the façade's line
# segments; docs/DESIGN.md, Decisions).
DEFAULTS = Method(detector="default", snapper="refine", pose="wall+lines")
# The paper's method (Mask R-CNN, Harris snapping, per-window iterative PnP): the reference in comparisons.
PAPER = Method(detector="maskrcnn", snapper="harris", pose="lm")
# Window classes the figures single out: thin, aspect (width / height) >= THIN_ASPECT or
# <= 1 / THIN_ASPECT; oblique, seen at an incidence (angle between the view ray and the window's
# normal, degrees) in OBLIQUE_INCIDENCE_DEG = [low, high).
THIN_ASPECT = 3.0
OBLIQUE_INCIDENCE_DEG = (60.0, 80.0)
# Floors of an exported building (pipeline.export.floors): two floors are at least MIN_STOREY_M
# apart (a lower clear height is no storey: a mezzanine row, a sign, a door's transom); a storey
# height is measured from the main wall's row spacings up to MAX_STOREY_M (a St Petersburg shop
# floor's 5 m; a wider spacing is a missing row, several storeys), else ASSUMED_STOREY_M.
MIN_STOREY_M = 2.2
MAX_STOREY_M = 5.0
ASSUMED_STOREY_M = 3.0


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


def vote_axis(axes: np.ndarray, weights: np.ndarray, agree_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(axis (3,), inliers (G,) bool): of unit axes (G, 3) with weights (G,) (e.g. walls' up axes,
    weighted by their windows), the one the most weight agrees with within agree_deg (ties: the
    first), refined as the weighted mean of the axes that agree with it."""
    a = np.asarray(axes, dtype=np.float64).reshape(-1, 3)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if not len(a) or len(a) != len(w):
        raise ValueError(f"vote_axis needs as many weights as axes (>= 1), got {len(a)} axes and {len(w)} weights")
    agree = a @ a.T >= np.cos(np.radians(agree_deg))  # (G, G)
    inliers = agree[int(np.argmax(agree @ w))]
    axis = (w[inliers, None] * a[inliers]).sum(axis=0)
    return axis / np.linalg.norm(axis), inliers


def heading_difference_deg(n_a: np.ndarray, n_b: np.ndarray, up: np.ndarray) -> float:
    """Angle (deg, 0-180) between two plane normals (3,) seen from above: their components
    perpendicular to the unit ``up`` (3,), so a difference of tilt (a wall's noisy vertical) does
    not count; 180 when either normal is along ``up`` (a horizontal plane has no heading)."""
    u = np.asarray(up, dtype=np.float64)
    h = [np.asarray(n, dtype=np.float64) - (np.asarray(n, dtype=np.float64) @ u) * u for n in (n_a, n_b)]
    norms = [float(np.linalg.norm(x)) for x in h]
    if min(norms) < 1e-9:
        return 180.0
    return float(np.degrees(np.arccos(np.clip(h[0] @ h[1] / (norms[0] * norms[1]), -1.0, 1.0))))


@dataclass(frozen=True)
class InputLimits:
    """Bounds on one photo's input, so memory and time stay bounded (pipeline/).

    max_windows_per_photo: instance ids (or detections) per photo; beyond it reconstruct stops with
        an error naming the count (each window costs ~10 ms and its share of the IFC export).
    detector_max_side_px: learned detectors see the photo resized so its long side is at most
        this (INTER_AREA); their masks and boxes are mapped back to full resolution.
    lsd_max_pixels: a photo's whole-image line segments (pipeline.segments.whole_image_segments)
        are found on a copy of at most this many pixels (INTER_AREA), mapped back to full
        resolution (LSD on 12 Mpx: ~1 CPU-s; on 4 Mpx: ~0.3; every bundled photo and render is
        smaller, so theirs are unchanged).
    max_facade_segments: the walls' façade lines (pipeline.walls.lines.photo_segments) keep at
        most this many of the photo's segments, the longest (their vanishing-point consensus costs
        segments x hypotheses: 3000 segments of a 12 Mpx photo took 5.6 CPU-s; the real test photos
        and the street photos of spb_facades/train have at most ~1000 at least 20 px long).
    inpaint_max_side_px: the export's void inpainting (Telea, pipeline.export.inpaint) works on a
        copy of the texture with its long side at most this; the fill, upsampled, replaces only the
        void pixels of the full-size texture (Telea's cost grows with the void pixels: 7 CPU-s at
        3851 x 3116 px).
    glb_png_compress_level: zlib level of model.glb's PNG texture (pipeline.export.mesh.png_image:
        lossless either way; 1 encodes a 12 Mpx texture in ~0.6 CPU-s, the default 6 in ~2.4 s, for
        a ~25 % larger file).
    fov_min_deg / fov_max_deg: a horizontal or vertical field of view outside this range
        (from K and the photo size) is reported as a warning: the focal length is probably wrong.
    max_json_bytes: a JSON input (annotations.json, K.json) larger than this is refused before it
        is read (json.loads of a 400 MB file takes several GB).
    max_image_pixels / max_image_bytes: an image file whose header states more pixels, or whose
        file is larger, is refused before it is decoded (fenestra.images; a 12000 x 9000 photo,
        108 Mpx, passes; ``fenestra reconstruct --max-pixels`` raises the pixel bound).
    max_render_side_px: the longest side a render may have (OpenGL renderbuffers of the software
        rasteriser stop at 8192 or 16384 px).
    max_label_bytes / max_label_lines: a dataset's label file (YOLO txt) larger than this, or with
        more lines, is refused before its lines are parsed (a 108 MB file of 6 million boxes took
        4.6 GB). A COCO RLE mask is an image: its stated size is bounded by max_image_pixels and
        must be its photo's, and an image's window annotations by max_windows_per_photo, all
        checked before any mask is decoded.
    max_procedural_houses / max_views_per_dataset / max_views_per_run: a benchmark profile's
        ``scenes.procedural``, its ``render.views_per_house`` (and ``fenestra render --views``), and
        its houses x views, checked when the profile is loaded (the ``scale`` profile renders
        20 x 500 views; each view costs ~0.2 s and its rows).
    max_storeys / max_windows_per_wall / max_house_windows: a procedural house's storeys, windows per
        wall and storey, and walls x storeys x windows per wall, checked before any IFC entity is made.
    max_dataset_photos: the photos a dataset may list (a folder's photos, a COCO file's images),
        checked before the first is read.
    """

    max_windows_per_photo: int = 1000
    detector_max_side_px: int = 1024
    lsd_max_pixels: int = 4_000_000
    max_facade_segments: int = 1500
    inpaint_max_side_px: int = 1024
    glb_png_compress_level: int = 1
    fov_min_deg: float = 1.0
    fov_max_deg: float = 170.0
    max_json_bytes: int = 64 * 2**20
    max_image_pixels: int = 150_000_000
    max_image_bytes: int = 512 * 2**20
    max_render_side_px: int = 8192
    max_label_bytes: int = 4 * 2**20
    max_label_lines: int = 100_000
    max_procedural_houses: int = 1000
    max_views_per_dataset: int = 10_000
    max_views_per_run: int = 100_000
    max_storeys: int = 100
    max_windows_per_wall: int = 100
    max_house_windows: int = 10_000
    max_dataset_photos: int = 100_000

    def check(self, name: str, value: int, what: str, error: type[Exception] = ValueError) -> int:
        """``value`` when it is at most the bound ``name`` (a field of this class); else ``error``
        naming ``what`` (the key or option the user gave), the value and the bound, raised before
        anything of that size is allocated."""
        bound = getattr(self, name)
        if value > bound:
            raise error(f"{what} = {value} is more than the {bound} allowed (fenestra.conventions.LIMITS.{name})")
        return value


LIMITS = InputLimits()
