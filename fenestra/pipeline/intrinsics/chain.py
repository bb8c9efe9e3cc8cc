"""The focal chain: the ranked sources' answers, the one chosen (:class:`ResolvedK`), and warnings
where two sources disagree."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fenestra.pipeline.intrinsics.exif import exif_focal
from fenestra.pipeline.intrinsics.focal import FocalEstimate, centred_K, fov_from_focal, prior_focal
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
    sources that gave none; warnings: where two sources disagree (:func:`disagree`), in the user's words.
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


SOURCE_WORDS = {"K": "your K", "exif": "the photo's EXIF", "vanishing points": "the façade's vanishing points",
                "prior": "a typical phone camera"}  # each source in a sentence
STATED = ("K", "exif")  # sources that state the camera's focal length (the prior's range is no test of them)


def disagree(a: FocalEstimate, b: FocalEstimate) -> bool:
    """Whether two sources disagree: neither's interval holds the other's focal length. A stated
    source (STATED: the user's K, the EXIF) never disagrees with the prior, which is only what a
    typical camera has."""
    if "prior" in (a.source, b.source) and {a.source, b.source} & set(STATED):
        return False
    return not (a.interval_px[0] <= b.focal_px <= a.interval_px[1]) and not (b.interval_px[0] <= a.focal_px <= b.interval_px[1])


def disagreement_words(a: FocalEstimate, b: FocalEstimate, chosen: FocalEstimate, image_size: tuple[int, int]) -> str:
    """A warning, in the user's words, that sources ``a`` and ``b`` disagree (values and intervals
    in px, the field of view in degrees along the long side of the (W, H) px photo), naming the
    one used and what the user can do."""
    def value(e: FocalEstimate) -> str:
        fov = "-".join(f"{fov_from_focal(f, image_size):.0f}" for f in e.interval_px[::-1])
        return f"{e.focal_px:.0f} px ({e.interval_px[0]:.0f}-{e.interval_px[1]:.0f} px, a {fov} deg view)"

    used = SOURCE_WORDS.get(chosen.source, chosen.source)
    if "prior" in (a.source, b.source):
        measured, prior = (b, a) if a.source == "prior" else (a, b)
        p_lo, p_hi = prior.interval_px
        return (f"the focal length sources disagree: {SOURCE_WORDS[measured.source]} give {value(measured)}, outside "
                f"the {p_lo:.0f}-{p_hi:.0f} px of {SOURCE_WORDS['prior']}; the photo may be cropped or zoomed, or "
                f"the vanishing points misled; using {used}; give --fx if you know the focal length")
    return (f"the focal length sources disagree: {SOURCE_WORDS.get(a.source, a.source)} gives {value(a)}, "
            f"{SOURCE_WORDS.get(b.source, b.source)} {value(b)}; using {used}")


def disagreements(estimates: list[FocalEstimate], image_size: tuple[int, int]) -> list[str]:
    """A warning (:func:`disagreement_words`) for each pair of estimates (in rank order, the first
    the one used) that :func:`disagree`; image_size: (W, H) px."""
    return [disagreement_words(a, b, estimates[0], image_size)
            for i, a in enumerate(estimates) for b in estimates[i + 1:] if disagree(a, b)]


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
    return ResolvedK(K, chosen, tuple(estimates), unavailable, tuple(disagreements(estimates, image_size)))


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
    return resolve_K_with(exif, quads, image_size, wall, segment_cache)


def resolve_K_with(exif: FocalEstimate | Unavailable | None, quads: np.ndarray, image_size: tuple[int, int],
                   wall: WallParams | None = None, segment_cache: SegmentCache | None = None) -> ResolvedK:
    """:func:`resolve_K` with the photo's EXIF focal length already read
    (exif.exif_focal_of_tags; None: the photo has none)."""
    vp = vanishing_focal(quads, image_size, wall, segment_cache)
    return choose_focal([exif if exif is not None else Unavailable("no EXIF focal length"), vp], ["exif", "vanishing points"],
                        image_size)
