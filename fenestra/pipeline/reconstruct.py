"""One photo + detections -> one WindowResult per detection: quad, snapping, aspect ratio, pose.

    results = reconstruct(image_rgb, K, detections, ReconstructConfig(snapper="linefit"))
    json.dump(windows_to_json(results), f)

To run several configs on the same detections, fit the quads (the costly stage) once:

    quads = fit_quads(detections, QuadParams(), image_rgb.shape[:2])
    for cfg in configs:
        results = reconstruct_from_quads(to_gray(image_rgb), K, detections, quads, cfg)

Each stage's failure is recorded in the result's ``failure`` (a pipeline.types.Failure) and the
remaining windows carry on; only malformed arguments (wrong shapes, unknown strategy) raise.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from fenestra.checks import check_image, check_K
from fenestra.conventions import DEFAULTS
from fenestra.errors import PipelineError
from fenestra.pipeline.aspect import aspect_ratio
from fenestra.pipeline.memo import StepMemo, key
from fenestra.pipeline.pose import estimate_pose
from fenestra.pipeline.poses import POSES, PoseStrategy, pose_strategies  # noqa: F401  (re-exported: the one registry)
from fenestra.pipeline.quad import QuadParams, QuadResult, corners_agree_with_mask, corners_to_quad, mask_to_quad
from fenestra.pipeline.segments import SegmentCache
from fenestra.pipeline.snappers import SNAPPERS
from fenestra.pipeline.types import Detection, Failure, WindowResult
from fenestra.pipeline.walls import apply_walls

STAGES = ("quad", "snap", "aspect", "pose")


@dataclass(frozen=True)
class ReconstructConfig:
    """Strategy choices and parameters of :func:`reconstruct`.

    snapper: a key of ``pipeline.snappers.SNAPPERS``; snapper_params: its dataclass (None: defaults).
    pose: a key of :data:`POSES`: per window, or per wall (windows grouped into walls, each wall
    fitted once).
    The defaults are ``fenestra.conventions.DEFAULTS``.
    height_m / width_m: the scale parameter (the window's height, or its width if given), m.
    fallback_focal_px: focal length used when K is None and the quad cannot give one.
    quad: parameters of the mask -> quad stage.
    """

    snapper: str = DEFAULTS.snapper
    pose: str = DEFAULTS.pose
    height_m: float = 1.0
    width_m: float | None = None
    fallback_focal_px: float | None = None
    snapper_params: object | None = None
    quad: QuadParams = field(default_factory=QuadParams)

    @classmethod
    def of(cls, method, height_m: float = 1.0, **params) -> "ReconstructConfig":
        """The config that runs a fenestra.methods.Method: its snapper, pose and quad source, the
        scale parameter ``height_m`` and any other field in ``params`` (the one place a method
        becomes a config: the session's runs and windows.json's ``config``)."""
        return cls(snapper=method.snapper, pose=method.pose, height_m=height_m,
                   quad=QuadParams(source=method.quad_source), **params)

    def __post_init__(self) -> None:
        SNAPPERS.lookup(self.snapper)  # UnknownName (a ValueError) naming the choices
        POSES.lookup(self.pose)
        for name in ("height_m", "width_m"):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive, got {v}")


def to_gray(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 gray from an (H, W, 3) uint8 RGB image (fenestra.checks.check_image), or an
    (H, W) gray one, returned as float32 (not copied when it is already). Gray = 0.299 R + 0.587 G + 0.114 B
    (OpenCV, rounded to uint8)."""
    img = np.asarray(image)
    if img.ndim == 2:
        return img.astype(np.float32, copy=False)
    return cv2.cvtColor(check_image(img), cv2.COLOR_RGB2GRAY).astype(np.float32)


def _result(i: int, det: Detection, cfg: ReconstructConfig, timings: dict, failure: Failure | None = None,
            **stages) -> WindowResult:
    """A WindowResult with the stages reached so far (``stages``: WindowResult fields); rest None."""
    fields = dict(quad_mask=None, quad_snapped=None, aspect_ratio=None, aspect_case=None,
                  focal_estimate_px=None, R=None, t=None, quad_reprojected=None, height_m=cfg.height_m)
    fields.update(stages)
    return WindowResult(index=i, score=float(det.score), failure=failure, timings_ms=dict(timings),
                        instance_id=det.instance_id, **fields)


def failed_results(detections: list[Detection], cfg: ReconstructConfig, reason: Failure) -> list[WindowResult]:
    """One WindowResult per detection, in order, each failed with ``reason`` (no stage reached):
    what a photo's output holds when its geometry failed as a whole."""
    return [_result(i, d, cfg, {}, reason) for i, d in enumerate(detections)]


@dataclass(frozen=True)
class QuadFit:
    """The mask -> quad stage of one detection, fitted once and reusable across configs.

    result: the :class:`~pipeline.quad.QuadResult`, or None when the detection's mask does not
    match the image shape (not fitted); ms: the measured fit time (ms), reported as the ``quad``
    timing of every WindowResult built from it.
    """

    result: QuadResult | None
    ms: float = 0.0


def fit_quads(detections: list[Detection], params: QuadParams = QuadParams(),
              image_shape: tuple[int, int] | None = None) -> list[QuadFit]:
    """Fit the quad of every detection (mask -> quad, or the predicted corners with
    ``params.source == "corners"`` where the detection has usable ones that agree with its mask:
    pipeline.quad.corners_agree_with_mask; with ``"network"`` as they are: :func:`network_quad`),
    in order, for
    :func:`reconstruct_from_quads`.

    image_shape: (H, W); a detection whose mask has another shape is not fitted (result None).
    """
    fits = []
    for det in detections:
        if image_shape is not None and mask_outside(det, image_shape):
            fits.append(QuadFit(None, 0.0))
            continue
        t0 = time.perf_counter()
        qr = corners_to_quad(det.corners) if params.source in ("corners", "network") else None
        if params.source == "network" and qr is not None and qr.quad is not None and image_shape is not None:
            qr = network_quad(qr, image_shape)
        elif qr is not None and qr.quad is not None and not corners_agree_with_mask(qr.quad, det.mask, det.origin):
            qr = None  # predicted corners that do not describe the mask: fall back to the mask fit
        if qr is None or qr.quad is None:  # the mask fit: the source, or the fallback
            qr = mask_to_quad(det.mask, params, _hint(det, det.origin)) if image_shape is None \
                else fit_sparse(det, params, image_shape)
        if params.source == "mask+corners" and qr.quad is None:
            qr = corner_fallback(det, qr)
        fits.append(QuadFit(qr, (time.perf_counter() - t0) * 1e3))
    return fits


def network_quad(qr: QuadResult, image_shape: tuple[int, int]) -> QuadResult:
    """A network's quad (quad source ``network``) as it is when its corners lie in the (H, W) image,
    else a ``touches_border`` failure: the session fits the visible part of a window cut by the
    photo's edge from its mask (visible_quads), as for every other quad source."""
    H, W = image_shape
    q = qr.quad
    if np.all((q[:, 0] >= -0.5) & (q[:, 0] <= W - 0.5) & (q[:, 1] >= -0.5) & (q[:, 1] <= H - 0.5)):
        return qr
    return QuadResult(None, None, 0.0,
                      Failure("quad", "touches_border", "the network's quad reaches past the photo's edge"))


def visible_quads(detections: list[Detection], fits: list[QuadFit], params: QuadParams,
                  image_shape: tuple[int, int]) -> dict[int, QuadResult]:
    """{detection index: the quad of its visible part} for every detection whose fit in ``fits``
    (:func:`fit_quads` with ``params``) failed with ``touches_border``: the mask fitted again with
    the image edge allowed as a side (``allow_border``, the mask as the source: predicted corners
    of a cut window are guesses beyond the photo); its ``cut`` names the image edges, its
    ``failure`` why even the visible part is no quadrilateral (a pentagon where an edge crosses a
    corner). image_shape: (H, W). Pure; the session caches it per detector and quad parameters."""
    border = replace(params, allow_border=True, source="mask")
    return {i: fit_sparse(det, border, image_shape) for i, (det, fit) in enumerate(zip(detections, fits))
            if fit.result is not None and getattr(fit.result.failure, "code", None) == "touches_border"}


def corner_fallback(det: Detection, failed: QuadResult) -> QuadResult:
    """The detection's predicted corners as its quad where the mask fit ``failed`` to find a
    quadrilateral (``not_quadrilateral``: a ragged or notched learned mask) and they describe the
    mask (pipeline.quad.corners_agree_with_mask); else ``failed`` as it is. Never for a mask cut by
    the image border or holding several blobs: there the window's own corners are not seen."""
    if failed.failure is None or failed.failure.code != "not_quadrilateral" or det.corners is None:
        return failed
    qr = corners_to_quad(det.corners)
    if qr.quad is None or not corners_agree_with_mask(qr.quad, det.mask, det.origin):
        return failed
    return qr


def _reaches_inner_edge(m: np.ndarray, origin: tuple[int, int], image_shape: tuple[int, int]) -> bool:
    """Whether an (h, w) mask crop at ``origin`` of an (H, W) image has a foreground pixel on one of
    its edges that is not an edge of the image (where a full mask would continue with background)."""
    (x0, y0), (h, w), (H, W) = origin, m.shape, image_shape
    edges = ((y0 > 0, m[0]), (y0 + h < H, m[-1]), (x0 > 0, m[:, 0]), (x0 + w < W, m[:, -1]))
    return any(inner and bool(np.any(line)) for inner, line in edges)


def mask_outside(det: Detection, image_shape: tuple[int, int]) -> str | None:
    """Why a detection's mask (full or a crop at ``det.origin``) does not lie in an (H, W) image."""
    (x0, y0), (h, w) = det.origin, np.asarray(det.mask).shape
    H, W = image_shape
    if x0 < 0 or y0 < 0 or x0 + w > W or y0 + h > H:
        return f"mask shape {(h, w)} at origin {(x0, y0)} != image {(H, W)}"
    return None


def _hint(det: Detection, origin: tuple[int, int]) -> np.ndarray | None:
    """The detection's predicted corners (4, 2) px moved to a mask whose pixel (0, 0) is at
    ``origin`` in the image, or None: mask_to_quad's hint."""
    return None if det.corners is None else np.asarray(det.corners, dtype=np.float64) - np.asarray(origin, dtype=np.float64)


def fit_sparse(det: Detection, params: QuadParams, image_shape: tuple[int, int]) -> QuadResult:
    """mask_to_quad of a detection whose mask is a crop at ``det.origin`` of an (H, W) image.

    The crop is padded by one background pixel where the image allows (what mask_to_quad's own
    crop of a full mask holds), so border checks and the fit are those of the full mask; the
    quad (4, 2) and lines (n_x, n_y, c) are moved to image coordinates. A crop whose mask
    reaches none of its own edges inside the image is fitted as it is (no padded copy: a
    full-width crop of a 150 Mpx photo is 150 MB).
    """
    m, (x0, y0) = np.asarray(det.mask), det.origin
    (h, w), (H, W) = m.shape, image_shape
    if (x0, y0, w, h) == (0, 0, W, H):
        return mask_to_quad(m, params, _hint(det, (0, 0)))
    if m.size and not _reaches_inner_edge(m, (x0, y0), image_shape):
        px, py = x0, y0
        qr = mask_to_quad(m, params, _hint(det, (px, py)))
    else:
        px, py = max(x0 - 1, 0), max(y0 - 1, 0)
        padded = np.zeros((min(y0 + h + 1, H) - py, min(x0 + w + 1, W) - px), dtype=bool)
        padded[y0 - py:y0 - py + h, x0 - px:x0 - px + w] = m != 0
        qr = mask_to_quad(padded, params, _hint(det, (px, py)))
    if qr.quad is None:
        return qr
    o = np.array([px, py], dtype=np.float64)
    lines = None if qr.lines is None else np.column_stack([qr.lines[:, :2], qr.lines[:, 2] + qr.lines[:, :2] @ o])
    return dataclasses.replace(qr, quad=qr.quad + o, lines=lines)


def reconstruct_one(i: int, gray: np.ndarray, K: np.ndarray | None, det: Detection,
                    cfg: ReconstructConfig, fit: QuadFit | None = None, memo: StepMemo | None = None) -> WindowResult:
    """Run quad -> snap -> aspect -> pose on one detection; failures go into the result.

    fit: the detection's already fitted quad (from :func:`fit_quads` with ``cfg.quad``), or None
    to fit it here. memo: the photo's pipeline.memo.StepMemo: the snapped quad and the aspect ratio
    kept under their inputs (the pose solvers of one snapper share them), or None.
    """
    timings: dict[str, float] = {}
    H, W = gray.shape
    outside = mask_outside(det, (H, W))
    if outside:
        return _result(i, det, cfg, timings, Failure("quad", None, outside))
    if fit is None or fit.result is None:
        fit = fit_quads([det], cfg.quad, (H, W))[0]
    qr = fit.result
    timings["quad"] = fit.ms
    if qr.failure is not None:
        return _result(i, det, cfg, timings, qr.failure)
    t0 = time.perf_counter()
    s = SNAPPERS[cfg.snapper]
    sp = cfg.snapper_params or s.params()
    if memo is None:
        snapped, _ = s.snap(gray, qr.quad, sp)
    else:  # the photo is the memo's: its snapped quads keyed by snapper, parameters and quad
        snapped = memo("snap", key(cfg.snapper, sp, qr.quad), lambda: s.snap(gray, qr.quad, sp)[0])
    timings["snap"] = (time.perf_counter() - t0) * 1e3
    done = dict(quad_mask=qr.quad, quad_snapped=snapped)
    t0 = time.perf_counter()
    try:
        pp = ((W - 1) / 2.0, (H - 1) / 2.0)

        def aspect():
            return aspect_ratio(snapped, K, principal_point=pp, fallback_focal_px=cfg.fallback_focal_px)

        ar = aspect() if memo is None else memo("aspect", key(snapped, K, pp, cfg.fallback_focal_px), aspect)
    except (PipelineError, ValueError) as e:
        timings["aspect"] = (time.perf_counter() - t0) * 1e3
        return _result(i, det, cfg, timings, Failure("aspect", None, str(e)), **done)
    timings["aspect"] = (time.perf_counter() - t0) * 1e3
    done.update(aspect_ratio=ar.ratio, aspect_case=ar.case,
                focal_estimate_px=ar.focal_px if ar.focal_source != "K" else None)
    if K is None:
        if ar.focal_px is None:
            return _result(i, det, cfg, timings, Failure("pose", None, "no K and no focal length (fronto-parallel quad); "
                                                                   "give K or fallback_focal_px"), **done)
        K_used = np.array([[ar.focal_px, 0.0, pp[0]], [0.0, ar.focal_px, pp[1]], [0.0, 0.0, 1.0]])
    else:
        K_used = K
    t0 = time.perf_counter()
    try:
        pr = estimate_pose(snapped, K_used, ar.ratio, cfg.height_m, cfg.width_m, POSES[cfg.pose].solver)
    except (PipelineError, ValueError) as e:
        timings["pose"] = (time.perf_counter() - t0) * 1e3
        return _result(i, det, cfg, timings, Failure("pose", None, str(e)), **done)
    timings["pose"] = (time.perf_counter() - t0) * 1e3
    return _result(i, det, cfg, timings, None, R=pr.R, t=pr.t, quad_reprojected=pr.reprojected,
                   height_m=pr.height_m, **done)


def reconstruct_from_quads(image: np.ndarray, K: np.ndarray | None, detections: list[Detection],
                           quads: list[QuadFit], cfg: ReconstructConfig = ReconstructConfig(),
                           base: list[WindowResult] | None = None,
                           segment_cache: SegmentCache | None = None,
                           memo: StepMemo | None = None) -> list[WindowResult]:
    """:func:`reconstruct` with the quads already fitted: ``quads = fit_quads(detections, cfg.quad,
    image_shape)``, one per detection, in order (so one fit serves every snapper x pose config).

    image: as for :func:`reconstruct`, or an (H, W) gray image (e.g. :func:`to_gray`'s, computed
    once). The ``quad`` timing of each result is the measured time of its (shared) fit.
    base: for a per-wall strategy, the per-window results it starts from, already computed with the
    same image, K, detections and quads and ``cfg`` with ``pose`` = the strategy's ``base_pose``
    (e.g. by a run of that per-window solver); they are used as they are, not recomputed.
    segment_cache: the photo's line segments (pipeline.segments.SegmentCache of this gray image),
    kept across the steps and configs that need them on this photo; None: a new one for this call.
    memo: the photo's pipeline.memo.StepMemo, kept across the configs run on it (their steps with
    identical inputs, e.g. the snapping and aspect ratio of the per-window solvers, computed once;
    the results are unchanged, the timings of a reused step are the lookup's); None: nothing kept
    across calls.
    """
    if len(quads) != len(detections):
        raise ValueError(f"{len(quads)} quads for {len(detections)} detections")
    gray = to_gray(image)
    K = None if K is None else check_K(K)
    wall = POSES[cfg.pose].wall
    if base is not None and (wall is None or len(base) != len(detections)):
        raise ValueError(f"base: {len(base)} per-window results given for pose {cfg.pose!r} and "
                         f"{len(detections)} detections; only a per-wall strategy takes them, one per detection")
    per_cfg = cfg if wall is None else replace(cfg, pose=wall.base_pose)
    results = list(base) if base is not None else [
        reconstruct_one(i, gray, K, d, per_cfg, q, memo) for i, (d, q) in enumerate(zip(detections, quads))]
    if wall is None:
        return results
    t0 = time.perf_counter()
    cache = SegmentCache(gray) if segment_cache is None else segment_cache
    results = apply_walls(results, K, gray.shape, cfg.height_m, cfg.width_m, wall, cache, memo)
    ms = (time.perf_counter() - t0) * 1e3 / max(len(results), 1)
    return [replace(r, timings_ms={**r.timings_ms, "wall": ms}) for r in results]


def reconstruct(image: np.ndarray, K: np.ndarray | None, detections: list[Detection],
                cfg: ReconstructConfig = ReconstructConfig(),
                segment_cache: SegmentCache | None = None) -> list[WindowResult]:
    """Reconstruct every detection in ``image`` ((H, W, 3) uint8 **RGB**, as fenestra.images.read_image gives).

    K: (3, 3) intrinsics, or None for an unknown focal length (square pixels, principal point at
    the image centre; f estimated per window by Zhang & He). Returns one WindowResult per
    detection, in order, with per-stage timings (ms) in ``timings_ms`` (quad, snap, aspect, pose).
    segment_cache: as for :func:`reconstruct_from_quads`.
    """
    gray = to_gray(image)
    return reconstruct_from_quads(gray, K, detections, fit_quads(detections, cfg.quad, gray.shape), cfg,
                                  segment_cache=segment_cache)


def _list(a: np.ndarray | None):
    return None if a is None else np.asarray(a, dtype=np.float64).tolist()


def window_to_dict(r: WindowResult, wall: int | None = None) -> dict:
    """One windows.json entry (DESIGN.md: Pipeline output); wall: the façade model's wall the
    window is on (pipeline.session.Window.wall), None without a façade model."""
    return {
        "index": r.index, "instance_id": r.instance_id, "score": r.score,
        "quad_mask": _list(r.quad_mask), "quad_snapped": _list(r.quad_snapped),
        "aspect_ratio": r.aspect_ratio, "aspect_case": None if r.aspect_case is None else r.aspect_case.value,
        "focal_estimate_px": r.focal_estimate_px,
        "R": _list(r.R), "t": _list(None if r.t is None else np.asarray(r.t).reshape(3)),
        "height_m": r.height_m,
        "width_m": None if r.aspect_ratio is None or r.R is None else r.aspect_ratio * r.height_m,
        "quad_reprojected": _list(r.quad_reprojected),
        "failure": None if r.failure is None else str(r.failure), "timings_ms": {k: round(v, 4) for k, v in r.timings_ms.items()},
        "wall": wall, "uncertainty": None if r.uncertainty is None else r.uncertainty.to_json(),
        "partial": r.partial is not None, "cut": [] if r.partial is None else list(r.partial.cut),
        "visible_fraction": None if r.partial is None else r.partial.visible_fraction,
    }


def windows_to_json(results: list[WindowResult], K: np.ndarray | None = None,
                    image_size: tuple[int, int] | None = None, config: ReconstructConfig | None = None,
                    walls: dict[int, int | None] | None = None) -> dict:
    """windows.json as a dict: ``{"K", "image_size": [W, H], "config", "windows": [...]}``;
    walls: {window index: the façade model's wall it is on} (None: no façade model)."""
    cfg = None
    if config is not None:
        cfg = {"snapper": config.snapper, "pose": config.pose, "height_m": config.height_m,
               "width_m": config.width_m, "fallback_focal_px": config.fallback_focal_px}
    return {"K": _list(K), "image_size": None if image_size is None else list(image_size),
            "config": cfg, "windows": [window_to_dict(r, (walls or {}).get(r.index)) for r in results]}
