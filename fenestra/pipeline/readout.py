"""What a person reads of one photo's reconstruction, typed: one line per window and the photo's
notes. windows.json's per-window reading fields, the CLI's table and notes, the batch summary, the
overlay's header and the viewer's table are all made from these values, never from windows.json.

    from fenestra.pipeline.readout import readout
    r = readout(result)            # result: pipeline.photo.PhotoResult -> PhotoReadout (pure)
    r.windows[0].status            # "in the model", "not in the model", "failed" or "no model made"
    r.windows[0].reasons           # the failure, flags and why not exported, each once
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from fenestra.pipeline.messages import failure_message
from fenestra.pipeline.types import WindowResult

STATUS_WORDS = {True: "in the model", False: "not in the model", None: "no model made"}


@dataclass(frozen=True)
class WindowLine:
    """One window as its reader sees it.

    index: the detection's index; score: the detector's, 0-1; confidence: the score, halved when the
    wall fit calls the window ill-conditioned, quartered when flagged, 0 when failed; aspect_ratio
    (width/height) and aspect_interval (lo, hi) of the measured window; width_m, height_m: its
    size, m (None without a pose); distance_m: camera to window centre, m; wall: the façade
    model's wall id; K_source: the intrinsics' source; scale_source / scale_assumed: its wall's;
    failure: why the pipeline failed on it (a sentence) or None; flags: why the façade model calls
    it implausible; not_exported: why the export decision keeps it out, None when kept; exported:
    its model was written (None: no model made); partial / cut: cut by the photo's edges (which
    ones), completed to its row's or column's size; visible_fraction: the share of its area the
    photo shows; timings_ms: {stage: ms}.
    """

    index: int
    score: float
    confidence: float
    aspect_ratio: float | None
    aspect_interval: tuple[float, float] | None
    aspect_case: str | None
    width_m: float | None
    height_m: float | None
    distance_m: float | None
    wall: int | None
    K_source: str
    scale_source: str | None
    scale_assumed: bool | None
    failure: str | None
    failure_message: str | None
    flags: tuple[str, ...]
    not_exported: str | None
    exported: bool | None
    partial: bool
    cut: tuple[str, ...]
    visible_fraction: float | None
    timings_ms: Mapping[str, float]

    @property
    def plausible(self) -> bool:
        """No failure and no flag."""
        return self.failure is None and not self.flags

    @property
    def status(self) -> str:
        """One of "failed", "in the model", "not in the model", "no model made"."""
        return "failed" if self.failure is not None else STATUS_WORDS[self.exported]

    @property
    def reasons(self) -> tuple[str, ...]:
        """Why it is not (or not plainly) in the model, in the user's words, each said once: the
        failure's sentence; else the flags; else why the export decision keeps it out (which, for
        a failed or flagged window, only repeats them)."""
        if self.failure_message:
            return (self.failure_message,)
        if self.flags:
            return self.flags
        return (self.not_exported,) if self.not_exported else ()


@dataclass(frozen=True)
class PhotoReadout:
    """One photo's reading: its windows (WindowLine, detection order), the intrinsics
    (pipeline.intrinsics.ResolvedK), the scale's sources and whether any wall's is assumed, the
    walls of the model, the warnings (the photo's, then the focal chain's), the geometry failure (a
    sentence or None), the lens distortion removed (None: none), and the export report
    (pipeline.photo.ExportReport, None when nothing was written)."""

    photo: str
    image_size: tuple[int, int]
    windows: tuple[WindowLine, ...]
    resolved: object
    scale_sources: tuple[str, ...]
    scale_assumed: bool
    walls: int
    warnings: tuple[str, ...]
    geometry_failure: str | None
    distortion: tuple[float, ...] | None
    export: object | None

    @property
    def detected(self) -> int:
        return len(self.windows)

    @property
    def exported(self) -> int:
        return sum(bool(w.exported) for w in self.windows)

    @property
    def flagged(self) -> int:
        return sum(bool(w.flags) for w in self.windows)

    @property
    def failed(self) -> int:
        return sum(w.failure is not None for w in self.windows)

    @property
    def files(self) -> dict[str, str]:
        """{kind: file name} of what was written (empty when nothing was)."""
        return {} if self.export is None else dict(self.export.files)

    def empty_note(self) -> str | None:
        """One line when a model was written but holds no window (how many were detected, flagged,
        failed); None when a window was exported or no model was written."""
        if self.export is None or self.exported or "ifc" not in self.export.files:
            return None
        if not self.windows:
            return "empty output: no window detected; model.ifc and model.obj hold no window, no model.glb"
        return (f"empty output: none of the {self.detected} detected windows exported ({self.flagged} flagged "
                f"implausible, {self.failed} failed; --export-all exports the flagged); model.ifc and model.obj "
                f"hold no window, no model.glb")

    def header(self) -> list[str]:
        """The intrinsics and the scale, one line each (the overlay's header, the CLI's notes), and
        the geometry failure when there is one."""
        k = self.resolved.chosen
        lo, hi = k.interval_px
        lines = [f"K: {k.source}, f = {k.focal_px:.0f} px [{lo:.0f}, {hi:.0f}]",
                 "scale: " + ("; ".join(self.scale_sources) or "none")]
        if self.geometry_failure:
            lines.append(f"geometry failed: {self.geometry_failure}")
        return lines


def aspect_interval(w: WindowResult, envelope: dict[int, tuple[float, float]]) -> tuple[float, float] | None:
    """A window's aspect interval (lo, hi): its fit's 90 % interval (widened when flagged) joined
    with its aspect ratios at the ends of the focal interval (pipeline.session.focal_envelope);
    None for a failed window and for a partial one (its visible extent's w/h is not the window's)."""
    if w.failure is not None or w.aspect_ratio is None or w.partial is not None:
        return None
    unc = w.uncertainty
    vals = [w.aspect_ratio, *(() if unc is None else (unc.aspect_lo, unc.aspect_hi)), *envelope.get(w.index, ())]
    return float(min(vals)), float(max(vals))


def confidence(w: WindowResult, flagged: bool) -> float:
    """The detector score, halved when the wall fit calls the window ill-conditioned, quartered
    when flagged; 0 for a failed window."""
    if w.failure is not None:
        return 0.0
    ill = w.uncertainty is not None and w.uncertainty.ill_conditioned
    return w.score * (0.5 if ill else 1.0) * (0.25 if flagged else 1.0)


def window_lines(rec, export_models: bool = True, written: set[int] | None = None) -> tuple[WindowLine, ...]:
    """The WindowLine of each window of a pipeline.session.Reconstruction (pure).

    Args:
        rec: the Reconstruction.
        export_models: models are made (``exported`` is the decision), else ``exported`` None.
        written: the indices whose model was written (None: the decision alone).
    Returns:
        one WindowLine per window, in detection order.
    """
    lines = []
    for win in rec.windows:
        r, k = win.result, win.index
        wall = rec.model.wall_of(k)
        flags = tuple(rec.model.flags.get(k, []))
        measured = r if win.regularized is None else win.measured
        iv = aspect_interval(measured, rec.envelope)
        posed = r.aspect_ratio is not None and r.R is not None
        lines.append(WindowLine(
            index=k, score=float(r.score), confidence=confidence(r, bool(flags)),
            aspect_ratio=None if r.aspect_ratio is None else float(r.aspect_ratio),
            aspect_interval=None if iv is None else (float(iv[0]), float(iv[1])),
            aspect_case=None if r.aspect_case is None else r.aspect_case.value,
            width_m=float(r.aspect_ratio * r.height_m) if posed else None,
            height_m=None if r.R is None or r.height_m is None else float(r.height_m),
            distance_m=None if r.t is None else float(np.linalg.norm(np.asarray(r.t, float))),
            wall=win.wall, K_source=rec.resolved.source,
            scale_source=None if wall is None else wall.scale_source,
            scale_assumed=None if wall is None else bool(wall.assumed),
            failure=None if r.failure is None else str(r.failure),
            failure_message=None if r.failure is None else failure_message(r.failure, () if r.partial is None else r.partial.cut),
            flags=flags, not_exported=win.export.reason,
            exported=(win.export.exported and (written is None or k in written)) if export_models else None,
            partial=r.partial is not None, cut=() if r.partial is None else tuple(r.partial.cut),
            visible_fraction=None if r.partial is None else r.partial.visible_fraction,
            timings_ms=dict(r.timings_ms)))
    return tuple(lines)


def readout(result) -> PhotoReadout:
    """The PhotoReadout of a pipeline.photo.PhotoResult (pure)."""
    rec = result.reconstruction
    written = None if result.export is None else set(result.export.exported)
    walls = rec.model.walls
    return PhotoReadout(
        photo=result.photo, image_size=tuple(result.image_size),
        windows=window_lines(rec, result.export_models, written), resolved=rec.resolved,
        scale_sources=tuple(sorted({w.scale_source for w in walls})), scale_assumed=any(w.assumed for w in walls),
        walls=len(rec.model_wall_ids()), warnings=(*result.warnings, *rec.resolved.warnings),
        geometry_failure=None if rec.geometry_failure is None else rec.geometry_failure.reason,
        distortion=None if not result.undistorted else tuple(result.distortion or ()), export=result.export)
