"""One photo in, a façade out: the path behind ``fenestra reconstruct`` and its Python API.

    from fenestra.pipeline import reconstruct_photo
    res = reconstruct_photo("street.jpg")                 # a PhotoResult, nothing written
    res = reconstruct_photo("street.jpg", out="out/st")   # ... and windows.json, model.ifc, overlay.png, ...
    res.reconstruction    # typed: pipeline.session.Reconstruction (every window's stages, K, walls)
    res.export            # typed: what the writer wrote (ExportReport), None when nothing was written
    res.to_json()         # windows.json's data (a new dict)

Always an answer: the intrinsics come from a ranked chain (the user's K, EXIF, the façade's
vanishing points, a stated prior: pipeline.intrinsics), so the geometry always runs; a failure of
the geometry or of one window is recorded (``failure``), never raised, and the detections and the
overlay are written whatever happens. Only bad input raises (PipelineError: an unreadable photo,
both --K and --fx, a K file that does not fit the photo).
"""
from __future__ import annotations

import json
import numbers
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from fenestra.conventions import DEFAULTS
from fenestra.errors import PipelineError
from fenestra.masks import mask_extent
from fenestra.methods import Method
from fenestra.pipeline.export.geometry import WALL_THICKNESS_M
from fenestra.pipeline.facade_model import Known
from fenestra.pipeline.readout import PhotoReadout, WindowLine, readout, window_lines
from fenestra.pipeline.reconstruct import ReconstructConfig
from fenestra.pipeline.session import Reconstruction
from fenestra.pipeline.types import Detection, WindowResult
from fenestra.pipeline.catalogue import CATALOGUE
from fenestra.pipeline.detectors import DETECTORS
from fenestra.pipeline.quad import QUAD_SOURCES
from fenestra.pipeline.snappers import SNAPPERS
from fenestra.pipeline.io import Camera, K_from_values, fit_camera_to_photo, photo_orientation, read_camera
from fenestra.images import read_image, read_instances
from fenestra.pipeline.io import intrinsics_warnings, photo_warnings, undistort_photo
from fenestra.pipeline.outdir import check_out, staged_dir
from fenestra.pipeline.intrinsics import gps_from_exif, read_exif_tags


WALL_THICKNESS_RANGE_M = (0.01, 2.0)  # a curtain wall's 1 cm to a 2 m fortress wall: outside, a typo or a unit mistake


@dataclass(frozen=True)
class PhotoOptions:
    """How :func:`reconstruct_photo` runs: detector (without masks), snapper, pose, quad_source
    (registry names, defaults fenestra.conventions.DEFAULTS), known (what sets each wall's scale:
    pipeline.facade_model.Known; nothing known: an assumed window height, flagged), export_all
    (export the implausible windows too), substitute (catalogue style or None), export (write
    model.ifc/obj/glb besides windows.json and the overlay), max_pixels (the largest photo read,
    checked before decoding; None: fenestra.conventions.LIMITS.max_image_pixels), wall_thickness_m
    (the exported walls' thickness, m; a photo shows no wall's depth).

    Checked once, when built: a field that is not one of its choices or of its type raises an
    :class:`OptionError` (a PipelineError) naming it, its choices and the value given."""

    detector: str = DEFAULTS.detector
    snapper: str = DEFAULTS.snapper
    pose: str = DEFAULTS.pose
    quad_source: str = DEFAULTS.quad_source
    known: Known = Known()
    export_all: bool = False
    substitute: str | None = None
    export: bool = True
    max_pixels: int | None = None  # a larger photo is refused before decoding (None: LIMITS.max_image_pixels)
    wall_thickness_m: float = WALL_THICKNESS_M  # the exported walls' thickness (not measured: stated)

    def __post_init__(self) -> None:
        check_options(self)


class OptionError(PipelineError):
    """A PhotoOptions field that cannot be used: ``field`` (its name), ``why`` (what it must be)
    and ``value`` (what was given); the message is one line naming all three."""

    def __init__(self, field: str, why: str, value) -> None:
        self.field, self.why, self.value = field, why, value
        super().__init__(f"PhotoOptions: {field} {why}, got {value!r} ({type(value).__name__})")


def check_options(options: PhotoOptions) -> None:
    """:class:`OptionError` for the first field of ``options`` that is not one of its choices:
    detector, snapper, pose, quad_source (registry names), substitute (a catalogue style or
    None), known (a Known), export_all and export (bool), max_pixels (a positive int or None),
    wall_thickness_m (metres in WALL_THICKNESS_RANGE_M)."""

    from fenestra.pipeline.poses import POSES  # noqa: PLC0415 (fenestra.pipeline.poses loads SciPy: imported when first used)

    for field, registry in (("detector", DETECTORS), ("snapper", SNAPPERS), ("pose", POSES)):
        v = getattr(options, field)
        if not isinstance(v, str) or v not in registry:
            raise OptionError(field, f"must be one of {sorted(registry)}", v)
    if options.quad_source not in QUAD_SOURCES:
        raise OptionError("quad_source", f"must be one of {list(QUAD_SOURCES)}", options.quad_source)
    if options.substitute is not None and (not isinstance(options.substitute, str)
                                           or options.substitute not in CATALOGUE):
        raise OptionError("substitute", f"must be None or one of {sorted(CATALOGUE)}", options.substitute)
    if not isinstance(options.known, Known):
        raise OptionError("known", "must be a fenestra.pipeline.facade_model.Known", options.known)
    for field in ("export_all", "export"):
        if not isinstance(getattr(options, field), bool):
            raise OptionError(field, "must be True or False", getattr(options, field))
    mp = options.max_pixels
    if mp is not None and (isinstance(mp, bool) or not isinstance(mp, numbers.Integral) or mp <= 0):
        raise OptionError("max_pixels", "must be a positive int or None", mp)
    wt, (lo, hi) = options.wall_thickness_m, WALL_THICKNESS_RANGE_M
    if isinstance(wt, bool) or not isinstance(wt, numbers.Real) or not lo <= wt <= hi:
        raise OptionError("wall_thickness_m", f"must be a number of metres in {lo:g}-{hi:g}", wt)


@dataclass(frozen=True)
class ExportReport:
    """What the writer wrote for one photo (:func:`write_all`): files {kind: file name} (overlay,
    viewer, and with the models ifc, obj, mtl, glb, texture, inpainted, manifest[, substituted]);
    exported: the detection indices whose model was written; skipped: (index, reason) of the windows
    left out, in detection order; failure: None, or why writing the models failed ("Type: message",
    recorded, not raised: windows.json is still written); doors: the openings written as IfcDoor.
    :meth:`to_json` is windows.json's ``export``."""

    files: dict = field(default_factory=dict)
    exported: tuple[int, ...] = ()
    skipped: tuple[tuple[int, str], ...] = ()
    failure: str | None = None
    doors: tuple[int, ...] = ()  # the openings (Reconstruction.openings indices) written as IfcDoor

    def to_json(self) -> dict:
        return {"files": dict(self.files), "exported": list(self.exported),
                "skipped": [{"index": i, "reason": r} for i, r in self.skipped], "failure": self.failure,
                "doors": list(self.doors)}


@dataclass(frozen=True)
class PhotoResult:
    """What :func:`reconstruct_photo` gives: the typed reconstruction and, when files were
    written, the typed export report; :meth:`to_json` is windows.json's data, computed from them.

    reconstruction: pipeline.session.Reconstruction; image_size (W, H) px; warnings: the photo's
    and the intrinsics' (the focal chain's are added by to_json); photo: the photo's path; gps:
    its EXIF position (pipeline.intrinsics.gps_from_exif) or None; undistorted / distortion: the
    user's lens distortion removed, its coefficients; export_models: options.export (models are
    made: windows' ``exported`` is the decision, else None); export: the ExportReport, or None
    when nothing was written (``out`` None).
    """

    reconstruction: Reconstruction
    image_size: tuple[int, int]
    warnings: tuple[str, ...]
    photo: str
    gps: dict | None
    undistorted: bool
    distortion: list | None
    export_models: bool = True
    export: ExportReport | None = None

    def readout(self) -> PhotoReadout:
        """What a person reads of it, typed (pipeline.readout): the CLI, the batch summary, the
        overlay's header and the viewer read this."""
        return readout(self)

    def to_json(self) -> dict:
        """windows.json's data (a new dict): :func:`reconstruction_json` of the reconstruction, the
        photo's fields, and ``export`` when written (a window is ``exported`` when the decision
        keeps it and its model was written)."""
        written = None if self.export is None else set(self.export.exported)
        doc = reconstruction_json(self.reconstruction, self.image_size, list(self.warnings), self.export_models,
                                  written)
        doc.update(photo=self.photo, gps=self.gps, undistorted=self.undistorted, distortion=self.distortion)
        if self.export is not None:
            doc["export"] = self.export.to_json()
        return doc


def user_camera(photo: Path, size: tuple[int, int], K_json: Path | None, fx: float | None, fy: float | None,
                cx: float | None, cy: float | None):
    """(Camera or None, how it was given, warnings) from --K / --fx; PipelineError for both."""

    if K_json is not None and fx is not None:
        raise PipelineError("give either --K or --fx, not both")
    if K_json is not None:
        camera, warnings = fit_camera_to_photo(read_camera(K_json, size), size, photo_orientation(photo))
        return camera, f"--K {K_json}", warnings
    if fx is not None:
        return Camera(K=K_from_values(fx, fy, cx, cy, size)), "--fx", []
    return None, "", []


def method_of(options: PhotoOptions, masks: bool) -> Method:
    """The method a user runs: the options' detector (``oracle``, which reads the instance map,
    when ``--masks`` gives the masks), snapper, pose and quad source."""
    return Method("oracle" if masks else options.detector, options.snapper, options.pose,
                  quad_source=options.quad_source)


def photo_session(image: np.ndarray, exif: dict, camera=None, instances: np.ndarray | None = None):
    """The pipeline.session.PhotoSession :func:`reconstruct_photo` runs on a photo read: image (H,
    W, 3) uint8 RGB, its EXIF tags (pipeline.intrinsics.read_exif_tags), the user's camera
    (pipeline.session.UserCamera) or None, an (H, W) instance map (``--masks``: the ``oracle``
    detector reads its crops) or None."""
    from fenestra.pipeline.session import PhotoSession  # noqa: PLC0415 (fenestra.pipeline.session loads SciPy: imported when first used)

    return PhotoSession(image, camera=camera, exif=exif, instances=instances,
                        detector_options={"oracle": {"sparse": True}})  # --masks: crops


def run_options(session, options: PhotoOptions) -> Reconstruction:
    """The user's method (:func:`method_of`: the oracle when the session holds an instance map)
    run on ``session`` with the options' known sizes, export_all and substitute style."""
    return session.run(method_of(options, session.instances is not None), options.known, options.export_all,
                       options.substitute)


def _is_path(v) -> bool:

    return isinstance(v, (str, os.PathLike)) and str(v) != ""


def check_arguments(photo, out, K_json, fx, fy, cx, cy, masks, options, force) -> None:
    """PipelineError, one line naming the argument, for what :func:`reconstruct_photo` cannot take:
    paths that are not str/PathLike (photo, K_json and masks must be existing regular files), focal
    values and principal point that are not finite real numbers (fx, fy > 0), options that are not
    a PhotoOptions (whose fields were checked when it was built: :func:`check_options`), a force
    that is not bool. Checked before anything is read or written."""

    def bad(name: str, why: str, v) -> PipelineError:
        return PipelineError(f"reconstruct_photo: {name} {why}, got {v!r} ({type(v).__name__})")

    for name, v, optional in (("photo", photo, False), ("K_json", K_json, True), ("masks", masks, True)):
        if v is None and optional:
            continue
        if not _is_path(v):
            raise bad(name, "must be a path (str or os.PathLike)", v)
        if not Path(v).is_file():
            raise bad(name, "must be an existing regular file" + (" (not found)" if not Path(v).exists() else ""), v)
    if out is not None and not _is_path(out):
        raise bad("out", "must be a folder path (str or os.PathLike) or None", out)
    for name, v in (("fx", fx), ("fy", fy), ("cx", cx), ("cy", cy)):
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not np.isfinite(float(v)):
            raise bad(name, "must be a finite number (px) or None", v)
        if name in ("fx", "fy") and v <= 0:
            raise bad(name, "must be positive (px)", v)
    if not isinstance(force, bool):
        raise bad("force", "must be True or False", force)
    if not isinstance(options, PhotoOptions):
        raise bad("options", "must be a fenestra.pipeline.photo.PhotoOptions", options)


def reconstruct_photo(photo: str | Path, out: str | Path | None = None, *, K_json: str | Path | None = None,
                      fx: float | None = None, fy: float | None = None, cx: float | None = None,
                      cy: float | None = None, masks: str | Path | None = None,
                      options: PhotoOptions | None = None, force: bool = False) -> PhotoResult:
    """Reconstruct the windows of one photo; return the typed :class:`PhotoResult` (its
    ``to_json()``: the windows.json data).

    photo: any image file OpenCV reads (EXIF orientation applied). out: a folder to write
    windows.json, overlay.png, index.html (a page showing them: pipeline.export.viewer) and
    (options.export) model.ifc, model.obj/.mtl, model.glb, texture.png, export.json into (written
    whole or not at all: pipeline.outdir; ``force`` replaces a non-empty
    folder that is not an output), or None to write nothing. K_json / fx, fy, cx, cy: the user's
    intrinsics (at most one of K_json and fx); without them the focal chain of
    pipeline.intrinsics.resolve_K decides. masks: an instance-map PNG (16-bit ids, 0 = none)
    instead of the detector. options: a PhotoOptions (None: the defaults, ``PhotoOptions()``).

    The work is :meth:`fenestra.pipeline.session.PhotoSession.run` (what the bench runs too);
    this reads the inputs, runs it, and writes the files (:func:`write_all`). windows.json's data
    (:meth:`PhotoResult.to_json`): ``K``, ``K_source`` (source, focal_px, interval_px, candidates,
    unavailable, detail), ``image_size`` [W, H], ``config``, ``windows`` (one per detection,
    failures included), ``warnings``, ``geometry_failure`` (None, or why the geometry failed as a
    whole), ``undistorted``, ``distortion``, ``export`` (what was exported or skipped, when
    written). Raises PipelineError only for bad input: one line naming the argument for a bad
    argument (:func:`check_arguments`, before anything is read), naming the file for a bad K file;
    a photo or instance map that cannot be decoded is a fenestra.errors.DatasetError (the file
    named). Both are FenestraError.
    """
    from fenestra.pipeline.session import UserCamera  # noqa: PLC0415 (fenestra.pipeline.session loads SciPy: imported when first used)

    options = PhotoOptions() if options is None else options
    check_arguments(photo, out, K_json, fx, fy, cx, cy, masks, options, force)  # PipelineError naming the argument
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
    instances = None if masks is None else read_instances(Path(masks), size, "--masks instance map")

    session = photo_session(image, read_exif_tags(photo), None if camera is None else UserCamera(camera.K, how),
                            instances)
    rec = run_options(session, options)
    del session, instances  # export needs neither the gray copies nor the instance map (a 100 Mpx photo: 0.5 GB each)

    result = PhotoResult(rec, size, tuple(warnings + intrinsics_warnings(rec.K, size)), str(photo), gps_from_exif(photo),
                         bool(camera is not None and camera.has_distortion),
                         None if camera is None or camera.distortion is None else camera.distortion.tolist(),
                         options.export)
    if out is not None:
        with staged_dir(Path(out), force, inputs) as tmp:
            result = replace(result, export=write_all(tmp, image, result, options))
            (tmp / "windows.json").write_text(json.dumps(result.to_json(), indent=2))
    return result


def row_fields(r: WindowResult, measured: WindowResult | None, fit) -> dict:
    """windows.json's row regularization fields of window ``r`` (pipeline.row_lines): ``regularized``
    (its sill and head are its row's consensus), ``row`` (the RowFit of the row it voted in, or
    None), ``height_measured_m`` (its height as measured; None without a pose) and ``measured``
    (when regularized: the measured ``aspect_ratio``, ``height_m``, ``width_m``, ``t``,
    ``quad_reprojected``; else None: the window's own fields are the measured ones)."""
    m = measured if measured is not None else r
    return {"regularized": measured is not None, "row": None if fit is None else fit.to_json(),
            "height_measured_m": None if m.failure is not None or m.R is None else float(m.height_m),
            "measured": None if measured is None else {
                "aspect_ratio": float(m.aspect_ratio), "height_m": float(m.height_m),
                "width_m": float(m.aspect_ratio) * float(m.height_m), "t": np.asarray(m.t).reshape(3).tolist(),
                "quad_reprojected": None if m.quad_reprojected is None else np.asarray(m.quad_reprojected).tolist()}}


def reconstruction_json(rec: Reconstruction, image_size: tuple[int, int], warnings: list[str], export: bool = True,
                        written: set[int] | None = None) -> dict:
    """windows.json's data of a pipeline.session.Reconstruction (a new dict; pure): ``K``,
    ``K_source``, ``image_size``, ``config``, ``walls``, ``scale``, ``windows`` (per window its
    stage results as the model holds it plus ``failure_message`` (the failure in the user's
    words: pipeline.messages), ``plausible``, ``flags``, ``scale_source``,
    ``scale_assumed``, ``K_source``, ``aspect_interval`` (of the measured window), ``confidence``,
    the row regularization's fields (:func:`row_fields`), ``exported``: the export decision (and,
    with ``written`` the indices whose model was written, only those), None when no model is made
    (``export`` False), ``not_exported``: why not; ``partial`` and ``cut``: a window cut by the
    photo's edges, its fields those of its visible part), ``openings`` (the detections the box
    verifier calls no window, each with its ``kind``, door or signboard: pipeline.doors.Opening),
    ``warnings`` (the photo's, the focal
    chain's), ``geometry_failure``."""
    from fenestra.pipeline.reconstruct import windows_to_json  # noqa: PLC0415 (fenestra.pipeline.reconstruct loads SciPy: imported when first used)

    model = rec.model
    doc = windows_to_json(rec.results(), K=rec.K, image_size=image_size, config=ReconstructConfig.of(rec.method),
                          walls={w.index: w.wall for w in rec.windows})
    assumed = [w.id for w in model.walls if w.assumed]
    windows = []
    for win, w, line in zip(rec.windows, doc["windows"], window_lines(rec, export, written)):
        windows.append({**w, "failure_message": line.failure_message, "plausible": line.plausible,
                        "flags": list(line.flags), "confidence": line.confidence,
                        "K_source": line.K_source, "exported": line.exported, "not_exported": line.not_exported,
                        "aspect_interval": None if line.aspect_interval is None else list(line.aspect_interval),
                        "scale_source": line.scale_source, "scale_assumed": line.scale_assumed,
                        **row_fields(win.result, win.measured if win.regularized is not None else None, win.row)})
    return {**doc, "windows": windows, "openings": [o.to_json() for o in rec.openings],
            "walls": [w.to_json() for w in model.walls],
            "scale": {"assumed": bool(assumed), "assumed_walls": assumed,
                      "sources": sorted({w.scale_source for w in model.walls})},
            "K_source": rec.resolved.to_json(),
            "geometry_failure": None if rec.geometry_failure is None else rec.geometry_failure.reason,
            "warnings": [*warnings, *rec.resolved.warnings]}


def wall_ids(rec: Reconstruction) -> dict[int, int]:
    """{window index: the id of the façade model's wall it is on} (members and partial windows):
    the writers' ``walls``, one IfcWall per wall."""
    return {k: w.id for w in rec.model.walls for k in w.windows}


def written_model(rec: Reconstruction, substitute: str | None = None):
    """The model :func:`write_all` writes for ``rec`` (pipeline.export.WrittenModel: the exported
    windows and doors upright and grounded, the export world's vertical, the rows and the floors), as a value,
    nothing written; substitute: the catalogue style ``rec``'s run was given (None: the default;
    its export decision, Window.export, is the model's: not made again)."""
    from fenestra.pipeline.export import DEFAULT_STYLE, written_model as model_of  # noqa: PLC0415 (fenestra.pipeline.export loads IfcOpenShell: imported when first used)

    return model_of(rec.results(), substitute or DEFAULT_STYLE, rec.not_exported, wall_ids(rec), decided=True,
                    doors=[o.placed for o in rec.openings if o.exported])


def write_all(out: Path, image: np.ndarray, result: PhotoResult, options: PhotoOptions) -> ExportReport:
    """The overlay always, then (options.export) the models of ``result``'s reconstruction, then
    index.html (pipeline.export.viewer: the overlay, the GLB in 3D or why there is none, the window
    table); returns the :class:`ExportReport`: an export that fails is recorded, not raised
    (windows.json is still written by the caller). The writers follow the reconstruction's export
    decision (``Window.export``): the windows it keeps out are the writers' ``exclude``."""
    from fenestra.pipeline.export import write_outputs, write_overlay  # noqa: PLC0415 (fenestra.pipeline.export loads IfcOpenShell: imported when first used)
    from fenestra.pipeline.export.viewer import write_viewer  # noqa: PLC0415 (fenestra.pipeline.export.viewer loads IfcOpenShell: imported when first used)

    rec = result.reconstruction
    model, results, decided = rec.model, rec.results(), rec.not_exported
    read = result.readout()  # before writing: the IFC properties, the overlay's header
    files, exported, skipped, failure, doors = {}, (), (), None, ()
    if options.export:
        placed_doors = [o for o in rec.openings if o.exported]
        try:
            paths = write_outputs(out, image, rec.K, results, substitute=options.substitute, exclude=decided,
                                  walls=wall_ids(rec),
                                  properties={w.index: window_properties(w) for w in read.windows},
                                  wall_properties={w.id: wall_properties(w) for w in model.walls}, overlay=False,
                                  gps=gps_tuple(result.gps), thickness_m=options.wall_thickness_m,
                                  source=Path(result.photo).name, doors=[o.placed for o in placed_doors],
                                  door_walls={o.index: o.wall for o in placed_doors},
                                  door_properties={o.index: door_properties(o, rec) for o in placed_doors})
        except (PipelineError, ValueError, OSError) as e:
            failure = f"{type(e).__name__}: {e}"
        else:
            files = {k: p.name for k, p in paths.items()}
            exported = tuple(w.index for w in rec.windows if w.export.exported)
            skipped = tuple((w.index, w.export.reason) for w in rec.windows if not w.export.exported)
            doors = tuple(o.index for o in placed_doors)
    files["overlay"] = write_overlay(out, image, rec.K, results, decided, boxes=detection_boxes(list(rec.detections)),
                                     header=read.header()).name
    report = ExportReport(files, exported, skipped, failure, doors)
    viewer = write_viewer(out, replace(result, export=report).readout(), dict(files)).name  # index.html
    return replace(report, files={**files, "viewer": viewer})


def gps_tuple(gps: dict | None) -> tuple | None:
    """windows.json's ``gps`` (from the photo's EXIF) as export's (latitude deg, longitude deg,
    altitude m[, heading deg]) (altitude 0 when unknown)."""
    if not gps:
        return None
    alt, heading = gps.get("altitude_m"), gps.get("heading_deg")
    return (gps["latitude_deg"], gps["longitude_deg"], alt or 0.0) + (() if heading is None else (heading,))


def detection_boxes(detections: list[Detection]) -> dict[int, tuple[int, int, int, int]]:
    """{index: (x0, y0, x1, y1) px} of each detection's mask (full image coordinates)."""
    boxes = {}
    for i, d in enumerate(detections):
        extent = mask_extent(d.mask)
        if extent is not None:
            (ox, oy), (x0, y0, x1, y1) = d.origin, extent
            boxes[i] = (x0 + ox, y0 + oy, x1 + ox, y1 + oy)
    return boxes


def wall_properties(w) -> dict:
    """The Fenestra property set of one fitted wall (IFC)."""
    return {"ScaleSource": w.scale_source, "ScaleAssumed": bool(w.assumed), "DistanceM": float(w.distance_m),
            "WindowCount": len(w.windows)}


def door_properties(o, rec: Reconstruction) -> dict:
    """The Fenestra property set of one door (IFC): the detection's score, the verifier's class,
    the wall it is on and its scale source, and whether the photo's bottom edge cuts it (its foot
    then put on its floor)."""
    wall = next(w for w in rec.model.walls if w.id == o.wall)
    return {"DetectionScore": float(o.score), "Class": "door (box verifier)", "Wall": int(o.wall),
            "ScaleSource": wall.scale_source, "ScaleAssumed": bool(wall.assumed),
            "CutByBottomEdge": o.placed.partial is not None}


def window_properties(w: WindowLine) -> dict:
    """The Fenestra property set of one window (IFC): confidence, aspect interval, K and scale
    sources, and whether it is partial (cut by the photo's border: Partial, CutBy the edges, e.g.
    "left" or "top, left", VisibleFraction the share of its area in the photo; its size is its
    row's or column's whole windows')."""
    lo, hi = w.aspect_interval or (None, None)
    return {"Confidence": w.confidence, "DetectionScore": w.score, "AspectRatio": w.aspect_ratio,
            "AspectLow": lo, "AspectHigh": hi, "KSource": w.K_source, "ScaleSource": w.scale_source,
            "ScaleAssumed": w.scale_assumed, "Plausible": w.plausible, "Flags": "; ".join(w.flags) or None,
            "Partial": w.partial, "CutBy": ", ".join(w.cut) or None, "VisibleFraction": w.visible_fraction}
