"""The one labelled-view type of the bench: a render or a photo, each with the truth it has.

Every source of views yields :class:`LabelledView` (one image and its labelled windows): the
rendered-view adapter (bench.render_adapter.read_rendered_view: a view folder of the data
contract, exact truth) and the real-format adapters (bench.real.adapters: coco, yolo, labelmap,
curtainwall, what their labels carry). bench.evaluate.evaluate_view measures whatever errors
this truth allows; a piece of truth a source lacks is None (or NaN for a view condition), never
guessed and never 0.

Conventions (fenestra.conventions): pixel centres at integers, the image spans [-0.5, W - 0.5];
quads (4, 2) px TL TR BR BL; boxes (4,) px x0 y0 x1 y1 on the pixel-edge outline (x1 - x0 = width
in px); world corners (4, 3) m TL TR BR BL; poses world-to-camera (R (3, 3), t (3,)). Labels are
in the frame of ``image``: an adapter whose labels are undistorted undistorts the photo and
records the coefficients it removed in ``distortion_removed``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fenestra.checks import check_K, check_quad
from fenestra.masks import SparseMask

NAN = float("nan")
PHOTO = "photo"  # the ``renderer`` of a photo (a results table's ``renderer`` column)


@dataclass(frozen=True, eq=False)
class LabelledWindow:
    """One labelled window (or, in LabelledView.ignore, one ignore region) of a view.

    id: unique within the view. quad: (4, 2) px TL TR BR BL or None; box: (4,) px x0 y0 x1 y1 or
    None; mask: its pixels (a SparseMask of the image) or None; at least one of the three is
    given, and a mask with no pixel needs a quad (a render's hidden window). aspect: the true
    width / height (unitless) or None; size_m: true (width, height) m or None. partial: cut by the
    image border or otherwise not wholly visible (not evaluable).

    Renders only (None / NaN for photos): instance_id, its value in LabelledView.instances;
    corners_world (4, 3) m TL TR BR BL; incidence_deg, distance_m, visible_fraction (view.json);
    corner_visible (4 bools); kind, an ignore region's (view.json ``ignore[*].kind``:
    "curtain_wall", or "glazed_door": an IfcDoor), None for a window.
    """

    id: str
    quad: np.ndarray | None = None
    box: np.ndarray | None = None
    mask: SparseMask | None = None
    aspect: float | None = None
    size_m: tuple[float, float] | None = None
    partial: bool = False
    instance_id: int = -1
    corners_world: np.ndarray | None = None
    incidence_deg: float = NAN
    distance_m: float = NAN
    visible_fraction: float = NAN
    corner_visible: tuple[bool, ...] = (True, True, True, True)
    kind: str | None = None

    def __post_init__(self) -> None:
        if self.quad is None and self.box is None and self.mask is None:
            raise ValueError(f"window {self.id!r} has neither quad, box nor mask")
        if self.quad is not None:
            check_quad(self.quad, f"window {self.id!r} quad")
        if self.box is not None:
            b = np.asarray(self.box, dtype=np.float64)
            if b.shape != (4,) or not np.all(np.isfinite(b)) or b[2] <= b[0] or b[3] <= b[1]:
                raise ValueError(f"window {self.id!r} box must be finite x0 < x1, y0 < y1, got {self.box!r}")
        if self.mask is not None:
            if not isinstance(self.mask, SparseMask):
                raise ValueError(f"window {self.id!r} mask must be a fenestra.data.SparseMask "
                                 f"(SparseMask.from_dense of an (H, W) bool array), got {type(self.mask).__name__}")
            if not self.mask.area and self.quad is None:
                raise ValueError(f"window {self.id!r} mask is empty and the window has no quad")
        if self.aspect is not None and not (math.isfinite(self.aspect) and self.aspect > 0):
            raise ValueError(f"window {self.id!r} aspect must be positive, got {self.aspect!r}")
        if self.corners_world is not None and np.shape(self.corners_world) != (4, 3):
            raise ValueError(f"window {self.id!r} corners_world must be (4, 3) m, got {np.shape(self.corners_world)}")

    def bbox(self) -> np.ndarray:
        """(4,) px x0 y0 x1 y1: the labelled box, else the mask's pixel-edge box, else the quad's."""
        if self.box is not None:
            return np.asarray(self.box, dtype=np.float64)
        if self.mask is not None and self.mask.area:
            return self.mask.box()
        q = np.asarray(self.quad, dtype=np.float64)
        return np.array([q[:, 0].min(), q[:, 1].min(), q[:, 0].max(), q[:, 1].max()])


@dataclass(frozen=True, eq=False)
class LabelledView:
    """One labelled image. dataset: the house (renders) or dataset name; name: the view's name
    (unique within the dataset); image: (H, W, 3) uint8 RGB in the labels' frame; K: (3, 3) px or
    None (unknown intrinsics); distortion_removed: OpenCV coefficients already undone, or None;
    coplanar: every window lies on one plane (enables the relative-size metric); ignore: ignore
    regions (a box or mask each; COCO ``iscrowd``, a render's curtain-wall glazing): neither
    window nor background, detection AP counts detections there neither way; renderer: the
    renderer of a render, ``"photo"`` for a photo.

    Renders only (None for photos): pose, the camera's world-to-camera (R (3, 3), t (3,)): exact
    pose truth; instances, the (H, W) int32 instance map the windows' ``instance_id`` refer to
    (the oracle detectors read it; a photo's is built from its masks, :meth:`instance_map`).
    """

    dataset: str
    name: str
    image: np.ndarray
    windows: tuple[LabelledWindow, ...]
    K: np.ndarray | None = None
    distortion_removed: tuple[float, ...] | None = None
    coplanar: bool = False
    ignore: tuple[LabelledWindow, ...] = ()
    renderer: str = PHOTO
    pose: tuple[np.ndarray, np.ndarray] | None = None
    instances: np.ndarray | None = None

    def __post_init__(self) -> None:
        img = np.asarray(self.image)
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise ValueError(f"view {self.name!r}: image must be (H, W, 3) uint8, got {img.shape} {img.dtype}")
        if self.K is not None:
            check_K(self.K)
        ids = [w.id for w in self.windows]
        if len(set(ids)) != len(ids):
            raise ValueError(f"view {self.name!r}: duplicate window ids {ids}")
        for w in (*self.windows, *self.ignore):
            if w.mask is not None and tuple(w.mask.shape) != img.shape[:2]:
                raise ValueError(f"view {self.name!r} window {w.id!r}: mask shape "
                                 f"{tuple(w.mask.shape)} != image {img.shape[:2]}")
        if self.instances is not None and np.shape(self.instances) != img.shape[:2]:
            raise ValueError(f"view {self.name!r}: instances shape {np.shape(self.instances)} != image {img.shape[:2]}")

    @property
    def key(self) -> str:
        """The view's COCO image key, "dataset/name"."""
        return f"{self.dataset}/{self.name}"

    @property
    def size(self) -> tuple[int, int]:
        """(H, W) px."""
        return self.image.shape[0], self.image.shape[1]

    @property
    def has_masks(self) -> bool:
        """Every window has a mask (mask IoU matching and mask AP need them)."""
        return bool(self.windows) and all(w.mask is not None for w in self.windows)

    def instance_map(self) -> np.ndarray | None:
        """(H, W) int32 instance map for the oracle detectors: a render's own; for a photo whose
        every window has a mask, window i's mask labelled i + 1 (0 = none); else None."""
        if self.instances is not None:
            return self.instances
        if not self.has_masks:
            return None
        inst = np.zeros(self.size, np.int32)
        for i, w in enumerate(self.windows):
            m = w.mask
            inst[m.r0:m.r1, m.c0:m.c1][m.crop] = i + 1
        return inst
