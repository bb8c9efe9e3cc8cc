"""``none``: no snapping; the mask quad is the answer (the baseline every strategy is compared to)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.pipeline.snappers.base import Snapper, check_inputs


@dataclass(frozen=True)
class NoneParams:
    """No parameters."""


def snap_none(gray: np.ndarray, quad: np.ndarray, params: NoneParams = NoneParams()) -> tuple[np.ndarray, dict]:
    """Return the quad unchanged (a copy)."""
    _, q = check_inputs(gray, quad)
    return q.copy(), {"moved": [False] * 4}


NONE = Snapper("none", snap_none, NoneParams, test_median_px=0.3,
                description="no snapping, the mask-fit quad as it is (the baseline)")
