"""CLI commands of pipeline/ (registered on the `fenestra` app by fenestra/app/cli.py).

    fenestra reconstruct PHOTO|FOLDER|'GLOB'... [--K K.json | --fx F [--fy --cx --cy]] [--masks MASKS.png]
        [--detector NAME] [--snapper NAME] [--pose NAME] [--known-height M | --known-width M |
        --known-storey M] [--export-all] [--substitute STYLE] --out DIR
    fenestra calibrate PHOTOS... --pattern COLSxROWS [--square M] --out K.json

Without --K/--fx the intrinsics come from the photo (pipeline.intrinsics.resolve_K: EXIF, else the
façade's vanishing points, else a stated prior); windows.json records ``K`` and ``K_source`` (with
the focal interval and every source's value). The photo path itself is pipeline.photo.

writes DIR/windows.json and, through pipeline.export, model.ifc, model.obj, overlay.png, ...
When K.json carries lens distortion (``"distortion": [k1, k2, p1, p2, k3]``, OpenCV), the photo is
undistorted with the same K first (cv2.undistort) and everything downstream (masks, quads, the
overlay and the texture) lives in that undistorted image; windows.json says ``"undistorted": true``.
"""
from __future__ import annotations

import csv
import glob
import io
import json
import re
import sys
import time
from pathlib import Path
from typing import Optional

import numpy as np
import typer
from typer.core import TyperCommand

from fenestra.conventions import DEFAULTS, LIMITS
from fenestra.errors import FenestraError, PipelineError
from fenestra.pipeline.facade_model import DEFAULT_WINDOW_HEIGHT_M, KNOWN_RANGE_M as FIELD_RANGE_M, Known
from fenestra.pipeline.export.geometry import WALL_THICKNESS_M
from fenestra.pipeline.photo import WALL_THICKNESS_RANGE_M, OptionError, PhotoOptions, PhotoResult, reconstruct_photo
from fenestra.pipeline.readout import PhotoReadout
from fenestra.pipeline.quad import QUAD_SOURCES
from fenestra.pipeline.reconstruct import POSES
from fenestra.pipeline.snappers import SNAPPERS
from fenestra.pipeline.outdir import held_out
from fenestra.pipeline.catalogue import get_style
from fenestra import outputs
from fenestra.pipeline.intrinsics import calibrate_chessboard, calibration_json
from fenestra.images import read_image
from fenestra.pipeline.detectors import DETECTORS


def run_reconstruct(photo: Path, out: Path, K_json: Optional[Path] = None, fx: Optional[float] = None,
                    fy: Optional[float] = None, cx: Optional[float] = None, cy: Optional[float] = None,
                    masks: Optional[Path] = None, detector: str = DEFAULTS.detector, snapper: str = DEFAULTS.snapper,
                    pose: str = DEFAULTS.pose, height: Optional[float] = None, width: Optional[float] = None,
                    substitute: Optional[str] = None, export: bool = True, force: bool = False,
                    quad_source: str = DEFAULTS.quad_source, storey: Optional[float] = None,
                    export_all: bool = False, max_pixels: Optional[int] = None,
                    wall_thickness: float = WALL_THICKNESS_M, options: Optional[PhotoOptions] = None) -> PhotoResult:
    """The `reconstruct` command on one photo as a function: pipeline.photo.reconstruct_photo
    writing into ``out``; returns its PhotoResult (``.to_json()``: the windows.json it wrote). height / width / storey: the
    known window height / window width / storey height, m (at most one; none: assumed);
    max_pixels: the largest photo read (None: fenestra.conventions.LIMITS.max_image_pixels);
    wall_thickness: the exported walls' thickness, m (WALL_THICKNESS_RANGE_M). options: the
    PhotoOptions already built from the flags (:func:`photo_options`; the batch builds them once),
    else built here from the option arguments."""

    if options is None:
        options = photo_options(detector=detector, snapper=snapper, pose=pose, quad_source=quad_source, width=width,
                                height=height, storey=storey, substitute=substitute, export=export,
                                export_all=export_all, max_pixels=max_pixels, wall_thickness=wall_thickness)
    with held_out(out, force, (photo, K_json, masks)):  # one reconstruct at a time into a folder
        return reconstruct_photo(photo, out, K_json=K_json, fx=fx, fy=fy, cx=cx, cy=cy, masks=masks, options=options,
                                 force=force)


# the physical range of each --known-* size, m (pipeline.facade_model.KNOWN_RANGE_M, by option)
KNOWN_RANGE_M = {opt: FIELD_RANGE_M[f] for opt, f in (("--known-width", "window_width_m"),
                                                       ("--known-height", "window_height_m"), ("--known-storey", "storey_m"))}


def known_sizes(width: Optional[float], height: Optional[float], storey: Optional[float]) -> Known:
    """pipeline.facade_model.Known from the CLI's --known-width/--known-height/--known-storey;
    PipelineError naming them when more than one is given, or naming the option and its range
    (KNOWN_RANGE_M) when one lies outside it (not finite included)."""
    for opt, v in zip(KNOWN_RANGE_M, (width, height, storey)):
        lo, hi = KNOWN_RANGE_M[opt]
        if v is not None and not lo <= v <= hi:
            raise PipelineError(f"{opt} {v:g} m is outside the physical range [{lo:g}, {hi:g}] m")
    try:
        return Known(window_width_m=width, window_height_m=height, storey_m=storey)
    except ValueError as e:
        raise PipelineError(f"--known-width/--known-height/--known-storey: {e}") from e


# the flag of each PhotoOptions field (what a refused option's message names)
OPTION_FLAGS = {"detector": "--detector", "snapper": "--snapper", "pose": "--pose", "quad_source": "--quad-source",
                "substitute": "--substitute", "max_pixels": "--max-pixels", "wall_thickness_m": "--wall-thickness"}


def photo_options(detector: str = DEFAULTS.detector, snapper: str = DEFAULTS.snapper, pose: str = DEFAULTS.pose,
                  quad_source: str = DEFAULTS.quad_source, width: Optional[float] = None,
                  height: Optional[float] = None, storey: Optional[float] = None, substitute: Optional[str] = None,
                  export: bool = True, export_all: bool = False, max_pixels: Optional[int] = None,
                  wall_thickness: float = WALL_THICKNESS_M) -> PhotoOptions:
    """The PhotoOptions of the `reconstruct` flags, checked once (PhotoOptions checks itself when
    built; the --known-* sizes by :func:`known_sizes`): PipelineError, one line naming the flag
    (:func:`option_message`), before any photo is read."""
    try:
        return PhotoOptions(detector=detector, snapper=snapper, pose=pose, quad_source=quad_source,
                            known=known_sizes(width, height, storey), substitute=substitute, export=export,
                            export_all=export_all, max_pixels=max_pixels, wall_thickness_m=wall_thickness)
    except OptionError as e:
        raise PipelineError(option_message(e)) from e


def option_message(e: OptionError) -> str:
    """A refused PhotoOptions field in the command line's words: its flag (OPTION_FLAGS), what it
    must be and the value given (--wall-thickness: the physical range; --substitute: the
    catalogue's styles)."""

    flag = OPTION_FLAGS.get(e.field, e.field)
    if e.field == "wall_thickness_m":
        lo, hi = WALL_THICKNESS_RANGE_M
        return f"{flag} {e.value!r} m is outside the physical range [{lo:g}, {hi:g}] m"
    if e.field == "substitute" and isinstance(e.value, str):
        try:
            get_style(e.value)
        except ValueError as why:
            return f"{flag}: {why}"
    return f"{flag} {e.why}, got {e.value!r}"


def run_calibrate(photos: list[Path], pattern: str, square: float, out: Path) -> dict:
    """The `calibrate` command as a function: returns the K.json dict it wrote. ``out`` follows
    fenestra.outputs' rule (checked before any photo is read): never one of the photos, never a
    file Fenestra did not write, never into a folder holding another kind of output."""

    try:
        cols, rows = (int(v) for v in pattern.lower().split("x"))
    except ValueError as e:
        raise PipelineError(f"--pattern must be COLSxROWS inner corners (e.g. 9x6), got {pattern!r}") from e
    try:
        outputs.check_file(out, inputs=photos)
        cal = calibrate_chessboard([read_image(p, "photo") for p in photos], (cols, rows), square)
        doc = calibration_json(cal)
        outputs.write_file(out, lambda p: p.write_text(json.dumps(doc, indent=2)), inputs=photos)
    except outputs.OwnershipError as e:
        raise PipelineError(str(e)) from e
    return doc


IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp", ".webp")


def expand_photos(args: list[str]) -> list[Path]:
    """The photos named by command-line arguments, in order, each once: a file as it is, a folder's
    image files (IMAGE_SUFFIXES, sorted), a glob pattern's matches (sorted). PipelineError naming an
    argument that names nothing."""

    found: list[Path] = []
    for a in args:
        p = Path(a)
        if p.is_dir():
            hits = sorted(q for q in p.iterdir() if q.is_file() and q.suffix.lower() in IMAGE_SUFFIXES)
        elif p.is_file():
            hits = [p]
        else:
            hits = sorted(Path(q) for q in glob.glob(a) if Path(q).is_file())
        if not hits:
            raise PipelineError(f"no photo found for {a!r} (not a file, a folder with photos, or a matching glob)")
        found += [h for h in hits if h not in found]
    return found


BATCH_FILES = ("summary.json", "summary.csv")  # a batch folder's own files: never a photo's folder
MAX_NAME_BYTES = 100  # a photo folder's name, UTF-8 bytes (filesystems allow 255)


def safe_name(stem: str) -> str:
    """A folder name for a photo's stem: every character but letters, digits, '_', '-' and '.'
    (a byte of a name that is not UTF-8 among them) replaced by '_', leading dots removed (never
    '.', '..' or a hidden folder), at most MAX_NAME_BYTES bytes; 'photo' when nothing is left."""
    name = re.sub(r"[^\w.-]", "_", stem).lstrip(".")
    while len(name.encode()) > MAX_NAME_BYTES:
        name = name[:-1]
    return name or "photo"


def output_names(photos: list[Path]) -> list[str]:
    """One subfolder name per photo (:func:`safe_name` of its stem, with its parent folder's name
    prefixed where stems repeat), unique without regard to case and never one of BATCH_FILES:
    a clash gets '_0', '_1', ... appended."""
    stems = [safe_name(p.stem) for p in photos]
    names = [s if stems.count(s) == 1 else safe_name(f"{p.parent.name}_{s}") for p, s in zip(photos, stems)]
    taken, out = {n.lower() for n in BATCH_FILES}, []
    for n in names:
        m, i = n, 0
        while m.lower() in taken or (i == 0 and names.count(n) > 1):
            m, i = f"{n}_{i}", i + 1
        taken.add(m.lower())
        out.append(m)
    return out


def summary_row(photo: Path, read: PhotoReadout | None, error: str | None, seconds: float | None = None,
                cpu_s: float | None = None, out_dir: Path | None = None) -> dict:
    """One summary line of a batch (summary.json's, a dict at the file boundary): photo, its time
    (wall and CPU seconds), its size (pixels and bytes) and its output folder's bytes, K source and
    f, walls, windows detected/exported/flagged/failed, the whole error message, and the photo's
    warnings (windows.json's, whole)."""
    size = {"seconds": None if seconds is None else round(seconds, 2), "cpu_s": None if cpu_s is None else round(cpu_s, 2),
            "photo_bytes": photo.stat().st_size if photo.is_file() else None,
            "output_bytes": None if out_dir is None or not out_dir.is_dir() else
            sum(f.stat().st_size for f in out_dir.rglob("*") if f.is_file())}
    if read is None:
        return {"photo": str(photo), "error": error, **size}
    W, H = read.image_size
    return {"photo": str(photo), "error": None, **size, "width_px": W, "height_px": H,
            "K_source": read.resolved.source, "focal_px": round(float(read.resolved.chosen.focal_px), 1),
            "walls": read.walls, "detected": read.detected, "exported": read.exported, "flagged": read.flagged,
            "failed": read.failed, "scale_assumed": read.scale_assumed, "warnings": list(read.warnings)}


SUMMARY_CSV_COLUMNS = ("photo", "error", "seconds", "cpu_s", "width_px", "height_px", "photo_bytes", "output_bytes",
                       "K_source", "focal_px", "walls", "detected", "exported", "flagged", "failed", "scale_assumed")


def summary_csv(rows: list[dict]) -> str:
    """summary.csv: one row per photo, the columns SUMMARY_CSV_COLUMNS (empty where not known)."""

    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=SUMMARY_CSV_COLUMNS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows([{k: ("" if r.get(k) is None else r.get(k)) for k in SUMMARY_CSV_COLUMNS} for r in rows])
    return buf.getvalue()


def run_batch(photos: list[Path], out: Path, kw: dict, inputs: tuple = ()) -> list[dict]:
    """Reconstruct each photo into out/<name> (run_reconstruct with ``kw``; names: :func:`output_names`),
    with a progress bar on stderr; a photo that fails (bad input, or a bug: "internal error") is
    recorded (its error) and the batch goes on. Writes out/summary.json and returns its rows.
    ``out`` follows fenestra.outputs' rule, checked before any photo: never a folder holding or
    inside the photos, ``inputs`` (the folders named) or K/masks, nor one holding another kind of
    output (a bench run, one photo's reconstruction); summary.json replaces only a summary
    Fenestra wrote. ``out`` is locked while the batch runs."""

    try:
        outputs.check_out(out, (*inputs, *photos, kw.get("K_json"), kw.get("masks")), kw.get("force", False),
                          kind=BATCH_KIND)
        out.mkdir(parents=True, exist_ok=True)
        with outputs.locked(out, "batch", keep=False):
            return _batch(photos, out, kw)
    except outputs.OwnershipError as e:
        raise PipelineError(str(e)) from e


BATCH_KIND = "batch"  # the kind of output a batch folder is (fenestra.outputs.KINDS)


def _batch(photos: list[Path], out: Path, kw: dict) -> list[dict]:
    """run_batch's body, in a checked and locked ``out``: summary.json and summary.csv claimed up
    front (refused before any photo runs), then each photo into its folder, then the summary."""


    def write_summary(rows: list[dict]) -> None:
        outputs.write_owned(out, "summary.json", json.dumps(rows, indent=2).encode(), kind=BATCH_KIND)
        outputs.write_owned(out, "summary.csv", summary_csv(rows).encode(errors="backslashreplace"), kind=BATCH_KIND)

    write_summary([])
    rows = []
    with typer.progressbar(list(zip(photos, output_names(photos))), label="reconstruct", file=sys.stderr,
                           item_show_func=lambda item: item[0].name if item else "") as bar:
        for photo, name in bar:
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                read, error = run_reconstruct(photo, out / name, **kw).readout(), None
            except (FenestraError, ValueError, OSError) as e:
                read, error = None, " ".join(str(e).split())
            except Exception as e:  # noqa: BLE001 -- a bug on one photo is recorded, the batch goes on
                read, error = None, f"internal error ({type(e).__name__}, please report it): " + " ".join(str(e).split())
            rows.append(summary_row(photo, read, error, time.perf_counter() - t0, time.process_time() - c0, out / name))
    write_summary(rows)
    return rows


def format_summary(rows: list[dict]) -> str:
    """The batch's summary table: one line per photo (with its time, size and output size), then the
    totals, then each photo's warnings in full."""
    lines = [f"{'photo':<24} {'time_s':>6} {'size_px':>10} {'out_MB':>6} {'K':<17} {'f_px':>6} {'walls':>5} "
             f"{'det':>4} {'exp':>4} {'flag':>4} {'fail':>4}"]
    for r in rows:
        name = Path(r["photo"]).name[:24]
        t = "-" if r.get("seconds") is None else f"{r['seconds']:.1f}"
        mb = "-" if r.get("output_bytes") is None else f"{r['output_bytes'] / 1e6:.1f}"
        if r["error"]:
            lines.append(f"{name:<24} {t:>6} error: {r['error']}")
            continue
        px = "-" if r.get("width_px") is None else f"{r['width_px']}x{r['height_px']}"
        lines.append(f"{name:<24} {t:>6} {px:>10} {mb:>6} {r['K_source']:<17} {r['focal_px']:>6.0f} {r['walls']:>5} "
                     f"{r['detected']:>4} {r['exported']:>4} {r['flagged']:>4} {r['failed']:>4}")
    ok = [r for r in rows if not r["error"]]
    total = sum(r.get("seconds") or 0.0 for r in rows)
    lines.append(f"{len(ok)} of {len(rows)} photos reconstructed in {total:.1f} s; {sum(r['exported'] for r in ok)} "
                 f"windows exported, {sum(r['flagged'] for r in ok)} flagged, {sum(r['failed'] for r in ok)} failed")
    lines += [f"{Path(r['photo']).name}: warning: {w}" for r in ok for w in r.get("warnings", [])]
    return "\n".join(lines)


def _echo_notes(read: PhotoReadout) -> None:
    """The single-photo command's notes: undistortion, intrinsics and their source, scale, warnings."""
    if read.distortion is not None:
        typer.echo(f"photo undistorted with distortion {list(read.distortion)} (quads are in that frame)")
    k = read.resolved.chosen
    typer.echo(f"intrinsics: {k.source} f = {k.focal_px:.0f} px [{k.interval_px[0]:.0f}, "
               f"{k.interval_px[1]:.0f}] ({k.detail})")
    typer.echo("scale: " + "; ".join(read.scale_sources or ["no wall"]))
    for w in read.warnings:
        typer.echo(f"warning: {w}", err=True)
    if read.geometry_failure:
        typer.echo(f"geometry failed (recorded in windows.json): {read.geometry_failure}", err=True)


def format_table(read: PhotoReadout) -> str:
    """A short plain-text table: one line per window, then the median per-stage timing."""
    lines = [f"{'#':>3} {'score':>5} {'aspect':>7} {'case':<17} {'dist_m':>7} {'wall':>4} {'exp':>3} why not / flags"]
    for w in read.windows:
        ar = "-" if w.aspect_ratio is None else f"{w.aspect_ratio:.4f}"
        dist = "-" if w.distance_m is None else f"{w.distance_m:.2f}"
        wall = "-" if w.wall is None else str(w.wall)
        exp = {True: "yes", False: "no", None: "-"}[w.exported]
        lines.append(f"{w.index:>3} {w.score:>5.2f} {ar:>7} {w.aspect_case or '-':<17} {dist:>7} {wall:>4} "
                     f"{exp:>3} {'; '.join(w.reasons)}")
    stages = ("quad", "snap", "aspect", "pose")
    med = {s: np.median([w.timings_ms[s] for w in read.windows if s in w.timings_ms] or [np.nan]) for s in stages}
    lines.append("median ms/window: " + "  ".join(f"{s} {med[s]:.2f}" for s in stages))
    return "\n".join(lines)


class PlainHelp(TyperCommand):
    """A command whose --help is click's plain layout: option names are never cut short (rich's
    table truncates them to fit 80 columns: ``--known-height,--heig…``) and ``\\b`` paragraphs
    (the examples) keep their lines."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs["rich_markup_mode"] = None
        super().__init__(*args, **kwargs)


def register(app: typer.Typer) -> None:
    """Add this stage's commands to the top-level app (choices in the help: from the registries)."""

    @app.command("reconstruct", cls=PlainHelp)
    def reconstruct_cmd(
        photos: list[str] = typer.Argument(..., help="photo(s), folder(s) of photos, or glob patterns (quoted, e.g. "
                                                     "'street/*.jpg'); any format OpenCV reads"),
        out: Path = typer.Option(..., "--out", help="output folder (several photos: one subfolder per photo)"),
        K_json: Optional[Path] = typer.Option(None, "--K", help='intrinsics JSON: {"K": 3x3} or fx/fy/cx/cy, optionally with '
                                              '"distortion": OpenCV coefficients k1, k2, p1, p2, k3 (a list): the '
                                              'photo is then undistorted with the same K before anything else'),
        fx: Optional[float] = typer.Option(None, "--fx", help="focal length, px"),
        fy: Optional[float] = typer.Option(None, "--fy", help="focal length y, px (default fx)"),
        cx: Optional[float] = typer.Option(None, "--cx", help="principal point x, px (default image centre)"),
        cy: Optional[float] = typer.Option(None, "--cy", help="principal point y, px (default image centre)"),
        masks: Optional[Path] = typer.Option(None, "--masks", help="instance-map PNG (16-bit ids, 0 = none) instead of a detector; with "
                                              "lens distortion in --K it must be in the undistorted photo's frame"),
        detector: str = typer.Option(DEFAULTS.detector, "--detector", help=f"detector (without --masks): {DETECTORS.describe()}"),
        snapper: str = typer.Option(DEFAULTS.snapper, "--snapper", help=f"corner snapper: {SNAPPERS.describe()}"),
        pose: str = typer.Option(DEFAULTS.pose, "--pose", help=f"pose strategy: {POSES.describe()}"),
        height: Optional[float] = typer.Option(None, "--known-height", "--height",
                                               help="a typical window's height, m: each wall's median window gets it "
                                                    f"(none of the --known-* given: {DEFAULT_WINDOW_HEIGHT_M:g} m, "
                                                    "flagged assumed)"),
        width: Optional[float] = typer.Option(None, "--known-width", "--width",
                                              help="a typical window's width, m (each wall's median window)"),
        storey: Optional[float] = typer.Option(None, "--known-storey",
                                               help="the storey (floor-to-floor) height, m: each wall's median "
                                                    "pitch between window rows"),
        export_all: bool = typer.Option(False, "--export-all", help="export the windows flagged implausible too"),
        max_pixels: Optional[int] = typer.Option(None, "--max-pixels", min=1,
                                                 help="the largest photo read, pixels, checked before decoding "
                                                      f"(default {LIMITS.max_image_pixels:_})"),
        substitute: Optional[str] = typer.Option(None, "--substitute", help="catalogue window style to swap in"),
        wall_thickness: float = typer.Option(WALL_THICKNESS_M, "--wall-thickness",
                                             help="the exported walls' thickness, m (IFC layer, OBJ/GLB slabs; "
                                                  "not measured: a photo shows no wall's depth)"),
        force: bool = typer.Option(False, "--force", help="write into a non-empty --out folder that holds no "
                                                         "reconstruct output (its files stay: none is replaced)"),
        quad_source: str = typer.Option(DEFAULTS.quad_source, "--quad-source",
                                        help=f"quad from: {', '.join(QUAD_SOURCES)} (corners: the detector's corner head, "
                                             "the mask fit where it has none; mask+corners: the mask fit, the "
                                             "corner head where the fit finds no quadrilateral; mask+lines: the mask fit, the best four "
                                             "of more lines on the mask's outline where it finds none)"),
    ) -> None:
        """Reconstruct the windows of photos: windows.json, overlay.png, IFC, OBJ, GLB per photo.

        Without --K/--fx the focal length comes from EXIF, the façade's vanishing points or a stated prior (windows.json: K_source); failures are recorded, not fatal. Several photos: a progress bar, one subfolder of --out per photo, a summary table (also --out/summary.json and summary.csv, with each photo's time and file sizes).

        \b
        Examples:
          fenestra reconstruct street.jpg --out out/street
          fenestra reconstruct street.jpg --out out/street --known-storey 3.2
          fenestra reconstruct 'photos/*.jpg' --out out/batch
          fenestra reconstruct img017.jpg --K K.json --masks panes017.png --out out/cw
        """  # noqa: E501 -- one paragraph: the help reflows it
        options = photo_options(detector=detector, snapper=snapper, pose=pose, quad_source=quad_source, width=width,
                                height=height, storey=storey, substitute=substitute, export_all=export_all,
                                max_pixels=max_pixels, wall_thickness=wall_thickness)  # refused before any photo is read
        paths = expand_photos(photos)
        if masks is not None and len(paths) > 1:
            raise PipelineError(f"--masks describes one photo; {len(paths)} photos given")
        kw = dict(K_json=K_json, fx=fx, fy=fy, cx=cx, cy=cy, masks=masks, force=force, options=options)
        if len(paths) == 1:
            read = run_reconstruct(paths[0], out, **kw).readout()
            typer.echo(format_table(read))
            _echo_notes(read)
            if (note := read.empty_note()) is not None:
                typer.echo(note, err=True)
            typer.echo(f"wrote {out / 'windows.json'}")
            return
        rows = run_batch(paths, out, kw, inputs=tuple(Path(a) for a in photos if Path(a).is_dir()))
        typer.echo(format_summary(rows))
        typer.echo(f"wrote {out / 'summary.json'}, {out / 'summary.csv'} and one folder per photo in {out}")
        if any(r["error"] for r in rows):
            raise SystemExit(1)

    @app.command("calibrate")
    def calibrate_cmd(
        photos: list[Path] = typer.Argument(..., help="chessboard photos (one camera, one size)"),
        pattern: str = typer.Option(..., "--pattern", help="inner corners COLSxROWS, e.g. 9x6"),
        square: float = typer.Option(1.0, "--square", help="square size, m (does not affect K)"),
        out: Path = typer.Option(..., "--out", help="K.json to write (what `reconstruct --K` reads)"),
    ) -> None:
        """Camera intrinsics and distortion from chessboard photos (OpenCV), with the reprojection error."""
        doc = run_calibrate(photos, pattern, square, out)
        typer.echo(f"board found in {doc['n_images']} of {doc['n_given']} photos; reprojection RMS "
                   f"{doc['reprojection_rms_px']:.3f} px; fx {doc['K'][0][0]:.2f} fy {doc['K'][1][1]:.2f}")
        typer.echo(f"wrote {out}")
