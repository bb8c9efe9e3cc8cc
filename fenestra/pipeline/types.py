"""Data types passed between pipeline stages (the pipeline/ contract).

pipeline/ is the system a user runs on one photo: it must not import bench/, renders/ or scenes/.
Images cross every pipeline API boundary (fenestra.images.read_image, detect, reconstruct, write_outputs,
substitute) as (H, W, 3) uint8 **RGB**, checked by :func:`fenestra.checks.check_image`; BGR exists
only inside calls to OpenCV's reading, writing and drawing functions.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np


class AspectCase(str, Enum):
    """How a window's aspect ratio was conditioned: which opposite image sides are parallel
    (pipeline.aspect.classify), or, after a per-wall fit, ``ILL_CONDITIONED`` (its 90 % interval
    too wide: pipeline.walls). A str: it compares equal to, and is written as, its value."""

    GENERAL = "general"
    ONE_PAIR_PARALLEL = "one_pair_parallel"
    FRONTO_PARALLEL = "fronto_parallel"
    ILL_CONDITIONED = "ill_conditioned"

    def __str__(self) -> str:
        return self.value


class Status(str, Enum):
    """A window's outcome, every state a results row holds: ``OK`` (posed), ``FAILED`` (a stage
    failed: ``failure``), ``MISSED`` (a labelled window no detection matched, or a method that
    cannot run on the view: the bench's rows). A str: it compares equal to, and is written as, its value."""

    OK = "ok"
    FAILED = "failed"
    MISSED = "missed"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class Unavailable:
    """A value a step could not give, and why: ``reason``, one line in the user's words (e.g. an
    EXIF focal length outside the plausible range). Returned where a value would be, so that the
    caller tests ``isinstance(x, Unavailable)``; ``str(u)`` is the reason."""

    reason: str

    def __str__(self) -> str:
        return self.reason


STAGES = ("quad", "snap", "aspect", "pose", "wall", "geometry")  # where a window can fail


@dataclass(frozen=True)
class Failure:
    """Why a window has no (full) result: the stage (one of :data:`STAGES`), a code where the stage
    names its failures (the quad stage's ``touches_border``, ``not_quadrilateral``, ...: pipeline.quad;
    else None) and the detail (one line, the numbers). ``reason`` is ``"<code>: <detail>"`` (the
    detail alone without a code); ``str(f)`` is ``"<stage>: <reason>"``, the form windows.json and
    the results tables hold. Callers test ``code``, never the text."""

    stage: str
    code: str | None
    detail: str

    def __post_init__(self) -> None:
        if self.stage not in STAGES:
            raise ValueError(f"Failure.stage must be one of {STAGES}, got {self.stage!r}")

    @property
    def reason(self) -> str:
        return self.detail if self.code is None else f"{self.code}: {self.detail}"

    def __str__(self) -> str:
        return f"{self.stage}: {self.reason}"


DETECTION_KINDS = ("window", "door", "signboard")  # what a detection is (Detection.kind)

CUT_SIDES = ("top", "bottom", "left", "right")  # the photo's edges that can cut a window


@dataclass(frozen=True)
class Partial:
    """A window cut by the photo's border: only its visible part is in the photo.

    cut: the photo's edges its mask reaches (one or more of :data:`CUT_SIDES`, in that order): the
    window goes on beyond them, so its true corners and size there are unknown. whole_failure:
    why the window as a whole has no geometry (the quad stage's ``touches_border``): what the bench
    measures a window by, and what a partial window never feeds into its wall's pose, scale or
    statistics (pipeline.facade_model.place_partials places it afterwards on its wall's plane,
    completed to its row's or column's whole windows: visible_fraction is then the share of its
    area the photo shows).
    """

    cut: tuple[str, ...]
    whole_failure: Failure
    visible_fraction: float | None = None  # of the completed window's area in the photo, 0-1 (None: not completed)

    def __post_init__(self) -> None:
        if self.visible_fraction is not None and not 0.0 < self.visible_fraction <= 1.0:
            raise ValueError(f"Partial.visible_fraction must be in (0, 1], got {self.visible_fraction!r}")
        if not self.cut or any(c not in CUT_SIDES for c in self.cut) or len(set(self.cut)) != len(self.cut):
            raise ValueError(f"Partial.cut must be distinct sides of {CUT_SIDES}, at least one, got {self.cut!r}")
        if list(self.cut) != sorted(self.cut, key=CUT_SIDES.index):
            raise ValueError(f"Partial.cut must list its sides in the order of {CUT_SIDES}, got {self.cut!r}")


@dataclass(frozen=True)
class Detection:
    """One detected window void. mask: (H, W) bool; box: (4,) x0, y0, x1, y1 px; score in [0, 1].

    Sparse form (large photos, many windows): ``mask`` is an (h, w) crop whose pixel [0, 0] is
    image pixel ``origin`` (x0, y0); the default origin (0, 0) with the image's shape is the full
    mask. instance_id: the input instance map's id (``--masks``), None for a detector's output.
    corners: (4, 2) px, TL TR BR BL in image order, full-image coordinates: the void's corners as a
    detector with a corner head predicts them (pipeline.quad.corners_to_quad), else None.
    kind: what the detector's box verifier calls it, one of :data:`DETECTION_KINDS` ("window" for
    a detector without one): a door becomes an IfcDoor, a signboard is left out with its reason.
    """

    mask: np.ndarray
    box: np.ndarray
    score: float
    label: str = "window"
    origin: tuple[int, int] = (0, 0)
    instance_id: int | None = None
    corners: np.ndarray | None = None
    kind: str = "window"

    def __post_init__(self) -> None:
        if self.kind not in DETECTION_KINDS:
            raise ValueError(f"Detection.kind must be one of {DETECTION_KINDS}, got {self.kind!r}")


@dataclass(frozen=True)
class Uncertainty:
    """A window's error bars from its wall's joint fit (pipeline.walls.window_uncertainty):
    first-order covariance, reported as intervals at ``level`` (0.9: 90 %).

    level: the intervals' coverage, in (0, 1); sigma_px: the corner sigma (px) the covariance
    used; aspect_sd: the aspect ratio's (width / height, unitless) standard deviation; aspect_lo,
    aspect_hi: its interval (unitless); rot_deg: bound on the rotation error (deg); trans_rel:
    bound on |t error| / |t| (unitless); ill_conditioned: the aspect interval or the rotation bound
    too wide (pipeline.walls.settings.WALL_FIT; aspect_case then becomes ``ill_conditioned``);
    widened: None, or the factor the façade model widened every interval by (a flagged window,
    pipeline.facade_model.FLAG_WIDEN). Scalars, all; :meth:`to_json` is windows.json's form.
    """

    level: float
    sigma_px: float
    aspect_sd: float
    aspect_lo: float
    aspect_hi: float
    rot_deg: float
    trans_rel: float
    ill_conditioned: bool
    widened: float | None = None

    def to_json(self) -> dict:
        """windows.json's ``uncertainty``: every field in order, ``widened`` only when set."""
        out = {"level": self.level, "sigma_px": self.sigma_px, "aspect_sd": self.aspect_sd,
               "aspect_lo": self.aspect_lo, "aspect_hi": self.aspect_hi, "rot_deg": self.rot_deg,
               "trans_rel": self.trans_rel, "ill_conditioned": self.ill_conditioned}
        if self.widened is not None:
            out["widened"] = self.widened
        return out


@dataclass(frozen=True)
class WindowResult:
    """Reconstruction of one detected window (one entry of windows.json).

    Quads are (4, 2) px, TL TR BR BL, pixel centres at integers (see fenestra.conventions).
    R (3, 3), t (3,) map the window frame (x along the wall, y up, z outward; origin at the
    bottom-left corner; size aspect_ratio*height x height m) to the camera frame (OpenCV).
    Fields are None when the stage failed; ``failure`` (a :class:`Failure`) then names the stage
    and reason.
    group: the joint fit's wall group the window was fitted in (per-wall strategies, pipeline.walls),
    else None (the façade model's wall a window is on is pipeline.session.Window.wall); uncertainty: its 90 % intervals (:class:`Uncertainty`, pipeline.walls.window_uncertainty),
    else None.
    partial: None for a whole window; a :class:`Partial` for a window cut by the photo's border,
    whose fields then describe its *visible* part: quad_mask = quad_snapped the visible quad (the
    mask fit with the image edge as a side, not snapped), R its wall's axes, t, aspect_ratio and
    height_m the visible extent on its wall's plane (pipeline.facade_model.place_partials), or a
    ``failure`` (stage ``wall``) when it has no wall to be placed on.
    """

    index: int
    score: float
    quad_mask: np.ndarray | None
    quad_snapped: np.ndarray | None
    aspect_ratio: float | None
    aspect_case: AspectCase | None
    focal_estimate_px: float | None
    R: np.ndarray | None
    t: np.ndarray | None
    height_m: float  # the scale parameter used for the pose (default 1 m)
    quad_reprojected: np.ndarray | None
    failure: Failure | None
    timings_ms: dict[str, float] = field(default_factory=dict)
    instance_id: int | None = None  # the detection's id in the input instance map, if any
    group: int | None = None
    uncertainty: Uncertainty | None = None
    partial: Partial | None = None

    @property
    def status(self) -> Status:
        return Status.OK if self.failure is None else Status.FAILED
