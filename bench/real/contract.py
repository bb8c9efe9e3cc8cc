"""The real-view contract: what every real-dataset adapter yields, one RealView per photo.

It mirrors a rendered view (DESIGN.md, "Data contracts") with every piece of ground truth
optional: a field the dataset does not label is None ("missing"), never guessed. Coordinates
follow fenestra.conventions: pixel centres at integers, the image spans [-0.5, W - 0.5];
quads are TL, TR, BR, BL; boxes are (x0, y0, x1, y1) on the pixel-edge outline (x1 - x0 = width
in px, as pipeline.detectors' Detection.box). Labels are in the frame of ``image``: an adapter
whose labels are in the undistorted frame undistorts the photo and records the coefficients it
removed in ``distortion_removed``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.conventions import check_K, check_quad
from fenestra.data import mask_box


@dataclass(frozen=True, eq=False)
class RealWindow:
    """One labelled window of a photo.

    id: unique within the view. quad: (4, 2) px TL TR BR BL or None; box: (4,) px x0 y0 x1 y1 or
    None; mask: (H, W) bool or None (at least one of the three is given). aspect: the true
    width / height (unitless) or None; size_m: true (width, height) m or None. partial: the
    window is cut by the image border or otherwise not wholly visible (not evaluable).
    """

    id: str
    quad: np.ndarray | None = None
    box: np.ndarray | None = None
    mask: np.ndarray | None = None
    aspect: float | None = None
    size_m: tuple[float, float] | None = None
    partial: bool = False

    def __post_init__(self) -> None:
        if self.quad is None and self.box is None and self.mask is None:
            raise ValueError(f"window {self.id!r} has neither quad, box nor mask")
        if self.quad is not None:
            check_quad(self.quad, f"window {self.id!r} quad")
        if self.box is not None:
            b = np.asarray(self.box, dtype=np.float64)
            if b.shape != (4,) or not np.all(np.isfinite(b)) or b[2] <= b[0] or b[3] <= b[1]:
                raise ValueError(f"window {self.id!r} box must be finite x0 < x1, y0 < y1, got {self.box!r}")
        if self.mask is not None and (np.asarray(self.mask).ndim != 2 or not np.asarray(self.mask).any()):
            raise ValueError(f"window {self.id!r} mask must be a non-empty (H, W) bool array")
        if self.aspect is not None and not (np.isfinite(self.aspect) and self.aspect > 0):
            raise ValueError(f"window {self.id!r} aspect must be positive, got {self.aspect!r}")

    def bbox(self) -> np.ndarray:
        """(4,) px x0 y0 x1 y1: the labelled box, else the mask's pixel-edge box, else the quad's."""
        if self.box is not None:
            return np.asarray(self.box, dtype=np.float64)
        if self.mask is not None:
            return mask_box(self.mask)
        q = np.asarray(self.quad, dtype=np.float64)
        return np.array([q[:, 0].min(), q[:, 1].min(), q[:, 0].max(), q[:, 1].max()])


@dataclass(frozen=True, eq=False)
class RealView:
    """One labelled photo. image: (H, W, 3) uint8 RGB in the labels' frame; K: (3, 3) px or None
    (unknown intrinsics); distortion_removed: OpenCV coefficients already undone, or None;
    coplanar: every window lies on one plane (enables the relative-size metric); ignore: ignore
    regions (a box or mask each; e.g. COCO ``iscrowd``): neither window nor background, detection
    AP counts detections there neither way."""

    dataset: str
    name: str
    image: np.ndarray
    windows: tuple[RealWindow, ...]
    K: np.ndarray | None = None
    distortion_removed: tuple[float, ...] | None = None
    coplanar: bool = False
    ignore: tuple[RealWindow, ...] = ()

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
            if w.mask is not None and np.asarray(w.mask).shape != img.shape[:2]:
                raise ValueError(f"view {self.name!r} window {w.id!r}: mask shape "
                                 f"{np.asarray(w.mask).shape} != image {img.shape[:2]}")

    @property
    def has_masks(self) -> bool:
        """Every window has a mask (oracle detectors and mask AP need them)."""
        return bool(self.windows) and all(w.mask is not None for w in self.windows)

    def instance_map(self) -> np.ndarray:
        """(H, W) int32: window i's mask labelled i + 1 (0 = none). ValueError without masks."""
        if not self.has_masks:
            raise ValueError(f"view {self.name!r}: not every window has a mask")
        inst = np.zeros(self.image.shape[:2], np.int32)
        for i, w in enumerate(self.windows):
            inst[np.asarray(w.mask, dtype=bool)] = i + 1
        return inst
