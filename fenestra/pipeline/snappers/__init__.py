"""Corner snapping strategies: registry ``SNAPPERS`` (name -> Snapper).

Every strategy has the same interface::

    quad, info = SNAPPERS[name].snap(gray, quad, params)

gray: (H, W) uint8 or float32 image; quad: (4, 2) px TL TR BR BL (pixel centres at integers);
params: the strategy's frozen dataclass (``SNAPPERS[name].params()`` gives the defaults).
Returns the snapped quad (4, 2) float64 and a dict of diagnostics (e.g. which corners moved).
Use :func:`snap` to look a strategy up by name with default parameters.

Each entry (:class:`~pipeline.snappers.base.Snapper`) also carries its one-line ``description``
(CLI help) and ``test_median_px`` (its bound in the generic snapper test): a new strategy is one
module and one line here, nothing else (docs/EXTENDING.md). ``SNAPPERS`` is a
:class:`fenestra.registry.Registry`: a snapper of another installed package registers itself through
the ``fenestra.plugins`` entry points (``SNAPPERS.register(MY_SNAPPER)``).
"""
from __future__ import annotations

import numpy as np

from fenestra.registry import Registry
from fenestra.pipeline.snappers.base import Snapper
from fenestra.pipeline.snappers.harris import HARRIS
from fenestra.pipeline.snappers.hough import HOUGH
from fenestra.pipeline.snappers.linefit import LINEFIT
from fenestra.pipeline.snappers.lsd import LSD
from fenestra.pipeline.snappers.none import NONE
from fenestra.pipeline.snappers.refine import REFINE
from fenestra.pipeline.snappers.subpix import SUBPIX

SNAPPERS: Registry[Snapper] = Registry("snapper", [
    NONE,
    HARRIS,
    HOUGH,
    LINEFIT,
    SUBPIX,
    LSD,
    REFINE,
])


def snap(name: str, gray: np.ndarray, quad: np.ndarray, params=None) -> tuple[np.ndarray, dict]:
    """Snap ``quad`` with strategy ``name`` (default parameters unless ``params`` is given)."""
    s = SNAPPERS[name]  # fenestra.registry.UnknownName (a ValueError) naming the choices
    return s.snap(gray, quad, s.params() if params is None else params)


__all__ = ["SNAPPERS", "Snapper", "snap"]
