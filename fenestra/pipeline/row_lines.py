"""Row regularization: the windows of one storey row of one wall share their sill and
head lines, as façade models have them.

    results, fits = regularize_rows(results, model, K)
    fits[k]          # RowFit of window k's row: consensus sill and head, tolerance, the voters
    fits[k].regularized   # True: window k now has the row's sill and head (its height changed)

A single photo measures each window's sill and head on its own, so the windows of one row of one
façade come out a few per cent apart in height and sill even where the building has one window
type (the median spread within a row of ``--known-storey`` runs of the St Petersburg test photos
was 7 %). Here, per wall of the façade model (:mod:`pipeline.facade_model`), its voters (whole,
posed, unflagged members: never a partial window, cut by the photo's border, nor an implausible
one) are grouped into rows by their sill along the wall's up axis with the export's own rule
(:func:`pipeline.export.geometry.storey_rows`: sills within half the median window height, the
same rows model.ifc's storeys get). In each row of at least two voters the consensus sill and
head are the medians (:func:`row_consensus`); a voter whose sill and head both lie within
ROW_AGREE_FRACTION of the consensus height of them agrees, and the consensus is then the median
over the agreeing ones. With at least two agreeing voters each of them is moved in its wall's
plane (along its own up axis) onto the consensus sill and gets the consensus height; its width,
rotation and plane stay measured, its aspect ratio becomes its measured width over the new height
and its reprojected quad that of the new rectangle. A window that does not agree (a door, a
window of another type, a bad fit) keeps its own geometry. Heights are lengths at the wall's
scale, so the step is the same with or without a known size (it runs always).

The measured window stays available: :func:`regularize_rows` returns the fits, and the caller
(pipeline.session) keeps the measured WindowResult of every regularized window (windows.json's
``measured``; what the bench measures a window's geometry by).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fenestra.conventions import project
from fenestra.pipeline.types import WindowResult

# A window agrees with its row when its sill and its head each lie within this fraction of the
# row's consensus height of the consensus lines (0.10: 15 cm on a 1.5 m window; 2.5 pixels on a
# 25-pixel-tall window, about what one pixel of mask error on each edge makes).
ROW_AGREE_FRACTION = 0.10
UP_AGREE_COS = 0.9  # a voter's up axis within ~25 deg of its wall's (merged walls agree within 10 deg)


@dataclass(frozen=True)
class RowFit:
    """One row of one wall: wall id, row (0 = lowest on the wall), the consensus sill and head
    (m along the wall's up axis, from the camera centre, at the wall's scale), the agreement
    tolerance (m), the windows that voted (whole, unflagged), those that agree, and whether this
    window was regularized (moved onto the consensus)."""

    wall: int
    row: int
    sill_m: float
    head_m: float
    tol_m: float
    voters: tuple[int, ...]
    agreeing: tuple[int, ...]
    regularized: bool

    def to_json(self) -> dict:
        return {"wall": self.wall, "row": self.row, "sill_m": self.sill_m, "head_m": self.head_m,
                "height_m": self.head_m - self.sill_m, "tol_m": self.tol_m, "voters": list(self.voters),
                "agreeing": list(self.agreeing), "regularized": self.regularized}


def row_consensus(sills: np.ndarray, heads: np.ndarray, fraction: float = ROW_AGREE_FRACTION
                  ) -> tuple[float, float, float, np.ndarray]:
    """(consensus sill, consensus head, tolerance, agreeing (N,) bool) of one row's windows, sills
    and heads (N,) in one unit along one up axis: the medians; tol = fraction x (head - sill) of
    them; a window agrees when |sill - consensus sill| <= tol and |head - consensus head| <= tol;
    with at least two agreeing, the consensus is the median over them (the tolerance kept)."""
    s, h = np.asarray(sills, dtype=np.float64), np.asarray(heads, dtype=np.float64)
    if s.shape != h.shape or s.ndim != 1 or not len(s):
        raise ValueError(f"sills and heads must be (N,) arrays of one length N >= 1, got shapes {s.shape}, {h.shape}")
    S, H = float(np.median(s)), float(np.median(h))
    tol = float(fraction) * (H - S)
    agree = (np.abs(s - S) <= tol) & (np.abs(h - H) <= tol)
    if agree.sum() >= 2:
        S, H = float(np.median(s[agree])), float(np.median(h[agree]))
    return S, H, tol, agree


def regularized(r: WindowResult, up: np.ndarray, sill: float, head: float, K: np.ndarray | None) -> WindowResult:
    """Window ``r`` with its sill and head at ``sill`` and ``head`` along ``up`` (3,) camera frame
    (its wall's up axis): moved along its own up axis R[:, 1] (in its plane), its height changed,
    its width kept (aspect ratio = measured width / new height), its reprojected quad the new
    rectangle's under K (3, 3) px (kept when K is None)."""
    R, t = np.asarray(r.R, dtype=np.float64), np.asarray(r.t, dtype=np.float64).reshape(3)
    c = float(up @ R[:, 1])  # ~1: the window's up axis along the wall's
    w = float(r.aspect_ratio) * float(r.height_m)
    h = (head - sill) / c
    t2 = t + (sill - float(up @ t)) / c * R[:, 1]
    rect = np.array([[0.0, h, 0.0], [w, h, 0.0], [w, 0.0, 0.0], [0.0, 0.0, 0.0]])  # TL TR BR BL, window frame
    quad = r.quad_reprojected if K is None else project(np.asarray(K, dtype=np.float64), R, t2, rect)
    return replace(r, t=t2, height_m=float(h), aspect_ratio=w / h, quad_reprojected=quad)


def regularize_rows(results: list[WindowResult], model, K: np.ndarray | None = None,
                    fraction: float = ROW_AGREE_FRACTION) -> tuple[list[WindowResult], dict[int, RowFit]]:
    """The results with each wall's agreeing windows on their rows' consensus sill and head lines
    (see the module docstring), and {window index: RowFit} of every voter in a row of at least two
    voters (``regularized`` False for those that keep their own). model: the façade model
    (pipeline.facade_model.FacadeModel: walls, flags); K (3, 3) px: for the reprojected quads.
    A new list; windows that are not regularized are the same objects."""
    from fenestra.pipeline.export.geometry import storey_rows  # noqa: PLC0415  (the export's row rule)

    out, fits = list(results), {}
    for wall in model.walls:
        voters = [k for k in wall.members if k not in model.flags and out[k].failure is None
                  and out[k].partial is None and out[k].R is not None and float(out[k].height_m) > 0]
        up = np.asarray(out[wall.members[0]].R, dtype=np.float64)[:, 1] if wall.members else None
        voters = [k for k in voters if float(up @ np.asarray(out[k].R)[:, 1]) > UP_AGREE_COS]
        if len(voters) < 2:
            continue
        sills = np.array([float(up @ np.asarray(out[k].t, dtype=np.float64).reshape(3)) for k in voters])
        heads = sills + np.array([float(out[k].height_m) * float(up @ np.asarray(out[k].R)[:, 1]) for k in voters])
        rows = storey_rows(sills, np.array([float(out[k].height_m) for k in voters]))
        for row in np.unique(rows):
            pick = np.flatnonzero(rows == row)
            if len(pick) < 2:
                continue
            S, H, tol, agree = row_consensus(sills[pick], heads[pick], fraction)
            ok = agree.sum() >= 2
            members = tuple(voters[i] for i in pick)
            agreeing = tuple(k for k, a in zip(members, agree) if a)
            for k, a in zip(members, agree):
                fits[k] = RowFit(wall.id, int(row), S, H, tol, members, agreeing, bool(ok and a))
                if ok and a:
                    out[k] = regularized(out[k], up, S, H, K)
    return out, fits
