"""One photo, any number of methods: the session that ``fenestra reconstruct`` and the bench share.

    session = PhotoSession(image, camera=UserCamera(K, "--K K.json"))   # or camera=None: K-free
    rec = session.run(Method("default", "refine", "wall+lines"))         # a Reconstruction
    rec.resolved         # the K used and where it came from (pipeline.intrinsics.ResolvedK)
    rec.model            # walls, their scales and the implausible windows (pipeline.facade_model)
    rec.windows[i]       # a Window: every stage's value (fit, measured, placed, regularized, export)
    rec.windows[i].result    # as the model holds it; .measured: as a whole window on its wall
    rec.exported         # {detection index: True/False}: what goes into the BIM model

The CLI makes one session per photo and runs one method; the bench makes one per view and runs
every method of its profile, then measures the rows. Both get the same answer for the same method,
because both go through :meth:`PhotoSession.run`: the detector at the CLI's resolution
(pipeline.detectors.detect), the quad fit, snapping, aspect ratio and pose, the focal chain when
the method has no K (EXIF, vanishing points, prior: pipeline.intrinsics), the façade model (one
plane and one scale per wall: pipeline.facade_model), the windows cut by the photo's border placed
on those walls afterwards (their visible part: pipeline.facade_model.place_partials) and the export
decision (pipeline.export.export_decision), each stage's value kept in a :class:`Window`.

Partial windows. A detection whose mask reaches the photo's edge fails the quad stage
(``touches_border``: its corners there are not in the photo), so it takes no part in the geometry,
the focal chain or the façade model's walls, scales and statistics. Its visible part is then
fitted with the image edge allowed as a side (pipeline.reconstruct.visible_quads: the mask fit with
``allow_border``, the quad of what the photo shows, not snapped) and placed on the wall its sides
point along, with that wall's pose and scale (its visible extent on the wall's plane); with no such
wall it stays a recorded failure. ``WindowResult.partial`` says which edges cut it.

The session owns what the methods on one photo share, each computed once: the gray image, its line
segments (pipeline.segments.SegmentCache), the step memo (pipeline.memo.StepMemo), each detector's
detections, the quads per detector and quad source, the per-window results a per-wall strategy
starts from, the resolved K per method, and the geometry per method (the façade model, cheap, is
applied per ``known``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from fenestra.errors import PipelineError
from fenestra.methods import Method
from fenestra.pipeline.facade_model import FacadeModel, Known, facade_model, place_partials
from fenestra.pipeline.intrinsics import choose_focal, exif_focal_of_tags, resolve_K_with, ResolvedK, user_focal
from fenestra.pipeline.memo import StepMemo
from fenestra.pipeline.poses import POSES
from fenestra.pipeline.quad import QuadParams
from fenestra.pipeline.reconstruct import (ReconstructConfig, failed_results, fit_quads, reconstruct_from_quads,
                                           to_gray, visible_quads)
from fenestra.pipeline.row_lines import RowFit, regularize_rows
from fenestra.pipeline.segments import SegmentCache, to_uint8
from fenestra.pipeline.types import Detection, Failure, Unavailable, WindowResult
from fenestra.pipeline.aspect import AspectError, aspect_ratio
from fenestra.pipeline.doors import place_openings

SCORE_MIN = 0.5  # detections a user gets (the detectors' default threshold): reconstructed and exported
CANDIDATE_SCORE_MIN = 0.05  # detections kept for detection AP (the bench), a superset of the above


@dataclass(frozen=True)
class UserCamera:
    """The intrinsics a user gave: K (3, 3) px, in the frame of the session's image, and how it
    was given (e.g. "--K K.json", for ``K_source``)."""

    K: np.ndarray
    how: str


@dataclass(frozen=True)
class Geometry:
    """A method's reconstruction before the façade model: results (one per detection), the K
    used, where it came from, the aspect envelope of the focal interval, and the geometry's
    failure as a whole (None, or a Failure every window then carries)."""

    results: tuple[WindowResult, ...]
    resolved: ResolvedK
    envelope: dict
    failure: Failure | None


@dataclass(frozen=True)
class ExportDecision:
    """Whether one window goes into the BIM model: ``exported``, or ``reason`` (one line) why not:
    failed, implausible (unless export_all), an unusable pose or a size no mesh takes
    (pipeline.export.export_decision, made once per run: the writers follow it)."""

    exported: bool
    reason: str | None = None


@dataclass(frozen=True)
class Window:
    """One detection through every stage of one method; each stage adds its field, none is
    overwritten (:meth:`PhotoSession.run`).

    index: the detection's (``Reconstruction.detections[index]``); fit: the method's per-window or
    per-wall result before the façade model (at the scale parameter); measured: on its wall's plane
    at its wall's scale (pipeline.facade_model.facade_model; a window cut by the photo's border: its
    whole-window failure, its whole corners and size not being in the photo); placed: a partial
    window's visible part placed on a wall, or its failure (pipeline.facade_model.place_partials),
    None for a whole window; row: the pipeline.row_lines.RowFit of the row it voted in, or None;
    regularized: on its row's consensus sill and head (pipeline.row_lines.regularize_rows), None
    when it keeps its own; export: its :class:`ExportDecision`; wall: the id of the façade model's
    wall it is on (pipeline.facade_model.FacadeModel.wall_of: a member, or a placed partial window),
    None for a window on none (failed). ``fit.group`` is the joint fit's own grouping, before walls
    that face one plane merge.
    """

    index: int
    fit: WindowResult
    measured: WindowResult
    placed: WindowResult | None
    row: RowFit | None
    regularized: WindowResult | None
    export: ExportDecision
    wall: int | None = None

    @property
    def result(self) -> WindowResult:
        """The window as the model holds it (windows.json's main fields, the files): regularized,
        else its placed visible part, else as measured."""
        return next(r for r in (self.regularized, self.placed, self.measured) if r is not None)

    @property
    def shipped(self) -> WindowResult:
        """The window as a BIM user gets it, measured as a whole window: :attr:`result`, but for a
        partial window its whole-window failure (its whole size is not in the photo). What the
        bench's BIM errors (width, height, position) measure; its corner, aspect-ratio and pose
        errors measure :attr:`measured`."""
        return self.measured if self.placed is not None else self.result

    @property
    def partial(self):
        """The pipeline.types.Partial of a window cut by the photo's border, else None."""
        return self.result.partial


@dataclass(frozen=True)
class Reconstruction:
    """What one method gives on one photo (what windows.json holds, typed).

    method; detections (the detector's, score >= SCORE_MIN, best first; ``windows[i]`` is
    ``detections[i]``'s); windows: one :class:`Window` per detection, every stage's value kept;
    resolved: pipeline.intrinsics.ResolvedK (``K``: the K used); model:
    pipeline.facade_model.FacadeModel; known: what set the scale; envelope: {index: (lo, hi)}
    aspect ratio at the ends of the focal interval; geometry_failure: Failure or None; openings:
    the detections the box verifier calls no window (score >= SCORE_MIN), each a
    pipeline.doors.Opening: a door placed on its wall (an IfcDoor), a signboard left out.
    """

    method: Method
    detections: tuple[Detection, ...]
    windows: tuple[Window, ...]
    resolved: ResolvedK
    model: FacadeModel
    known: Known
    envelope: dict
    geometry_failure: Failure | None
    openings: tuple = ()

    @property
    def K(self) -> np.ndarray:
        return self.resolved.K

    def results(self) -> list[WindowResult]:
        """Every window as the model holds it (:attr:`Window.result`), in detection order: what
        the writers draw, inpaint and export."""
        return [w.result for w in self.windows]

    @property
    def not_exported(self) -> dict[int, str]:
        """{detection index: reason} of every window that stays out of the BIM model."""
        return {w.index: w.export.reason for w in self.windows if not w.export.exported}

    @property
    def exported(self) -> dict[int, bool]:
        """{detection index: whether the window goes into the model}."""
        return {w.index: w.export.exported for w in self.windows}

    def model_wall_ids(self) -> set[int]:
        """The walls of the façade model a user gets: the walls holding a window that goes into the
        BIM model and has no failure (a wall fitted to flagged windows only, a lone window whose
        plane is nonsense or a shop sign, is no wall of the model: model.ifc holds none for it)."""
        return {w.wall for w in self.windows if w.wall is not None and w.export.exported and w.result.failure is None}

    def scale_source(self, index: int) -> str | None:
        """How window ``index``'s wall got its scale: "assumed" (the default window height), or
        the Known field that set it ("storey_m", "window_height_m", "window_width_m"); None for a
        window on no wall (failed)."""
        wall = self.model.wall_of(index)
        if wall is None:
            return None
        if wall.assumed:
            return "assumed"
        return next(k for k, v in vars(self.known).items() if v is not None)


@dataclass
class PhotoSession:
    """The per-photo state every method shares (see the module docstring). Not thread-safe; one
    per photo.

    image: (H, W, 3) uint8 RGB, in the frame of ``camera`` and ``instances`` (undistorted where
    the camera has distortion). camera: the user's intrinsics, or None (a method then resolves K
    through the focal chain). exif: the photo's EXIF tags {tag id: value}
    (pipeline.intrinsics.read_exif_tags: its focal length joins the chain), {} for an image
    without (a render).
    instances: an (H, W) instance map (a user's ``--masks``, or a render's truth) for the
    detectors that read one (capability ``needs_instances``: ``oracle``). detector_options:
    {detector: {build option: value}}. max_side: learned detectors see the photo with its long
    side at most this (px; None: fenestra.conventions.LIMITS.detector_max_side_px, the CLI's).
    """

    image: np.ndarray
    camera: UserCamera | None = None
    exif: dict = field(default_factory=dict)
    instances: np.ndarray | None = None
    detector_options: dict = field(default_factory=dict)
    max_side: int | None = None
    stage_s: dict = field(default_factory=dict)  # CPU seconds per stage computed (not reused) in this session

    def __post_init__(self) -> None:
        self.gray = to_gray(self.image)
        self.size = (self.image.shape[1], self.image.shape[0])  # (W, H)
        self.segments = SegmentCache(to_uint8(self.gray))  # the photo's line segments, found once
        self.memo = StepMemo()  # the steps with identical inputs, computed once for every method
        self._candidates: dict[str, list[Detection]] = {}
        self._quads: dict = {}
        self._per_window: dict = {}
        self._resolved: dict = {}
        self._geometry: dict = {}

    # ------------------------------------------------------------ detection

    def candidates(self, detector: str) -> list[Detection]:
        """Every window detection of ``detector`` down to CANDIDATE_SCORE_MIN, best first (cached)."""
        return [d for d in self._all_candidates(detector) if d.kind == "window"]

    def _all_candidates(self, detector: str) -> list[Detection]:
        """Every detection of ``detector``, of every kind (pipeline.types.DETECTION_KINDS), down to
        CANDIDATE_SCORE_MIN, best first (cached)."""
        if detector not in self._candidates:
            from fenestra.pipeline.detectors import detect, detector_entry  # noqa: PLC0415 (pipeline.detectors loads torch: imported when first used)
            from fenestra.pipeline.types import DETECTION_KINDS  # noqa: PLC0415 (beside the detectors, which it names)

            t0 = time.process_time()
            opts = dict(self.detector_options.get(detector, {}))
            if detector_entry(detector).needs_instances:
                if self.instances is None:
                    raise PipelineError(f"detector {detector!r} needs an instance map (--masks); none was given")
                dets = detect(detector, self.image, CANDIDATE_SCORE_MIN, instances=self.instances,
                              kinds=DETECTION_KINDS, **opts)
            else:
                if self.max_side:
                    opts["max_side"] = self.max_side
                dets = detect(detector, self.image, CANDIDATE_SCORE_MIN, kinds=DETECTION_KINDS, **opts)
            self._tick("detect", t0)
            self._candidates[detector] = dets
        return self._candidates[detector]

    def detections(self, detector: str) -> list[Detection]:
        """The window detections a user gets (score >= SCORE_MIN), best first."""
        return [d for d in self.candidates(detector) if d.score >= SCORE_MIN]

    def non_windows(self, detector: str) -> list[Detection]:
        """The detections a user gets (score >= SCORE_MIN) that the detector's box verifier calls a
        door or a signboard, best first."""
        return [d for d in self._all_candidates(detector) if d.kind != "window" and d.score >= SCORE_MIN]

    def openings(self, method: Method, final: list[WindowResult], model: FacadeModel, exported: set,
                 K: np.ndarray) -> tuple:
        """pipeline.doors.place_openings of the method's non-window detections: doors on the walls
        of the windows ``exported`` (detection indices), ``final`` the windows as the model holds
        them."""

        dets = self.non_windows(method.detector)
        if not dets:
            return ()
        params = self.config(method).quad
        fits = fit_quads(dets, params, self.gray.shape)
        return place_openings(dets, fits, visible_quads(dets, fits, params, self.gray.shape), final, model, exported,
                              K, self.size)

    # ------------------------------------------------------------ geometry

    def config(self, method: Method, height_m: float = 1.0) -> ReconstructConfig:
        return ReconstructConfig.of(method, height_m)

    def quads(self, detector: str, params: QuadParams) -> list:
        """fit_quads of the detector's detections (cached per detector and quad parameters)."""
        k = (detector, params)
        if k not in self._quads:
            t0 = time.process_time()
            self._quads[k] = fit_quads(self.detections(detector), params, self.gray.shape)
            self._tick("quad", t0)
        return self._quads[k]

    def visible(self, detector: str, params: QuadParams) -> dict:
        """{detection index: QuadResult of its visible part} of the detections cut by the photo's
        border (pipeline.reconstruct.visible_quads of :meth:`quads`; cached per detector and quad
        parameters)."""
        k = ("visible", detector, params)
        if k not in self._quads:
            t0 = time.process_time()
            self._quads[k] = visible_quads(self.detections(detector), self.quads(detector, params), params,
                                           self.gray.shape)
            self._tick("quad", t0)
        return self._quads[k]

    def _per_window_results(self, detector: str, K: np.ndarray | None, cfg: ReconstructConfig) -> list:
        """reconstruct_from_quads with a per-window solver (``cfg.pose``), cached per detector, K,
        snapper, quad parameters and scale: the base every per-wall strategy starts from."""
        k = (detector, None if K is None else np.asarray(K).tobytes(), cfg)
        if k not in self._per_window:
            t0 = time.process_time()
            self._per_window[k] = reconstruct_from_quads(self.gray, K, self.detections(detector),
                                                         self.quads(detector, cfg.quad), cfg, memo=self.memo)
            self._tick("reconstruct", t0)
        return self._per_window[k]

    def reconstruct(self, detector: str, K: np.ndarray | None, cfg: ReconstructConfig) -> list[WindowResult]:
        """One method's per-window or per-wall results with K (None: K-free per-window estimate)."""
        wall = POSES[cfg.pose].wall
        if wall is None:
            return list(self._per_window_results(detector, K, cfg))
        base = self._per_window_results(detector, K, replace(cfg, pose=wall.base_pose))
        t0 = time.process_time()
        out = reconstruct_from_quads(self.gray, K, self.detections(detector), self.quads(detector, cfg.quad), cfg,
                                     base=base, segment_cache=self.segments, memo=self.memo)
        self._tick("wall", t0)
        return out

    def resolve(self, method: Method) -> ResolvedK:
        """The method's intrinsics: the user's K (compared with EXIF) unless the method withholds
        it; else the focal chain (EXIF, the façade's vanishing points with the method's per-wall
        strategy and its snapped quads, the prior). Cached per (detector, snapper, pose, quad)."""

        exif = exif_focal_of_tags(self.exif, self.size)
        if self.camera is not None and not method.withhold_K:
            K = np.asarray(self.camera.K, dtype=np.float64)
            r = choose_focal([user_focal(K, self.camera.how), exif if exif is not None else Unavailable("no EXIF focal length")],
                             ["K", "exif"], self.size, principal_point=(float(K[0, 2]), float(K[1, 2])))
            return replace(r, K=K)  # the user's K as given (fy, skew kept)
        k = (method.detector, method.snapper, method.pose, method.quad_source)
        if k not in self._resolved:
            t0 = time.process_time()
            quads = self.kfree_quads(method)
            self._resolved[k] = resolve_K_with(exif, quads, self.size, POSES[method.pose].wall, self.segments)
            self._tick("focal", t0)
        return self._resolved[k]

    def kfree_quads(self, method: Method) -> np.ndarray:
        """The snapped quads (N, 4, 2) px the focal chain sees for ``method`` with K withheld: the
        method's per-window fit with no K (a focal length of the long side as its fallback)."""
        cfg = self.config(method)
        W, H = self.size
        per = self._per_window_results(method.detector, None,
                                       replace(cfg, pose=POSES[cfg.pose].per_window_pose,
                                               fallback_focal_px=float(max(H, W))))
        return np.array([r.quad_snapped for r in per if r.quad_snapped is not None]).reshape(-1, 4, 2)

    def geometry(self, method: Method, height_m: float = 1.0) -> Geometry:
        """The method's results before the façade model (cached): K resolved, then every detection
        reconstructed with it; a failure of the geometry as a whole is recorded, not raised."""
        k = (method, height_m)
        if k not in self._geometry:
            resolved = self.resolve(method)
            cfg = self.config(method, height_m)
            dets = self.detections(method.detector)
            try:
                results = self.reconstruct(method.detector, resolved.K, cfg)
                envelope = focal_envelope(results, resolved.K, resolved.chosen.interval_px)
                failure = None
            except PipelineError as e:  # recorded: the detections are still written, each with this failure
                failure = Failure("geometry", None, str(e))
                results, envelope = failed_results(dets, cfg, failure), {}
            self._geometry[k] = Geometry(tuple(results), resolved, envelope, failure)
        return self._geometry[k]

    def run(self, method: Method, known: Known = Known(), export_all: bool = False,
            style: str | None = None, height_m: float = 1.0, regularize: bool = True) -> Reconstruction:
        """The method on this photo, as ``fenestra reconstruct`` runs it: geometry, façade model
        with ``known``, the partial windows placed on its walls (pipeline.facade_model.place_partials),
        the rows' sill and head lines regularized (pipeline.row_lines.regularize_rows; not with
        ``regularize`` False) and the export decision (flagged windows stay out unless export_all;
        style: the catalogue window, None for the default), then the doors and signboards
        (:meth:`openings`)."""
        from fenestra.pipeline.export import DEFAULT_STYLE, export_decision  # noqa: PLC0415 (fenestra.pipeline.export loads IfcOpenShell: imported when first used)

        g = self.geometry(method, height_m)
        measured, model = facade_model(list(g.results), known)
        visible = self.visible(method.detector, self.config(method, height_m).quad)
        placed, model = place_partials(measured, model, visible, g.resolved.K, self.size, known)
        final, rows = regularize_rows(placed, model, g.resolved.K) if regularize else (placed, {})
        out = export_decision(final, style or DEFAULT_STYLE, kept_out(model, export_all))
        windows = tuple(Window(k, g.results[k], measured[k], placed[k] if placed[k].partial is not None else None,
                               rows.get(k), final[k] if k in rows and rows[k].regularized else None,
                               ExportDecision(k not in out, out.get(k)), _wall_id(model, k))
                        for k in range(len(final)))
        openings = self.openings(method, final, model, {w.index for w in windows if w.export.exported}, g.resolved.K)
        return Reconstruction(method, tuple(self.detections(method.detector)), windows, g.resolved, model, known,
                              g.envelope, g.failure, openings)

    def _tick(self, stage: str, t0: float) -> None:
        self.stage_s[stage] = self.stage_s.get(stage, 0.0) + time.process_time() - t0


def _wall_id(model: FacadeModel, index: int) -> int | None:
    wall = model.wall_of(index)
    return None if wall is None else wall.id


def kept_out(model: FacadeModel, export_all: bool = False) -> dict[int, str]:
    """{window index: reason} of the implausible windows the model leaves out (none with
    ``export_all``): the one rule both the export decision and the written files follow."""
    return {} if export_all else {k: "implausible: " + "; ".join(v) for k, v in model.flags.items()}


def focal_envelope(results: list, K: np.ndarray, interval_px: tuple[float, float]) -> dict[int, tuple[float, float]]:
    """{window index: (min, max) aspect ratio} when the focal length moves to the ends of its
    interval: each posed window's aspect ratio plus the change of its quad's closed-form aspect
    ratio (pipeline.aspect.aspect_ratio, Zhang & He with K) from K's focal length to each end (ms
    per window, no refit). {} when the interval is a single value (the user's K)."""

    lo, hi = interval_px
    if not hi > lo:
        return {}

    def with_f(f: float) -> np.ndarray:
        Kf = np.array(K, dtype=np.float64)
        Kf[0, 0], Kf[1, 1] = f, f * K[1, 1] / K[0, 0]
        return Kf

    out = {}
    for r in results:
        if r.failure is not None or r.aspect_ratio is None or r.quad_snapped is None:
            continue
        try:
            a0 = aspect_ratio(r.quad_snapped, K).ratio
            d = [aspect_ratio(r.quad_snapped, with_f(f)).ratio - a0 for f in (lo, hi)]
        except (AspectError, ValueError):
            continue
        out[r.index] = (float(r.aspect_ratio + min(0.0, *d)), float(r.aspect_ratio + max(0.0, *d)))
    return out


__all__ = ["CANDIDATE_SCORE_MIN", "ExportDecision", "Geometry", "focal_envelope", "kept_out", "PhotoSession", "Reconstruction", "SCORE_MIN", "UserCamera", "Window"]
