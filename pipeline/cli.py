"""CLI commands of pipeline/ (registered on the `fenestra` app by fenestra/cli.py).

    fenestra reconstruct PHOTO [--K K.json | --fx F [--fy --cx --cy]] [--masks MASKS.png]
        [--detector NAME] [--snapper NAME] [--pose NAME] [--height M] [--width M]
        [--substitute STYLE] --out DIR
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

import json
from pathlib import Path
from typing import Optional

import numpy as np
import typer

from fenestra.config import choices
from fenestra.conventions import DEFAULTS
from fenestra.errors import PipelineError
from pipeline.facade_model import DEFAULT_WINDOW_HEIGHT_M, Known
from pipeline.photo import PhotoOptions, reconstruct_photo
from pipeline.quad import QUAD_SOURCES
from pipeline.reconstruct import pose_strategies
from pipeline.snappers import SNAPPERS


def run_reconstruct(photo: Path, out: Path, K_json: Optional[Path] = None, fx: Optional[float] = None,
                    fy: Optional[float] = None, cx: Optional[float] = None, cy: Optional[float] = None,
                    masks: Optional[Path] = None, detector: str = DEFAULTS.detector, snapper: str = DEFAULTS.snapper,
                    pose: str = DEFAULTS.pose, height: Optional[float] = None, width: Optional[float] = None,
                    substitute: Optional[str] = None, export: bool = True, force: bool = False,
                    quad_source: str = DEFAULTS.quad_source, storey: Optional[float] = None,
                    export_all: bool = False) -> dict:
    """The `reconstruct` command on one photo as a function: pipeline.photo.reconstruct_photo
    writing into ``out``; returns the windows.json dict it wrote. height / width / storey: the
    known window height / window width / storey height, m (at most one; none: assumed)."""
    options = PhotoOptions(detector=detector, snapper=snapper, pose=pose, quad_source=quad_source,
                           known=known_sizes(width, height, storey), substitute=substitute, export=export,
                           export_all=export_all)
    return reconstruct_photo(photo, out, K_json=K_json, fx=fx, fy=fy, cx=cx, cy=cy, masks=masks, options=options,
                             force=force)


def known_sizes(width: Optional[float], height: Optional[float], storey: Optional[float]) -> Known:
    """pipeline.facade_model.Known from the CLI's --known-width/--known-height/--known-storey;
    PipelineError naming them when more than one is given or one is not a positive length."""
    try:
        return Known(window_width_m=width, window_height_m=height, storey_m=storey)
    except ValueError as e:
        raise PipelineError(f"--known-width/--known-height/--known-storey: {e}") from e


def run_calibrate(photos: list[Path], pattern: str, square: float, out: Path) -> dict:
    """The `calibrate` command as a function: returns the K.json dict it wrote."""
    from pipeline.intrinsics import calibrate_chessboard, calibration_json  # noqa: PLC0415
    from pipeline.io import read_photo  # noqa: PLC0415

    try:
        cols, rows = (int(v) for v in pattern.lower().split("x"))
    except ValueError as e:
        raise PipelineError(f"--pattern must be COLSxROWS inner corners (e.g. 9x6), got {pattern!r}") from e
    cal = calibrate_chessboard([read_photo(p) for p in photos], (cols, rows), square)
    doc = calibration_json(cal)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=2))
    return doc


def format_table(doc: dict) -> str:
    """A short plain-text table: one line per window, then the median per-stage timing."""
    lines = [f"{'#':>3} {'score':>5} {'aspect':>7} {'case':<17} {'dist_m':>7} failure"]
    for w in doc["windows"]:
        ar = f"{w['aspect_ratio']:.4f}" if w["aspect_ratio"] is not None else "-"
        dist = f"{np.linalg.norm(w['t']):.2f}" if w["t"] is not None else "-"
        lines.append(f"{w['index']:>3} {w['score']:>5.2f} {ar:>7} {w['aspect_case'] or '-':<17} {dist:>7} "
                     f"{w['failure'] or ''}")
    stages = ("quad", "snap", "aspect", "pose")
    med = {s: np.median([w["timings_ms"][s] for w in doc["windows"] if s in w["timings_ms"]] or [np.nan])
           for s in stages}
    lines.append("median ms/window: " + "  ".join(f"{s} {med[s]:.2f}" for s in stages))
    return "\n".join(lines)


def register(app: typer.Typer) -> None:
    """Add this stage's commands to the top-level app (choices in the help: from the registries)."""
    from pipeline.detectors import DETECTORS  # noqa: PLC0415

    detector_names = ", ".join(DETECTORS)

    @app.command("reconstruct")
    def reconstruct_cmd(
        photo: Path = typer.Argument(..., help="the photo (any format OpenCV reads)"),
        out: Path = typer.Option(..., "--out", help="output folder"),
        K_json: Optional[Path] = typer.Option(None, "--K", help='intrinsics JSON: {"K": 3x3} or fx/fy/cx/cy, optionally with '
                                              '"distortion": OpenCV coefficients k1, k2, p1, p2, k3 (a list): the '
                                              'photo is then undistorted with the same K before anything else'),
        fx: Optional[float] = typer.Option(None, "--fx", help="focal length, px"),
        fy: Optional[float] = typer.Option(None, "--fy", help="focal length y, px (default fx)"),
        cx: Optional[float] = typer.Option(None, "--cx", help="principal point x, px (default image centre)"),
        cy: Optional[float] = typer.Option(None, "--cy", help="principal point y, px (default image centre)"),
        masks: Optional[Path] = typer.Option(None, "--masks", help="instance-map PNG (16-bit ids, 0 = none) instead of a detector; with "
                                              "lens distortion in --K it must be in the undistorted photo's frame"),
        detector: str = typer.Option(DEFAULTS.detector, "--detector", help=f"detector (without --masks): {detector_names}"),
        snapper: str = typer.Option(DEFAULTS.snapper, "--snapper", help=f"corner snapper: {choices(SNAPPERS)}"),
        pose: str = typer.Option(DEFAULTS.pose, "--pose", help=f"pose strategy: {choices(pose_strategies())}"),
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
        substitute: Optional[str] = typer.Option(None, "--substitute", help="catalogue window style to swap in"),
        force: bool = typer.Option(False, "--force", help="replace a non-empty --out folder that holds no reconstruct output"),
        quad_source: str = typer.Option(DEFAULTS.quad_source, "--quad-source",
                                        help=f"quad from: {', '.join(QUAD_SOURCES)} (corners: the detector's corner head, "
                                             "the mask fit where it has none)"),
    ) -> None:
        """Reconstruct the windows of one photo: windows.json, IFC, OBJ, overlay."""
        if quad_source not in QUAD_SOURCES:
            raise typer.BadParameter(f"--quad-source must be one of {QUAD_SOURCES}, got {quad_source!r}")
        doc = run_reconstruct(photo, out, K_json, fx, fy, cx, cy, masks, detector, snapper, pose,
                              height, width, substitute, force=force, quad_source=quad_source, storey=storey,
                              export_all=export_all)
        typer.echo(format_table(doc))
        if doc.get("undistorted"):
            typer.echo(f"photo undistorted with distortion {doc['distortion']} (quads are in that frame)")
        ks = doc["K_source"]
        typer.echo(f"intrinsics: {ks['source']} f = {ks['focal_px']:.0f} px [{ks['interval_px'][0]:.0f}, "
                   f"{ks['interval_px'][1]:.0f}] ({ks['detail']})")
        for w in doc["warnings"]:
            typer.echo(f"warning: {w}", err=True)
        if doc.get("geometry_failure"):
            typer.echo(f"geometry failed (recorded in windows.json): {doc['geometry_failure']}", err=True)
        typer.echo(f"wrote {out / 'windows.json'}")

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
