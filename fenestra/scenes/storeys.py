"""A house's storeys from its IFC: the storey height (floor to floor, m), what a user who knows the
building would type as ``fenestra reconstruct --known-storey``, and the storey a window stands on:
the bench's truth for both.

    storey_height_m("fenestra/scenes/ifc/AC20-FZK-Haus.ifc")                  # 2.7
    storey_index(0.8, storey_elevations_m("fenestra/scenes/ifc/AC20-FZK-Haus.ifc"))   # 0: the ground floor
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from fenestra.errors import DatasetError


def facade_levels(elevations_m: list[float]) -> list[float]:
    """The distinct storey elevations (m, ascending; to the micrometre) at or above the ground
    floor (elevation >= 0: a basement or a foundation level is not a façade storey)."""
    return sorted({round(float(e), 6) for e in elevations_m if float(e) >= -1e-6})


def storey_height_from_elevations(elevations_m: list[float]) -> float | None:
    """Median difference of consecutive storey elevations (m) at or above the ground floor
    (:func:`facade_levels`); None with fewer than two such levels."""
    levels = facade_levels(elevations_m)
    if len(levels) < 2:
        return None
    return float(np.median(np.diff(levels)))


def storey_index(z_m: float, elevations_m: list[float]) -> int | None:
    """The storey (0 = the ground floor) a point at height ``z_m`` (m, the IFC world) stands on:
    the highest of :func:`facade_levels` at or below it (1 um tolerance); None below the ground
    floor or without levels."""
    levels = facade_levels(elevations_m)
    i = int(np.searchsorted(levels, float(z_m) + 1e-6, side="right")) - 1
    return i if i >= 0 else None


def storey_height_m(ifc_path: str | Path) -> float | None:
    """The storey height (m) of an IFC house (:func:`storey_elevations_m`), or None when it has
    fewer than two storeys at or above ground. DatasetError naming the file if it cannot be read."""
    return storey_height_from_elevations(storey_elevations_m(ifc_path))


@functools.lru_cache(maxsize=32)
def storey_elevations_m(ifc_path: str | Path) -> tuple[float, ...]:
    """The IfcBuildingStorey elevations of an IFC house (the model's length unit converted to m),
    in file order. DatasetError naming the file if it cannot be read."""
    import ifcopenshell  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)
    import ifcopenshell.util.unit  # noqa: PLC0415 (IfcOpenShell: imported when first used, not at the package's import)

    try:
        model = ifcopenshell.open(str(ifc_path))
    except (OSError, RuntimeError) as e:
        raise DatasetError(f"{ifc_path}: not a readable IFC file ({e})") from e
    scale = float(ifcopenshell.util.unit.calculate_unit_scale(model))
    return tuple(float(s.Elevation or 0.0) * scale for s in model.by_type("IfcBuildingStorey"))
