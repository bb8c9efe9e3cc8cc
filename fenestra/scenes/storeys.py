"""A house's storey height (floor to floor, m) from its IFC storeys: what a user who knows the
building would type as ``fenestra reconstruct --known-storey``, and the bench's truth for it.

    storey_height_m("fenestra/scenes/ifc/AC20-FZK-Haus.ifc")   # 2.7
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from fenestra.errors import DatasetError


def storey_height_from_elevations(elevations_m: list[float]) -> float | None:
    """Median difference of consecutive storey elevations (m) at or above the ground floor
    (elevation >= 0: a basement or a foundation level is not a façade storey); None with fewer
    than two such levels."""
    levels = sorted({round(float(e), 6) for e in elevations_m if float(e) >= -1e-6})
    if len(levels) < 2:
        return None
    return float(np.median(np.diff(levels)))


@functools.lru_cache(maxsize=32)
def storey_height_m(ifc_path: str | Path) -> float | None:
    """The storey height (m) of an IFC house (IfcBuildingStorey elevations in the model's length
    unit, converted to m), or None when it has fewer than two storeys at or above ground.
    DatasetError naming the file if it cannot be read."""
    import ifcopenshell  # noqa: PLC0415
    import ifcopenshell.util.unit  # noqa: PLC0415

    try:
        model = ifcopenshell.open(str(ifc_path))
    except (OSError, RuntimeError) as e:
        raise DatasetError(f"{ifc_path}: not a readable IFC file ({e})") from e
    scale = float(ifcopenshell.util.unit.calculate_unit_scale(model))
    return storey_height_from_elevations([float(s.Elevation or 0.0) * scale
                                          for s in model.by_type("IfcBuildingStorey")])
