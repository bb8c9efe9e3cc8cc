"""The focal chain: the ranked sources' answers, the one chosen (:class:`ResolvedK`), and warnings
where two sources disagree."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fenestra.pipeline.intrinsics.exif import exif_focal
from fenestra.pipeline.intrinsics.focal import FocalEstimate, centred_K, prior_focal
from fenestra.pipeline.intrinsics.vanishing import vanishing_focal
from fenestra.pipeline.types import Unavailable

if TYPE_CHECKING:  # annotations only; pipeline.walls is imported where a fit runs
    from fenestra.pipeline.segments import SegmentCache
    from fenestra.pipeline.walls import WallParams


@dataclass(frozen=True)
class ResolvedK:
    """The chain's answer.

    K: (3, 3) px from the first usable focal source; chosen: that source's :class:`FocalEstimate`;
    estimates: every source that gave a value, in rank order; unavailable: {source: why} for the
    sources that gave none; warnings: where two sources' intervals do not overlap.
    """

    K: np.ndarray
    chosen: FocalEstimate
    estimates: tuple[FocalEstimate, ...]
    unavailable: dict
    warnings: tuple[str, ...]

    @property
    def source(self) -> str:
        """The chosen source's name."""
        return self.chosen.source

    @property
    def detail(self) -> str:
        """How the chosen source found its value."""
        return self.chosen.detail

    def to_json(self) -> dict:
        """windows.json's ``K_source``: source, detail, focal_px, interval_px, candidates, unavailable."""
        return {**self.chosen.to_json(), "candidates": [e.to_json() for e in self.estimates],
                "unavailable": dict(self.unavailable)}


def disagreements(estimates: list[FocalEstimate]) -> list[str]:
    """A warning for each pair of measured sources (not the prior) whose intervals do not overlap."""
    measured = [e for e in estimates if e.source != "prior"]
    return [f"focal sources disagree: {a.source} {a.focal_px:.0f} px [{a.interval_px[0]:.0f}, {a.interval_px[1]:.0f}] "
            f"vs {b.source} {b.focal_px:.0f} px [{b.interval_px[0]:.0f}, {b.interval_px[1]:.0f}]; using {measured[0].source}"
            for i, a in enumerate(measured) for b in measured[i + 1:] if not a.overlaps(b)]


def choose_focal(ranked: list[FocalEstimate | Unavailable | None], names: list[str], image_size: tuple[int, int],
                 principal_point: tuple[float, float] | None = None) -> ResolvedK:
    """The chain's answer from each source's.

    Args:
        ranked: each source's estimate, or why it has none (Unavailable, or None for "not
            given"), in rank order; the prior closes the chain.
        names: the sources' names, one per entry of ``ranked``.
        image_size: (W, H) px.
        principal_point: (cx, cy) px kept from the user's K; None: the image centre.
    Returns:
        The first estimate's K, every estimate, the unavailable sources and the disagreements.
    """
    estimates = [e for e in ranked if isinstance(e, FocalEstimate)] + [prior_focal(image_size)]
    unavailable = {n: e.reason for n, e in zip(names, ranked) if isinstance(e, Unavailable)}
    chosen = estimates[0]
    K = centred_K(chosen.focal_px, image_size)
    if principal_point is not None:
        K[0, 2], K[1, 2] = principal_point
    return ResolvedK(K, chosen, tuple(estimates), unavailable, tuple(disagreements(estimates)))


def resolve_K(photo: str | Path | None, quads: np.ndarray, image_size: tuple[int, int],
              wall: WallParams | None = None, segment_cache: SegmentCache | None = None) -> ResolvedK:
    """Intrinsics for a photo without --K: EXIF, then the façade's vanishing points, then the prior
    (never fails). Both measured sources are computed so that a disagreement can be reported.

    Args:
        photo: the photo file (its EXIF), or None for an image without a file (a render).
        quads: (N, 4, 2) px snapped window quads of the photo.
        image_size: (W, H) px.
        wall: the per-wall strategy's parameters (default ``WallParams()``; with ``lines`` the
            photo's façade segments join the focal fit, which needs segment_cache).
        segment_cache: the photo's pipeline.segments.SegmentCache.
    Returns:
        The chain's :class:`ResolvedK`.
    """
    exif = None if photo is None else exif_focal(photo, image_size)
    vp = vanishing_focal(quads, image_size, wall, segment_cache)
    return choose_focal([exif if exif is not None else Unavailable("no EXIF focal length"), vp], ["exif", "vanishing points"],
                        image_size)
