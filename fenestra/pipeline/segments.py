"""Straight line segments of a gray image: OpenCV's line segment detector (LSD, von Gioi et al.
2012, ``cv2.createLineSegmentDetector``), the one segment detector of the pipeline.

:func:`detect_segments` finds them in a whole image or a crop of it; the ``lsd`` snapper
(fenestra/pipeline/snappers/lsd.py) uses it on a crop around each quad, the walls' façade lines
(fenestra/pipeline/walls/lines.py) on the whole photo. Output shape everywhere: (M, 2, 2) float64 px,
segment m from ``s[m, 0]`` (x, y) to ``s[m, 1]`` (x, y), full-image coordinates with pixel
centres at integers (LSD's convention, and ours: a step between rows 29 and 30 lies at y = 29.5).

:class:`SegmentCache` keeps one photo's segments, so that the steps that need them (the focal fit
without K, then the wall fit) find them once: the caller makes one per photo and passes it down
(LSD on a 6000x4000 photo takes ~3 s and ~0.5 GB). It also keeps what is derived from them
(:meth:`SegmentCache.derived`: the walls' façade-line work, pipeline.walls.lines.FacadeSegments), so
that the bench's methods of one view share it.
"""
from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import TypeVar

import cv2
import numpy as np

from fenestra.conventions import LIMITS


def check_gray(gray: np.ndarray) -> np.ndarray:
    """A gray image (H, W), uint8 or float, as an array; ValueError naming another shape or dtype."""
    g = np.asarray(gray)
    if g.ndim != 2 or not (g.dtype == np.uint8 or np.issubdtype(g.dtype, np.floating)):
        raise ValueError(f"gray must be an (H, W) uint8 or float image, got shape {g.shape} dtype {g.dtype}")
    return g


def to_uint8(gray: np.ndarray) -> np.ndarray:
    """A gray image (H, W), uint8 or float in [0, 255], as uint8 (rounded, clipped; uint8 is
    returned as it is). ValueError for another shape or dtype."""
    g = check_gray(gray)
    if g.dtype == np.uint8:
        return g
    if g.size and float(g.min()) >= 0:  # OpenCV rounds (half to even, as np.round) and saturates in one pass: no float copy
        return cv2.convertScaleAbs(g)
    r = np.round(g)
    return np.clip(r, 0, 255, out=r).astype(np.uint8)


def detect_segments(gray: np.ndarray, scale: float, box: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """LSD segments (M, 2, 2) float64 px (start, end; full-image coordinates, pixel centres at
    integers) of a gray image (H, W), uint8 or float in [0, 255] (rounded to uint8).

    scale: the image scale LSD works at (1: full resolution, no sub-sampling bias; 0.8: OpenCV's
    default, which smooths); box (x0, y0, x1, y1) px: only the crop [y0:y1, x0:x1] is searched
    (None: the whole image). (0, 2, 2) when LSD finds none.
    """
    g = check_gray(gray)
    x0, y0 = (0, 0) if box is None else (int(box[0]), int(box[1]))
    if box is not None:
        g = g[y0:int(box[3]), x0:int(box[2])]
    crop = np.ascontiguousarray(to_uint8(g))
    found = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD, float(scale)).detect(crop)[0]
    if found is None:
        return np.zeros((0, 2, 2))
    seg = found.reshape(-1, 2, 2).astype(np.float64)
    return seg if box is None else seg + [x0, y0]


def whole_image_segments(gray: np.ndarray, scale: float, max_pixels: int | None = None) -> np.ndarray:
    """:func:`detect_segments` of a whole image (H, W) at ``scale``; an image of more than
    ``max_pixels`` pixels (None: LIMITS.lsd_max_pixels) is first resized (INTER_AREA) to that many
    and its segments mapped back (``(p + 0.5) / f - 0.5``), so LSD's memory (its double-precision
    copy and gradients) and time stay bounded on any photo. Images up to ``max_pixels`` (every
    render, every bundled photo) are searched as they are."""
    g = check_gray(gray)
    H, W = g.shape
    max_pixels = LIMITS.lsd_max_pixels if max_pixels is None else int(max_pixels)
    if H * W <= max_pixels:
        return detect_segments(g, scale)
    f = float(np.sqrt(max_pixels / (H * W)))
    small = cv2.resize(to_uint8(g), (max(1, round(W * f)), max(1, round(H * f))), interpolation=cv2.INTER_AREA)
    fx, fy = small.shape[1] / W, small.shape[0] / H
    return (detect_segments(small, scale) + 0.5) / [fx, fy] - 0.5


def longest_segments(segments: np.ndarray, n: int) -> np.ndarray:
    """The ``n`` longest of segments (M, 2, 2) px, in their given order (all of them when M <= n;
    ties in length at the cut: the earlier ones). ValueError for n < 0."""
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    s = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    if len(s) <= n:
        return s
    length = np.linalg.norm(s[:, 1] - s[:, 0], axis=1)
    return s[np.sort(np.argsort(-length, kind="stable")[:n])]


T = TypeVar("T")


class SegmentCache:
    """The segments of one photo, found on the first request per LSD scale and kept.

    An explicit cache: make one per photo (``SegmentCache(gray)``, gray (H, W) uint8 or float in
    [0, 255]) and pass it to every step that needs that photo's segments. It holds the image, not
    a copy: do not change it while the cache is in use.
    """

    def __init__(self, gray: np.ndarray) -> None:
        self._gray = check_gray(gray)
        self._found: dict[float, np.ndarray] = {}
        self._derived: dict[Hashable, object] = {}

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the photo."""
        return self._gray.shape

    def segments(self, scale: float, min_length_px: float = 0.0) -> np.ndarray:
        """The photo's segments (M, 2, 2) px (:func:`detect_segments` at ``scale``) at least
        ``min_length_px`` long; a new array each call (the kept one is not exposed)."""
        key = float(scale)
        if key not in self._found:
            self._found[key] = whole_image_segments(self._gray, key)
        s = self._found[key]
        return s[np.linalg.norm(s[:, 1] - s[:, 0], axis=1) >= min_length_px]

    def halved(self) -> "SegmentCache":
        """The cache of this photo at half its size in each dimension (area averaging, OpenCV
        INTER_AREA; (H + 1) // 2 x (W + 1) // 2 px), made on the first request and kept: what a
        half-size copy of the photo would give."""
        H, W = self.shape
        return self.derived(("halved",), lambda: SegmentCache(cv2.resize(
            to_uint8(self._gray), ((W + 1) // 2, (H + 1) // 2), interpolation=cv2.INTER_AREA)))

    def derived(self, key: Hashable, make: Callable[[], T]) -> T:
        """What ``make()`` derives from this photo's segments, made on the first request for
        ``key`` and kept with them (pipeline.walls.lines.photo_segments keeps the photo's
        FacadeSegments here, so the walls' line work is done once per photo, not per method)."""
        if key not in self._derived:
            self._derived[key] = make()
        return self._derived[key]  # type: ignore[return-value]
