"""Floors of the exported building: model.ifc's IfcBuildingStoreys, from one wall's rows of windows.

    floors = floor_levels(placed, walls, doors)    # export world (geometry.upright), before grounding
    floors.elevations_m     # each floor's level, m, bottom-up; floors.names: "Ground floor", "Floor 1", ...
    floors.floor_of[k]      # the floor window k is contained in; floors.door_floor_of[d]: door d's
    placed, doors, floors = grounded_floors(placed, doors, floors)   # the ground floor at z = 0

A window row is not a floor: a door, a signboard taken for a window, a mezzanine row or a
neighbouring building's windows make rows at any height. The floors come from the **main wall**
(the wall with the most whole windows: geometry.storey_rows groups its sills into rows) alone:

1. Of its rows, the floors are the set with the most windows in which no two are closer than
   MIN_STOREY_M (``floor_rows``: a weighted interval choice, exact); the other rows' windows (a
   stray sign, a transom row) are contained in the floor they stand in.
2. The storey height is the median spacing of consecutive floor rows up to MAX_STOREY_M
   (``storey_m``, measured), else ASSUMED_STOREY_M; a spacing of n storey heights (a row no window
   of which was found) holds n - 1 more floors, evenly spaced.
3. A floor's level is its row's sill minus the sill height (geometry.SILL_HEIGHT_M, at most the
   typical window height). Doors whose foot lies lower than half the sill height below the lowest
   floor row's sill reach the ground line: the median of their bottoms is the ground floor's level (within MIN_STOREY_M of the lowest
   row's floor, that floor; farther, floors are added down to it, a storey height apart). Without
   such a door, the lowest floor row's floor is the ground floor.
4. Every window (every wall's, partial ones by the middle of their visible part) and every door is
   contained in the floor whose band it stands in: the highest floor at most ``tol_m`` (half the
   typical window height) above its own floor level (sill minus sill height; a door's bottom).

Units: metres at the model's scale, z up (the export world of pipeline.export.geometry).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fenestra.conventions import ASSUMED_STOREY_M, MAX_STOREY_M, MIN_STOREY_M
from fenestra.pipeline.export.geometry import (SILL_HEIGHT_M, STOREY_TOL_FRACTION, PlacedWindow, sill_z,
                                               storey_rows)


@dataclass(frozen=True)
class Floors:
    """The building's floors: ``elevations_m`` (each floor's level, export world, m, bottom-up);
    ``floor_of`` {window index: floor}; ``door_floor_of`` {door index: floor}; ``storey_m`` the
    storey height used and ``storey_measured`` whether the main wall's rows gave it; ``main_wall``
    the wall id the floors come from (None: every window counted as one wall); ``row_sills_m`` the
    sills of the main wall's rows that are floors (m); ``ground`` how the ground floor's level was
    found ("doors" or "lowest row"); ``sill_height_m`` a floor's level below its row's sill;
    ``tol_m`` the band tolerance (and storey_rows' row tolerance)."""

    elevations_m: tuple
    floor_of: dict
    door_floor_of: dict
    storey_m: float
    storey_measured: bool
    main_wall: int | None
    row_sills_m: tuple
    ground: str
    sill_height_m: float
    tol_m: float

    @property
    def names(self) -> tuple:
        """"Ground floor", "Floor 1", ... bottom-up (one name at least: the ground floor)."""
        return tuple("Ground floor" if k == 0 else f"Floor {k}" for k in range(max(1, len(self.elevations_m))))

    @property
    def ground_z_m(self) -> float:
        """The ground floor's level in the world the floors were taken in (0 once grounded)."""
        return self.elevations_m[0] if self.elevations_m else 0.0

    def to_json(self) -> dict:
        """export.json's ``storeys``: the storey height and its source, the main wall, the ground,
        and per floor its name, elevation, windows and doors (one ground floor at 0 m when there
        is none: model.ifc's one storey)."""
        return {"storey_m": self.storey_m, "storey_source": "measured" if self.storey_measured else "assumed",
                "main_wall": self.main_wall, "ground": self.ground, "sill_height_m": self.sill_height_m,
                "tolerance_m": self.tol_m,
                "floors": [{"name": n, "elevation_m": e,
                            "windows": sorted(i for i, f in self.floor_of.items() if f == k),
                            "doors": sorted(i for i, f in self.door_floor_of.items() if f == k)}
                           for k, (n, e) in enumerate(zip(self.names, self.elevations_m or (0.0,)))]}


def floor_rows(sills: np.ndarray, weights: np.ndarray, min_gap: float = MIN_STOREY_M) -> list[int]:
    """Indices (ascending sill) of the rows that are floors: of rows at ``sills`` (N,) m holding
    ``weights`` (N,) windows, the subset of the largest total weight in which consecutive sills
    are at least ``min_gap`` m apart (dynamic programming over the sorted rows; ties: the subset
    with more rows, then the lower rows). [] for no row."""
    s, w = np.asarray(sills, dtype=np.float64), np.asarray(weights, dtype=np.float64)
    order = np.argsort(s, kind="stable")
    s, w = s[order], w[order]
    best: list[tuple] = []  # best[i]: (total weight, rows, chosen indices) of a subset ending at row i
    for i in range(len(s)):
        prev = [best[j] for j in range(i) if s[i] - s[j] >= min_gap]
        base = max(prev, key=lambda b: (b[0], b[1]), default=(0.0, 0, ()))
        best.append((base[0] + w[i], base[1] + 1, base[2] + (i,)))
    if not best:
        return []
    top = max(best, key=lambda b: (b[0], b[1], [-k for k in b[2]]))
    return [int(order[k]) for k in top[2]]


def measured_storey_m(row_sills: list[float], max_storey_m: float = MAX_STOREY_M) -> float | None:
    """The median spacing (m) of consecutive floor rows' sills (ascending) that are at most
    ``max_storey_m``; None without one."""
    gaps = [b - a for a, b in zip(row_sills[:-1], row_sills[1:]) if b - a <= max_storey_m]
    return float(np.median(gaps)) if gaps else None


def filled(levels: list[float], storey_m: float, min_gap: float = MIN_STOREY_M) -> list[float]:
    """``levels`` (ascending, m) with the floors a gap of n storeys holds added: n = the gap over
    ``storey_m`` rounded (at most gap / min_gap), n - 1 levels evenly spaced in it."""
    out = levels[:1]
    for a, b in zip(levels[:-1], levels[1:]):
        n = max(1, min(int(round((b - a) / storey_m)), int((b - a) // min_gap)))
        out.extend(a + (b - a) * k / n for k in range(1, n + 1))
    return out


def band(level_m: float, elevations: list[float], tol_m: float) -> int:
    """The floor a thing whose own floor level is ``level_m`` stands in: the highest of
    ``elevations`` (ascending) at most ``tol_m`` above it; 0 below them all."""
    return int(max([k for k, e in enumerate(elevations) if e <= level_m + tol_m], default=0))


def _main_members(whole: list[PlacedWindow], walls: dict | None) -> tuple[int | None, list[PlacedWindow]]:
    """(main wall id, its whole windows): the wall with the most whole windows (ties: the lower
    id); with ``walls`` None every window is of one wall (id None)."""
    if walls is None:
        return None, whole
    count: dict = {}
    for pw in whole:
        if walls.get(pw.index) is not None:
            count[walls[pw.index]] = count.get(walls[pw.index], 0) + 1
    if not count:
        return None, whole
    main = min(count, key=lambda w: (-count[w], w))
    return main, [pw for pw in whole if walls.get(pw.index) == main]


def floor_levels(placed: list[PlacedWindow], walls: dict | None = None, doors: list[PlacedWindow] = (),
                 sill_height_m: float = SILL_HEIGHT_M, tol_fraction: float = STOREY_TOL_FRACTION,
                 min_storey_m: float = MIN_STOREY_M, max_storey_m: float = MAX_STOREY_M,
                 assumed_storey_m: float = ASSUMED_STOREY_M) -> Floors:
    """The floors of ``placed`` windows and ``doors`` (PlacedWindow, indices of their own) in their
    export world (see the module docstring). walls: {window index: wall id} (None: one wall).
    ValueError naming a bad sill height or storey bound."""
    if not (np.isfinite(sill_height_m) and sill_height_m >= 0):
        raise ValueError(f"sill_height_m must be finite and non-negative, got {sill_height_m!r}")
    if not (0 < min_storey_m <= max_storey_m and min_storey_m <= assumed_storey_m):
        raise ValueError(f"storey bounds must satisfy 0 < min {min_storey_m!r} <= max {max_storey_m!r} and "
                         f"min <= assumed {assumed_storey_m!r}")
    doors = list(doors)
    whole = [pw for pw in placed if not pw.partial] or list(placed)
    main, members = _main_members(whole, walls)
    heights = np.array([pw.height_m for pw in (members or doors)]) if (members or doors) else np.ones(1)
    typical = float(np.median(heights))
    sill_h, tol = float(min(sill_height_m, typical)), float(tol_fraction) * typical
    rows_sills: list[float] = []
    if members:
        sills = np.array([sill_z(pw) for pw in members])
        rows = storey_rows(sills, np.array([pw.height_m for pw in members]), tol_fraction)
        r_sills = np.array([float(np.median(sills[rows == r])) for r in range(int(rows.max()) + 1)])
        r_count = np.array([int((rows == r).sum()) for r in range(len(r_sills))])
        rows_sills = sorted(float(r_sills[k]) for k in floor_rows(r_sills, r_count, min_storey_m))
    measured = measured_storey_m(rows_sills, max_storey_m)
    storey = measured if measured is not None else float(assumed_storey_m)
    levels = filled([s - sill_h for s in rows_sills], storey, min_storey_m)
    lowest_sill = rows_sills[0] if rows_sills else np.inf
    grounding = [sill_z(d) for d in doors if sill_z(d) < lowest_sill - 0.5 * sill_h]
    ground = "lowest row"
    if grounding:
        g, ground = float(np.median(grounding)), "doors"
        if not levels or levels[0] - g < min_storey_m:
            levels = [g] + levels[1:]
        else:
            levels = filled([g, levels[0]], storey, min_storey_m)[:-1] + levels
    floor_of = {pw.index: band(_own_level(pw, sill_h, typical), levels, tol) for pw in placed} if levels else {}
    door_floor_of = {d.index: band(sill_z(d), levels, tol) for d in doors} if levels else {}
    return Floors(tuple(float(e) for e in levels), floor_of, door_floor_of, storey, measured is not None, main,
                  tuple(rows_sills), ground, sill_h, tol)


def _own_level(pw: PlacedWindow, sill_h: float, typical: float) -> float:
    """A window's own floor level (m): its sill minus the sill height; for a partial window (its
    sill may be the photo's edge) the middle of its visible part minus half a typical window too."""
    if not pw.partial:
        return sill_z(pw) - sill_h
    return sill_z(pw) + 0.5 * pw.height_m - 0.5 * typical - sill_h


def on_floor(door: PlacedWindow, level_m: float, reach_m: float) -> PlacedWindow:
    """``door`` with its bottom on its floor's level ``level_m`` (export world, m), its head kept,
    when its foot lies within ``reach_m`` of it or the photo's bottom edge cuts it (``partial``: a
    door runs down to its floor): moved along its own up axis in its wall's plane and its height
    changed (a step or the photo's edge hides a door's foot). Else, or when its up axis is not
    within 60 degrees of the vertical, the door unchanged."""
    up = door.world @ door.R[:, 1]  # the door's up axis in the export world
    dz = sill_z(door) - level_m
    if up[2] < 0.5 or not (door.partial or abs(dz) <= reach_m):
        return door
    height = door.height_m + dz / up[2]
    if not height > 0:
        return door
    return replace(door, height_m=float(height), t=door.t - (dz / up[2]) * door.R[:, 1])


def grounded_floors(placed: list[PlacedWindow], doors: list[PlacedWindow], floors: Floors
                    ) -> tuple[list[PlacedWindow], list[PlacedWindow], Floors]:
    """(placed, doors, floors) with the export world's origin moved onto the ground floor's level
    (z = 0 there), each door's bottom on its floor's level (:func:`on_floor`, within ``tol_m``)."""
    shift = np.array([0.0, 0.0, -floors.ground_z_m])
    moved = replace(floors, elevations_m=tuple(e - floors.ground_z_m for e in floors.elevations_m),
                    row_sills_m=tuple(s - floors.ground_z_m for s in floors.row_sills_m))
    placed = [replace(pw, offset=pw.offset + shift) for pw in placed]
    doors = [replace(d, offset=d.offset + shift) for d in doors]
    if moved.elevations_m:
        doors = [on_floor(d, moved.elevations_m[moved.door_floor_of.get(d.index, 0)], moved.tol_m) for d in doors]
    return placed, doors, moved
