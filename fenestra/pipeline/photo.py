"""One photo in, a façade out: the path behind ``fenestra reconstruct`` and its Python API.

    from fenestra.pipeline import reconstruct_photo
    doc = reconstruct_photo("street.jpg")                 # the windows.json data, nothing written
    doc = reconstruct_photo("street.jpg", out="out/st")   # ... and windows.json, model.ifc, overlay.png, ...

Always an answer: the intrinsics come from a ranked chain (the user's K, EXIF, the façade's
vanishing points, a stated prior: pipeline.intrinsics), so the geometry always runs; a failure of
the geometry or of one window is recorded (``failure``), never raised, and the detections and the
overlay are written whatever happens. Only bad input raises (PipelineError: an unreadable photo,
both --K and --fx, a K file that does not fit the photo).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from fenestra.conventions import DEFAULTS
from fenestra.errors import PipelineError
from fenestra.pipeline.facade_model import FacadeModel, Known, facade_model
from fenestra.pipeline.quad import QuadParams
from fenestra.pipeline.reconstruct import (ReconstructConfig, failed_results, fit_quads, reconstruct_from_quads, to_gray,
                                  windows_to_json)
from fenestra.pipeline.segments import SegmentCache, to_uint8
from fenestra.pipeline.types import Detection


@dataclass(frozen=True)
class PhotoOptions:
    """How :func:`reconstruct_photo` runs: detector (without masks), snapper, pose, quad_source
    (registry names, defaults fenestra.conventions.DEFAULTS), known (what sets each wall's scale:
    pipeline.facade_model.Known; nothing known: an assumed window height, flagged), export_all
    (export the implausible windows too), substitute (catalogue style or None), export (write
    model.ifc/obj/glb besides windows.json and the overlay), max_pixels (the largest photo read,
    checked before decoding; None: fenestra.conventions.LIMITS.max_image_pixels)."""

    detector: str = DEFAULTS.detector
    snapper: str = DEFAULTS.snapper
    pose: str = DEFAULTS.pose
    quad_source: str = DEFAULTS.quad_source
    known: Known = Known()
    export_all: bool = False
    substitute: str | None = None
    export: bool = True
    max_pixels: int | None = None  # a larger photo is refused before decoding (None: LIMITS.max_image_pixels)

    def config(self) -> ReconstructConfig:
        return ReconstructConfig(snapper=self.snapper, pose=self.pose, quad=QuadParams(source=self.quad_source))


def user_camera(photo: Path, size: tuple[int, int], K_json: Path | None, fx: float | None, fy: float | None,
                cx: float | None, cy: float | None):
    """(Camera or None, how it was given, warnings) from --K / --fx; PipelineError for both."""
    from fenestra.pipeline.io import Camera, K_from_values, fit_camera_to_photo, photo_orientation, read_camera  # noqa: PLC0415

    if K_json is not None and fx is not None:
        raise PipelineError("give either --K or --fx, not both")
    if K_json is not None:
        camera, warnings = fit_camera_to_photo(read_camera(K_json, size), size, photo_orientation(photo))
        return camera, f"--K {K_json}", warnings
    if fx is not None:
        return Camera(K=K_from_values(fx, fy, cx, cy, size)), "--fx", []
    return None, "", []


def window_quads(gray: np.ndarray, detections: list[Detection], cfg: ReconstructConfig) -> np.ndarray:
    """Snapped quads (N, 4, 2) px of the detections, found without K (per-window pass with the pose
    strategy's own per-window solver and a provisional focal length of the long side; only the
    snapped corners are used: they do not depend on the pose)."""
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415

    H, W = gray.shape
    per = reconstruct_from_quads(gray, None, detections, fit_quads(detections, cfg.quad, gray.shape),
                                 replace(cfg, pose=POSES[cfg.pose].per_window_pose,
                                         fallback_focal_px=float(max(H, W))))
    return np.array([r.quad_snapped for r in per if r.quad_snapped is not None]).reshape(-1, 4, 2)


def resolve_intrinsics(photo: Path, gray: np.ndarray, detections: list[Detection], cfg: ReconstructConfig,
                       segment_cache: SegmentCache, user=None, user_how: str = ""):
    """pipeline.intrinsics.ResolvedK for the photo: the user's K first when given (compared with
    EXIF), else EXIF, vanishing points (the chosen per-wall strategy's, with its façade lines), prior."""
    from fenestra.pipeline.intrinsics import choose_focal, exif_focal, resolve_K, user_focal  # noqa: PLC0415
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415

    H, W = gray.shape
    if user is not None:
        exif = exif_focal(photo, (W, H))
        return choose_focal([user_focal(user.K, user_how), exif if exif is not None else "no EXIF focal length"],
                            ["K", "exif"], (W, H), principal_point=(float(user.K[0, 2]), float(user.K[1, 2])))
    quads = window_quads(gray, detections, cfg)
    return resolve_K(photo, quads, (W, H), POSES[cfg.pose].wall, segment_cache)


def reconstruct_photo(photo: str | Path, out: str | Path | None = None, *, K_json: str | Path | None = None,
                      fx: float | None = None, fy: float | None = None, cx: float | None = None,
                      cy: float | None = None, masks: str | Path | None = None,
                      options: PhotoOptions = PhotoOptions(), force: bool = False) -> dict:
    """Reconstruct the windows of one photo; return the windows.json data (a dict).

    photo: any image file OpenCV reads (EXIF orientation applied). out: a folder to write
    windows.json, overlay.png and (options.export) model.ifc, model.obj/.mtl, model.glb, texture.png,
    export.json into (written whole or not at all: pipeline.outdir; ``force`` replaces a non-empty
    folder that is not an output), or None to write nothing. K_json / fx, fy, cx, cy: the user's
    intrinsics (at most one of K_json and fx); without them the focal chain of
    pipeline.intrinsics.resolve_K decides. masks: an instance-map PNG (16-bit ids, 0 = none)
    instead of the detector.

    The dict: ``K``, ``K_source`` (source, focal_px, interval_px, candidates, unavailable, detail),
    ``image_size`` [W, H], ``config``, ``windows`` (one per detection, failures included),
    ``warnings``, ``geometry_failure`` (None, or why the geometry failed as a whole),
    ``undistorted``, ``distortion``, ``export`` (what was exported or skipped, when written).
    Raises PipelineError only for bad input.
    """
    from fenestra.images import read_image  # noqa: PLC0415
    from fenestra.pipeline.io import intrinsics_warnings, photo_warnings, undistort_photo  # noqa: PLC0415
    from fenestra.pipeline.outdir import check_out, staged_dir  # noqa: PLC0415

    photo = Path(photo)
    inputs = (photo, K_json, masks)  # never inside out: replacing it would delete them
    if out is not None:
        check_out(Path(out), force, inputs)  # before the (slow) pipeline runs
    image = read_image(photo, "photo", options.max_pixels)
    size = (image.shape[1], image.shape[0])
    camera, how, warnings = user_camera(photo, size, None if K_json is None else Path(K_json), fx, fy, cx, cy)
    warnings = photo_warnings(photo) + warnings
    if camera is not None:
        image = undistort_photo(image, camera)  # masks are taken to be in this frame
    cfg = options.config()
    detections = detect_windows(image, size, masks, options.detector)
    gray = to_gray(image)
    segment_cache = SegmentCache(to_uint8(gray))  # the photo's line segments, found once for all steps
    resolved = resolve_intrinsics(photo, gray, detections, cfg, segment_cache, camera, how)
    K = resolved.K
    warnings += list(resolved.warnings) + intrinsics_warnings(K, size)
    geometry_failure, envelope = None, {}
    try:
        results = reconstruct_from_quads(gray, K, detections, fit_quads(detections, cfg.quad, gray.shape), cfg,
                                         segment_cache=segment_cache)
        envelope = focal_envelope(results, K, resolved.chosen.interval_px)
    except PipelineError as e:  # recorded: the detections are still written, each with this failure
        geometry_failure = str(e)
        results = failed_results(detections, cfg, f"geometry: {e}")
    del gray, segment_cache  # export needs neither: a 100 Mpx photo's gray copies are 0.5 GB
    results, model = facade_model(results, options.known)
    doc = windows_to_json(results, K=K, image_size=size, config=cfg)
    annotate(doc, model, resolved.source, envelope)
    doc.update(photo=str(photo), K_source=resolved.to_json(), geometry_failure=geometry_failure,
               undistorted=bool(camera is not None and camera.has_distortion),
               distortion=None if camera is None or camera.distortion is None else camera.distortion.tolist(),
               warnings=warnings)
    if out is not None:
        with staged_dir(Path(out), force, inputs) as tmp:
            doc["export"] = write_all(tmp, image, K, results, options, model, doc, detections)
            (tmp / "windows.json").write_text(json.dumps(doc, indent=2))
    return doc


def detect_windows(image: np.ndarray, size: tuple[int, int], masks: str | Path | None, detector: str) -> list[Detection]:
    """Detections from an instance-map PNG (``masks``) or the detector ``detector`` on ``image``."""
    if masks is not None:
        from fenestra.pipeline.detectors.oracle import detections_from_instance_map  # noqa: PLC0415
        from fenestra.images import read_instances  # noqa: PLC0415

        return detections_from_instance_map(read_instances(Path(masks), size, "--masks instance map"))
    from fenestra.pipeline.detectors import detect  # noqa: PLC0415

    return detect(detector, image)


def focal_envelope(results: list, K: np.ndarray, interval_px: tuple[float, float]) -> dict[int, tuple[float, float]]:
    """{window index: (min, max) aspect ratio} when the focal length moves to the ends of its
    interval: each posed window's aspect ratio plus the change of its quad's closed-form aspect
    ratio (pipeline.aspect.aspect_ratio, Zhang & He with K) from K's focal length to each end (ms
    per window, no refit). {} when the interval is a single value (the user's K)."""
    from fenestra.pipeline.aspect import AspectError, aspect_ratio  # noqa: PLC0415

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


def aspect_interval(w: dict, envelope: dict[int, tuple[float, float]]) -> list[float] | None:
    """A window's aspect interval: its fit's 90 % interval (widened when flagged) joined with its
    aspect ratios at the ends of the focal interval (:func:`focal_envelope`); None for a failed window."""
    if w["failure"] is not None or w["aspect_ratio"] is None:
        return None
    unc = w["uncertainty"] or {}
    vals = [w["aspect_ratio"], *(unc[k] for k in ("aspect_lo", "aspect_hi") if k in unc),
            *envelope.get(w["index"], ())]
    return [float(min(vals)), float(max(vals))]


def annotate(doc: dict, model: FacadeModel, K_source: str, envelope: dict[int, tuple[float, float]]) -> None:
    """Add the façade model to windows.json: ``walls``, ``scale`` and per window ``plausible``,
    ``flags`` (reasons), ``scale_source``, ``scale_assumed``, ``K_source``, ``aspect_interval``
    (:func:`aspect_interval`) and ``confidence`` (detector score, halved when ill-conditioned,
    quartered when flagged; 0 for a failed window)."""
    doc["walls"] = [w.to_json() for w in model.walls]
    assumed = [w.id for w in model.walls if w.assumed]
    doc["scale"] = {"assumed": bool(assumed), "assumed_walls": assumed,
                    "sources": sorted({w.scale_source for w in model.walls})}
    for w in doc["windows"]:
        i = w["index"]
        wall = model.wall_of(i)
        flags = model.flags.get(i, [])
        ill = bool(w["uncertainty"] and w["uncertainty"].get("ill_conditioned"))
        conf = 0.0 if w["failure"] else w["score"] * (0.5 if ill else 1.0) * (0.25 if flags else 1.0)
        w.update(plausible=w["failure"] is None and not flags, flags=flags, confidence=conf, K_source=K_source,
                 exported=None, aspect_interval=aspect_interval(w, envelope),
                 scale_source=None if wall is None else wall.scale_source,
                 scale_assumed=None if wall is None else wall.assumed)


def write_all(out: Path, image: np.ndarray, K: np.ndarray, results: list, options: PhotoOptions,
              model: FacadeModel, doc: dict, detections: list[Detection]) -> dict:
    """The overlay always, then (options.export) the models; returns {"files", "exported", "skipped",
    "failure"}: an export that fails is recorded, not raised (windows.json is still written by the
    caller). Flagged windows are skipped unless options.export_all; with options.export each
    window of ``doc`` gets ``exported`` (bool; None when no model is written)."""
    from fenestra.pipeline.export import write_outputs, write_overlay  # noqa: PLC0415

    exclude = {} if options.export_all else {k: "implausible: " + "; ".join(v) for k, v in model.flags.items()}
    report = {"files": {}, "exported": [], "skipped": [], "failure": None}
    if options.export:
        info = {w["index"]: w for w in doc["windows"]}
        try:
            paths = write_outputs(out, image, K, results, substitute=options.substitute, exclude=exclude,
                                  walls={k: w.id for w in model.walls for k in w.members},
                                  properties={k: window_properties(info[k]) for k in info},
                                  wall_properties={w.id: wall_properties(w) for w in model.walls}, overlay=False)
        except (PipelineError, ValueError, OSError) as e:
            report["failure"] = f"{type(e).__name__}: {e}"
        else:
            manifest = json.loads(paths["manifest"].read_text())
            report.update(files={k: p.name for k, p in paths.items()},
                          exported=[e["index"] for e in manifest["exported"]], skipped=manifest["skipped"])
    reasons = {**exclude, **{e["index"]: e["reason"] for e in report["skipped"]}}
    report["files"]["overlay"] = write_overlay(out, image, K, results, reasons, boxes=detection_boxes(detections),
                                               header=overlay_header(doc)).name
    if options.export:
        for w in doc["windows"]:
            w["exported"] = w["index"] in report["exported"]
    return report


def detection_boxes(detections: list[Detection]) -> dict[int, tuple[int, int, int, int]]:
    """{index: (x0, y0, x1, y1) px} of each detection's mask (full image coordinates)."""
    boxes = {}
    for i, d in enumerate(detections):
        ys, xs = np.nonzero(np.asarray(d.mask))
        if len(xs):
            x0, y0 = d.origin
            boxes[i] = (int(xs.min() + x0), int(ys.min() + y0), int(xs.max() + x0), int(ys.max() + y0))
    return boxes


def overlay_header(doc: dict) -> list[str]:
    """The overlay panel's header: intrinsics and scale, one line each."""
    ks = doc["K_source"]
    lines = [f"K: {ks['source']}, f = {ks['focal_px']:.0f} px [{ks['interval_px'][0]:.0f}, {ks['interval_px'][1]:.0f}]",
             "scale: " + ("; ".join(doc["scale"]["sources"]) or "none")]
    if doc.get("geometry_failure"):
        lines.append(f"geometry failed: {doc['geometry_failure']}")
    return lines


def wall_properties(w) -> dict:
    """The Fenestra property set of one fitted wall (IFC)."""
    return {"ScaleSource": w.scale_source, "ScaleAssumed": bool(w.assumed), "DistanceM": float(w.distance_m),
            "WindowCount": len(w.members)}


def window_properties(w: dict) -> dict:
    """The Fenestra property set of one window (IFC): confidence, aspect interval, K and scale sources."""
    lo, hi = w["aspect_interval"] or (None, None)
    return {"Confidence": float(w["confidence"]), "DetectionScore": float(w["score"]),
            "AspectRatio": w["aspect_ratio"], "AspectLow": lo, "AspectHigh": hi,
            "KSource": w["K_source"], "ScaleSource": w["scale_source"], "ScaleAssumed": w["scale_assumed"],
            "Plausible": bool(w["plausible"]), "Flags": "; ".join(w["flags"]) or None}
