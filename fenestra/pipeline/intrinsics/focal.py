"""One focal source's answer (:class:`FocalEstimate`), the pinhole relations between a focal length
and a field of view, and the two sources that need no pixels: the user's K and the stated prior.

The prior is a typical phone camera: PRIOR_FOV_DEG horizontal field of view along the photo's long
side, with the wide interval PRIOR_FOV_RANGE_DEG. It is always available, so the chain never fails.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.errors import PipelineError

PRIOR_FOV_DEG = 65.0  # a typical phone's horizontal field of view (along the long side)
PRIOR_FOV_RANGE_DEG = (40.0, 90.0)  # the prior's wide interval (tele-ish to ultra-wide-ish)


def centred_K(focal_px: float, image_size: tuple[int, int]) -> np.ndarray:
    """Square-pixel K with the principal point at the image centre.

    Args:
        focal_px: focal length (px), positive and finite; PipelineError otherwise.
        image_size: (W, H) px.
    Returns:
        K (3, 3) float64 px, principal point ((W - 1) / 2, (H - 1) / 2).
    """
    W, H = image_size
    if not (np.isfinite(focal_px) and focal_px > 0):
        raise PipelineError(f"focal length must be positive, got {focal_px}")
    return np.array([[focal_px, 0.0, (W - 1) / 2.0], [0.0, focal_px, (H - 1) / 2.0], [0.0, 0.0, 1.0]])


def focal_from_fov(fov_deg: float, image_size: tuple[int, int]) -> float:
    """Focal length (px) giving a field of view ``fov_deg`` (deg) along the long side of a (W, H) px image."""
    return max(image_size) / 2.0 / np.tan(np.radians(fov_deg) / 2.0)


def fov_from_focal(focal_px: float, image_size: tuple[int, int]) -> float:
    """Field of view (deg) along the long side of a (W, H) px image for a focal length (px)."""
    return float(np.degrees(2.0 * np.arctan(max(image_size) / 2.0 / focal_px)))


@dataclass(frozen=True)
class FocalEstimate:
    """One source's focal length.

    source: "K" | "exif" | "vanishing points" | "prior"; focal_px: the value (px); interval_px:
    (lo, hi) px (90 % for vanishing points, the stated range otherwise); detail: how it was found.
    """

    source: str
    focal_px: float
    interval_px: tuple[float, float]
    detail: str

    def overlaps(self, other: "FocalEstimate") -> bool:
        """Whether the two intervals share a value."""
        return self.interval_px[0] <= other.interval_px[1] and other.interval_px[0] <= self.interval_px[1]

    def to_json(self) -> dict:
        """{"source", "focal_px", "interval_px": [lo, hi], "detail"}: windows.json's form."""
        return {"source": self.source, "focal_px": self.focal_px, "interval_px": list(self.interval_px),
                "detail": self.detail}


def user_focal(K: np.ndarray, how: str) -> FocalEstimate:
    """The user's K (3, 3) px as a chain entry; its interval is the value itself (taken as exact).
    how: where it came from (e.g. "--K K.json")."""
    f = float(K[0, 0])
    return FocalEstimate("K", f, (f, f), how)


def prior_focal(image_size: tuple[int, int]) -> FocalEstimate:
    """The stated prior for a (W, H) px image: PRIOR_FOV_DEG along the long side, its interval (px)
    from PRIOR_FOV_RANGE_DEG."""
    lo, hi = (focal_from_fov(a, image_size) for a in PRIOR_FOV_RANGE_DEG[::-1])
    return FocalEstimate("prior", focal_from_fov(PRIOR_FOV_DEG, image_size), (lo, hi),
                         f"assumed: a typical phone camera, {PRIOR_FOV_DEG:g} deg field of view along the long side "
                         f"({PRIOR_FOV_RANGE_DEG[0]:g}-{PRIOR_FOV_RANGE_DEG[1]:g} deg)")
