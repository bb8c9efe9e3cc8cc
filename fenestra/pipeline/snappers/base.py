"""Shared pieces of the corner snappers: the Snapper record, input checks, line helpers."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from fenestra.checks import check_quad


@dataclass(frozen=True)
class Snapper:
    """A registered strategy and what it declares about itself.

    name: its registry key; snap(gray, quad, params) -> (quad (4, 2), info dict with ``moved``:
    4 bools); params: its frozen parameter dataclass (``params()``: the defaults); description:
    one line for CLI help and the docs; test_median_px: its bound on the median corner error (px)
    on tests/pipeline/test_pipeline_snappers.py's synthetic views (antialiased quads, noise sigma 2, from the
    mask-fit quad), which the generic snapper test holds every registered strategy to.
    """

    name: str
    snap: Callable[[np.ndarray, np.ndarray, Any], tuple[np.ndarray, dict]]
    params: type
    description: str
    test_median_px: float

    def __post_init__(self) -> None:
        if not self.description.strip():
            raise ValueError(f"snapper {self.name!r} needs a description (CLI help, docs)")
        if not self.test_median_px > 0:
            raise ValueError(f"snapper {self.name!r}: test_median_px must be > 0, got {self.test_median_px!r}")


def check_inputs(gray: np.ndarray, quad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate and return (gray as float32 (H, W), quad as float64 (4, 2)); ValueError otherwise."""
    g = np.asarray(gray)
    if g.ndim != 2:
        raise ValueError(f"gray image must be 2-D (H, W), got shape {g.shape}")
    return g.astype(np.float32, copy=False), check_quad(quad)


def line_through(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Line (n_x, n_y, c), |n| = 1, n . p = c, through points a, b (2,)."""
    d = b - a
    n = np.array([-d[1], d[0]]) / np.linalg.norm(d)
    return np.array([n[0], n[1], n @ a])


def intersect(l1: np.ndarray, l2: np.ndarray) -> np.ndarray:
    """Intersection (2,) of lines (n_x, n_y, c); inf if parallel."""
    A = np.array([l1[:2], l2[:2]])
    det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    if abs(det) < 1e-12:
        return np.array([np.inf, np.inf])
    return np.linalg.solve(A, np.array([l1[2], l2[2]]))


def quad_from_lines(lines: np.ndarray) -> np.ndarray:
    """Corners (4, 2) TL TR BR BL from side lines (4, 3) top, right, bottom, left."""
    return np.array([intersect(lines[(k - 1) % 4], lines[k]) for k in range(4)])


def side_lines(quad: np.ndarray) -> np.ndarray:
    """Side lines (4, 3) top, right, bottom, left of a TL TR BR BL quad (side k: corner k -> k+1)."""
    return np.array([line_through(quad[k], quad[(k + 1) % 4]) for k in range(4)])


def keep_if_far(old: np.ndarray, new: np.ndarray, max_move_px: float) -> tuple[np.ndarray, list[bool]]:
    """Corners of ``new`` that moved more than ``max_move_px`` (or are not finite) revert to ``old``."""
    moved = np.linalg.norm(new - old, axis=1)
    ok = np.isfinite(moved) & (moved <= max_move_px)
    return np.where(ok[:, None], new, old), ok.tolist()
