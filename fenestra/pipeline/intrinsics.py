"""Intrinsics when the user gives none: a ranked chain of focal sources, or chessboard photos.

The chain used by ``fenestra reconstruct`` / ``pipeline.reconstruct_photo`` (:func:`resolve_K`),
first usable source wins; every source that gave a value is kept, and two whose intervals do not
overlap give a warning naming both values:

1. ``K``: the user's K (--K K.json or --fx), interval = the value itself (taken as exact).
2. ``exif``: FocalLengthIn35mmFilm (f_px = f35 / 36 mm * max(W, H)), else FocalLength (mm) with
   FocalPlaneXResolution (px per unit of FocalPlaneResolutionUnit), rescaled from the EXIF
   PixelX/YDimension to the photo's size when they are given. Rationals and (num, den) tuples are
   read as numbers. Interval: +- EXIF_REL_INTERVAL (nominal focal lengths, focus breathing). A
   focal length whose field of view along the long side is outside EXIF_FOV_RANGE_DEG (no camera
   makes it: a 35 mm equivalent of 65535 mm is a 0.03 deg view) is refused: EXIF is then
   unavailable with that reason, never used.
3. ``vanishing points``: the focal length from the walls' two orthogonal vanishing directions,
   refined over all their windows' corners and, with a ``+lines`` strategy, the façade's own line
   segments (pipeline.walls.focal_from_walls); principal point at the image centre, square pixels.
   Where no wall alone shows converging verticals (a level camera), two walls seen at a right angle
   (a corner of the building: their two horizontal vanishing points) give it, the fit then tying
   them at right angles (pipeline.walls.corner_focals). Interval (90 %): f +- VP_SD_MULTIPLIER x sd,
   the multiplier calibrated on renders with known K (tools/focal_calibration.py). Not used when its field of view is outside PLAUSIBLE_FOV_DEG or that
   interval is no narrower than the prior's (:func:`vp_max_sd`). Bounded time: the fit stops as soon as
   f runs away, after a capped number of evaluations, or when its first pass is already several times
   vaguer than that bound (pipeline.walls.fit_walls_focal). Nor when it is unstable
   (:func:`vanishing_stability`, issue 35): with at least 2 x VP_SPLIT_MIN_QUADS windows, the two halves
   of the windows (by position) are fitted alone, and halves whose 90 % intervals are disjoint, or a
   half without an answer, send the chain to the prior; ``unavailable`` then says "unstable: halves
   give A px and B px ...".
4. ``prior``: a typical phone camera, PRIOR_FOV_DEG horizontal field of view along the photo's long
   side, with the wide interval PRIOR_FOV_RANGE_DEG. Always available: the chain never fails.

:func:`calibrate_chessboard` is the paper's calibration step (OpenCV): K and distortion from
photos of a chessboard, with the RMS reprojection error; :func:`calibration_json` writes the
K.json that ``--K`` reads.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from fenestra.errors import PipelineError
from fenestra.pipeline.types import Unavailable

if TYPE_CHECKING:  # annotations only; pipeline.walls is imported lazily below
    from fenestra.pipeline.segments import SegmentCache
    from fenestra.pipeline.walls import WallParams

FULL_FRAME_WIDTH_MM = 36.0  # the 35 mm-equivalent focal length refers to a 36 x 24 mm frame
EXIF_IFD = 0x8769
TAG_FOCAL = 0x920A
TAG_FOCAL_35 = 0xA405
TAG_PLANE_XRES = 0xA20E
TAG_PLANE_UNIT = 0xA210
TAG_PIXEL_X = 0xA002
TAG_PIXEL_Y = 0xA003
PLANE_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0}  # inch, cm, mm
# The physical range of an EXIF focal length, as the field of view (deg) along the photo's long side:
# 0.5 deg is a 35 mm equivalent of 4125 mm (super-zoom bridge cameras reach 3000 mm, 0.69 deg), 170 deg
# one of 1.6 mm (beyond any rectilinear lens; fisheyes are read as pinholes here). Outside: refused.
EXIF_FOV_RANGE_DEG = (0.5, 170.0)


def centred_K(focal_px: float, image_size: tuple[int, int]) -> np.ndarray:
    """Square-pixel K (3, 3) with focal ``focal_px`` and the principal point at the centre of an
    image of ``image_size`` (W, H) px."""
    W, H = image_size
    if not (np.isfinite(focal_px) and focal_px > 0):
        raise PipelineError(f"focal length must be positive, got {focal_px}")
    return np.array([[focal_px, 0.0, (W - 1) / 2.0], [0.0, focal_px, (H - 1) / 2.0], [0.0, 0.0, 1.0]])


def exif_number(value) -> float | None:
    """An EXIF value as a positive finite float, or None: numbers, PIL's IFDRational, (num, den)
    tuples (a rational as some writers store it; den 0 gives None) and one-element sequences."""
    if isinstance(value, (tuple, list)):
        if len(value) == 2:
            try:
                num, den = float(value[0]), float(value[1])
            except (TypeError, ValueError):
                return None
            return exif_number(num / den) if den else None
        return exif_number(value[0]) if len(value) == 1 else None
    try:
        v = float(value)
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return v if np.isfinite(v) and v > 0 else None


def focal_from_exif_tags(tags: dict, image_size: tuple[int, int]) -> tuple[float, str] | None:
    """(focal px, how) from EXIF tags {tag id: value}, or None if they do not give it.

    tags: FocalLengthIn35mmFilm (0xA405, mm), FocalLength (0x920A, mm), FocalPlaneXResolution
    (0xA20E, px per unit), FocalPlaneResolutionUnit (0xA210: 2 inch, 3 cm, 4 mm), PixelXDimension /
    PixelYDimension (0xA002 / 0xA003: the size the focal-plane resolution refers to, else the
    photo's). Values may be numbers, rationals or (num, den) tuples. image_size (W, H).
    PipelineError (naming the tag, the value and EXIF_FOV_RANGE_DEG) for a focal length whose
    field of view is outside that physical range.
    """
    W, H = image_size
    f35 = exif_number(tags.get(TAG_FOCAL_35))
    if f35:
        return exif_in_range(f35 / FULL_FRAME_WIDTH_MM * max(W, H), f"exif FocalLengthIn35mmFilm {f35:g} mm",
                             image_size)
    f_mm, xres = exif_number(tags.get(TAG_FOCAL)), exif_number(tags.get(TAG_PLANE_XRES))
    unit = PLANE_UNIT_MM.get(int(exif_number(tags.get(TAG_PLANE_UNIT)) or 2))
    if f_mm and xres and unit:
        px_per_mm = xres / unit
        dims = [exif_number(tags.get(t)) for t in (TAG_PIXEL_X, TAG_PIXEL_Y)]
        rescale = max(W, H) / max(dims) if all(dims) else 1.0
        how = f"exif FocalLength {f_mm:g} mm x FocalPlaneXResolution {px_per_mm:g} px/mm"
        return exif_in_range(f_mm * px_per_mm * rescale,
                             how + (f" x {rescale:.4g} (photo resized)" if rescale != 1.0 else ""), image_size)
    return None


def exif_in_range(focal_px: float, how: str, image_size: tuple[int, int]) -> tuple[float, str]:
    """(focal_px, how) when its field of view along the long side is inside EXIF_FOV_RANGE_DEG,
    else PipelineError naming it, the field of view and the range (also in 35 mm-equivalent mm)."""
    fov = fov_from_focal(focal_px, image_size) if np.isfinite(focal_px) and focal_px > 0 else float("nan")
    lo, hi = EXIF_FOV_RANGE_DEG
    if not lo <= fov <= hi:
        mm = [FULL_FRAME_WIDTH_MM / 2.0 / np.tan(np.radians(a) / 2.0) for a in (hi, lo)]
        raise PipelineError(f"{how} (f = {focal_px:.4g} px) is a {fov:.3g} deg field of view, outside the physical "
                            f"{lo:g}-{hi:g} deg (35 mm equivalent {mm[0]:.1f}-{mm[1]:.0f} mm)")
    return focal_px, how


def read_exif_tags(path: str | Path) -> dict:
    """{tag id: value} of a photo's EXIF (main IFD and the Exif sub-IFD); {} if it has none."""
    from PIL import Image  # noqa: PLC0415

    from fenestra.pipeline.io import pil_open  # noqa: PLC0415

    try:
        with pil_open(path) as im:
            exif = im.getexif()
            tags = dict(exif)
            tags.update(exif.get_ifd(EXIF_IFD))
    except (OSError, ValueError, Image.DecompressionBombError):
        return {}
    return tags


GPS_IFD = 0x8825  # EXIF GPS sub-IFD: 1/2 LatitudeRef/Latitude, 3/4 LongitudeRef/Longitude, 5/6 AltitudeRef/Altitude,
# 16/17 ImgDirectionRef ("T" true, "M" magnetic)/ImgDirection (the view's heading, deg clockwise)


def _dms(value) -> float | None:
    """Degrees from an EXIF (degrees, minutes, seconds) triple of numbers or rationals; None if not one."""
    if not isinstance(value, (tuple, list)) or len(value) != 3:
        return None
    parts = []
    for v in value:
        try:
            x = float(v[0]) / float(v[1]) if isinstance(v, (tuple, list)) and len(v) == 2 else float(v)
        except (TypeError, ValueError, ZeroDivisionError):
            return None
        if not (np.isfinite(x) and x >= 0):
            return None
        parts.append(x)
    return parts[0] + parts[1] / 60.0 + parts[2] / 3600.0


def _exif_non_negative(value) -> float | None:
    """:func:`exif_number`, with 0 allowed (an altitude at sea level, a heading due north)."""
    try:
        if value is not None and float(value) == 0.0:
            return 0.0
    except (TypeError, ValueError, ZeroDivisionError):
        pass
    return exif_number(value)


def gps_from_exif_tags(gps: dict) -> dict | None:
    """{"latitude_deg", "longitude_deg", "altitude_m", "heading_deg"} from an EXIF GPS IFD {tag:
    value} (north and east positive, altitude below sea level negative; heading: GPSImgDirection
    when its reference is true north, degrees clockwise; each None when absent), or None when the
    photo gives no latitude and longitude, or ones outside [-90, 90] / [-180, 180] degrees."""
    lat, lon = _dms(gps.get(2)), _dms(gps.get(4))
    if lat is None or lon is None:
        return None
    lat = -lat if str(gps.get(1, "N")).upper().startswith("S") else lat
    lon = -lon if str(gps.get(3, "E")).upper().startswith("W") else lon
    if abs(lat) > 90.0 or abs(lon) > 180.0:
        return None
    alt = _exif_non_negative(gps.get(6))
    if alt is not None and gps.get(5) in (1, b"\x01"):
        alt = -alt
    heading = _exif_non_negative(gps.get(17))
    true_north = str(gps.get(16, "")).upper().startswith("T")  # a magnetic heading ("M") needs the declination
    return {"latitude_deg": float(lat), "longitude_deg": float(lon), "altitude_m": None if alt is None else float(alt),
            "heading_deg": float(heading) % 360.0 if heading is not None and true_north else None}


def gps_from_exif(path: str | Path) -> dict | None:
    """The photo file's EXIF position (:func:`gps_from_exif_tags`), or None."""
    from PIL import Image  # noqa: PLC0415

    from fenestra.pipeline.io import pil_open  # noqa: PLC0415

    try:
        with pil_open(path) as im:
            return gps_from_exif_tags(dict(im.getexif().get_ifd(GPS_IFD)))
    except (OSError, ValueError, Image.DecompressionBombError):
        return None


def focal_from_exif(path: str | Path, image_size: tuple[int, int]) -> tuple[float, str] | None:
    """(focal px, how) from the photo file's EXIF, or None; PipelineError for one outside the
    physical range (:func:`focal_from_exif_tags`). Note: FocalPlaneXResolution refers to the
    sensor's full resolution; it is used as is (photos resized after capture give a wrong f)."""
    return focal_from_exif_tags(read_exif_tags(path), image_size)


EXIF_REL_INTERVAL = 0.05  # EXIF focal lengths are nominal: +- 5 %
PRIOR_FOV_DEG = 65.0  # a typical phone's horizontal field of view (along the long side)
PRIOR_FOV_RANGE_DEG = (40.0, 90.0)  # the prior's wide interval (tele-ish to ultra-wide-ish)
PLAUSIBLE_FOV_DEG = (20.0, 100.0)  # a vanishing-point focal length outside is not used (phone: a 3x tele, 26 deg, .. wide)
# The vanishing-point focal length's 90 % interval is f +- VP_SD_MULTIPLIER x sd (the fit's sd): the 90th
# percentile of |f - f_true| / sd over 98 fits on 144 renders with known K (procedural houses 100-105, 24
# views each, dataset seed 1, a 30-95 deg field of view; none of the bench's renders), measured by
#     PYOPENGL_PLATFORM=egl nice .venv/bin/python tools/focal_calibration.py   # -> out/focal-calibration/calibration.csv
# (docs/experiments.md, "Calibrated vanishing-point focal intervals"). It replaces a x3 inflation of the
# normal 1.645 sd (4.93 sd: 94 % coverage there) and a +-15 % gate. The estimate is used when that interval
# is narrower than the prior's (PRIOR_FOV_RANGE_DEG): a measured answer that says more than the assumption.
VP_SD_MULTIPLIER = 2.69
# Stability check of the vanishing-point focal length (issue 35: on real photos the answer moved by
# 12-218 % under gray / JPEG / mirror / 10 % crop while its interval said +-3 %): the windows are split in
# VP_SPLIT_PARTS disjoint halves (:func:`evidence_halves`), each fitted alone with the same façade segments;
# when every half has at least VP_SPLIT_MIN_QUADS windows and the halves' calibrated 90 % intervals are
# disjoint, or a half gives no focal length while the whole does, the answer is called unstable and the
# prior is used (:func:`vanishing_stability`). Measured on renders and on the St Petersburg photos
# (docs/experiments.md, "Vanishing points unstable under re-encoding").
VP_SPLIT_PARTS = 2
# 4 windows a half: with 3 the check called one calibration render unstable whose interval held the truth
# (its focal error 15.9 %, the prior's 45.3 %); with 4 it changes no render answer there
VP_SPLIT_MIN_QUADS = 4
VP_STABILITY_CHECK = True  # the check in the CLI's chain (vanishing_focal's default; False: the chain before it)


def focal_from_fov(fov_deg: float, image_size: tuple[int, int]) -> float:
    """Focal length (px) giving a field of view ``fov_deg`` along the long side of a (W, H) image."""
    return max(image_size) / 2.0 / np.tan(np.radians(fov_deg) / 2.0)


def fov_from_focal(focal_px: float, image_size: tuple[int, int]) -> float:
    """Field of view (deg) along the long side of a (W, H) image for a focal length (px)."""
    return float(np.degrees(2.0 * np.arctan(max(image_size) / 2.0 / focal_px)))


@dataclass(frozen=True)
class FocalEstimate:
    """One source's focal length: source "K" | "exif" | "vanishing points" | "prior"; focal_px;
    interval_px (lo, hi) px (90 % for vanishing points, stated ranges otherwise); detail: how."""

    source: str
    focal_px: float
    interval_px: tuple[float, float]
    detail: str

    def overlaps(self, other: "FocalEstimate") -> bool:
        """Whether the two intervals share a value."""
        return self.interval_px[0] <= other.interval_px[1] and other.interval_px[0] <= self.interval_px[1]

    def to_json(self) -> dict:
        return {"source": self.source, "focal_px": self.focal_px, "interval_px": list(self.interval_px),
                "detail": self.detail}


def user_focal(K: np.ndarray, how: str) -> FocalEstimate:
    """The user's K as a chain entry (interval: the value itself)."""
    f = float(K[0, 0])
    return FocalEstimate("K", f, (f, f), how)


def exif_focal(photo: str | Path, image_size: tuple[int, int]) -> FocalEstimate | Unavailable | None:
    """The photo file's EXIF focal length (:func:`exif_focal_of_tags` of its :func:`read_exif_tags`)."""
    return exif_focal_of_tags(read_exif_tags(photo), image_size)


def exif_focal_of_tags(tags: dict, image_size: tuple[int, int]) -> FocalEstimate | Unavailable | None:
    """The EXIF focal length of tags {tag id: value} (:func:`focal_from_exif_tags`; image_size (W,
    H) px) +- EXIF_REL_INTERVAL, None without one, or why it is refused (Unavailable: outside
    EXIF_FOV_RANGE_DEG; the chain records it as unavailable)."""
    try:
        found = focal_from_exif_tags(tags, image_size)
    except PipelineError as e:
        return Unavailable(str(e))
    if found is None:
        return None
    f, how = found
    return FocalEstimate("exif", f, (f * (1 - EXIF_REL_INTERVAL), f * (1 + EXIF_REL_INTERVAL)), how)


def prior_focal(image_size: tuple[int, int]) -> FocalEstimate:
    """The stated prior: PRIOR_FOV_DEG along the long side, interval from PRIOR_FOV_RANGE_DEG."""
    lo, hi = (focal_from_fov(a, image_size) for a in PRIOR_FOV_RANGE_DEG[::-1])
    return FocalEstimate("prior", focal_from_fov(PRIOR_FOV_DEG, image_size), (lo, hi),
                         f"assumed: a typical phone camera, {PRIOR_FOV_DEG:g} deg field of view along the long side "
                         f"({PRIOR_FOV_RANGE_DEG[0]:g}-{PRIOR_FOV_RANGE_DEG[1]:g} deg)")


def vanishing_fit(quads: np.ndarray, image_size: tuple[int, int], wall: WallParams | None = None,
                  segment_cache: SegmentCache | None = None,
                  give_up_rel_sd: float | None = None) -> tuple[float, float] | Unavailable:
    """The façade's vanishing-point focal length and its sd (px), ungated: (f, sd) from snapped
    window quads (N, 4, 2) px (pipeline.walls.focal_from_walls), or why there is none
    (Unavailable: unobservable, or an implausible field of view). give_up_rel_sd: a relative sd above which the
    caller will not use the answer (the fit may stop early above a multiple of it); None: never."""
    from fenestra.pipeline.walls import WallParams, focal_from_walls  # noqa: PLC0415

    W, H = image_size
    if not len(quads):
        return Unavailable("no window quads")
    try:
        f, sd = focal_from_walls(np.asarray(quads, dtype=np.float64), (H, W), wall or WallParams(), segment_cache,
                                 max_rel_sd=give_up_rel_sd)
    except PipelineError as e:
        return Unavailable(str(e))
    if not (np.isfinite(f) and f > 0 and np.isfinite(sd)):
        return Unavailable(f"focal length {f} +- {sd} px")
    fov = fov_from_focal(f, image_size)
    if not PLAUSIBLE_FOV_DEG[0] <= fov <= PLAUSIBLE_FOV_DEG[1]:
        return Unavailable(f"f = {f:.0f} px is a {fov:.0f} deg field of view, outside the plausible "
                           f"{PLAUSIBLE_FOV_DEG[0]:g}-{PLAUSIBLE_FOV_DEG[1]:g} deg")
    return f, sd


def vp_max_sd(image_size: tuple[int, int]) -> float:
    """The largest sd (px) a vanishing-point focal length may have to be used: its calibrated 90 %
    interval (2 x VP_SD_MULTIPLIER x sd wide) narrower than the prior's (:func:`prior_focal`)."""
    lo, hi = prior_focal(image_size).interval_px
    return (hi - lo) / (2.0 * VP_SD_MULTIPLIER)


def vanishing_estimate(f: float, sd: float, image_size: tuple[int, int], how: str = "") -> FocalEstimate | Unavailable:
    """The acceptance rule of a vanishing-point fit f +- sd (px): the estimate with its calibrated
    90 % interval f +- VP_SD_MULTIPLIER x sd when that interval is narrower than the prior's, else
    why it is not used (Unavailable). how: words on where it came from, for the detail."""
    half = VP_SD_MULTIPLIER * sd
    if not sd < vp_max_sd(image_size):
        lo, hi = prior_focal(image_size).interval_px
        return Unavailable(f"f = {f:.0f} +- {half:.0f} px (90 %, calibrated {VP_SD_MULTIPLIER:g} sd) is no narrower "
                           f"than the prior's {lo:.0f}-{hi:.0f} px")
    return FocalEstimate("vanishing points", f, (max(f - half, 1e-6), f + half),
                         f"f = {f:.1f} +- {sd:.1f} px (sd){how}, principal point at the "
                         f"image centre; interval: 90 %, {VP_SD_MULTIPLIER:g} sd (calibrated on renders)")


def evidence_halves(quads: np.ndarray, parts: int = VP_SPLIT_PARTS) -> list[np.ndarray]:
    """``parts`` disjoint, deterministic index sets (each sorted, int) covering window quads (N, 4, 2)
    px: the windows ordered by their centroid's x, then y (px), dealt out in turn (window k to part k
    mod parts), so that every part spans the façade.
    The same quads in any order give the same windows in each part."""
    c = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2).mean(axis=1)
    order = np.lexsort((c[:, 1], c[:, 0])) if len(c) else np.zeros(0, int)
    return [np.sort(order[k::parts]) for k in range(parts)]


def vanishing_stability(quads: np.ndarray, image_size: tuple[int, int], fit: tuple[float, float],
                        wall: WallParams | None = None, segment_cache: SegmentCache | None = None,
                        min_quads: int = VP_SPLIT_MIN_QUADS, parts: int = VP_SPLIT_PARTS) -> tuple[bool, str]:
    """Whether the vanishing-point focal length ``fit`` (f, sd) px of window quads (N, 4, 2) px in a
    (W, H) image stands when its evidence is split: each part of :func:`evidence_halves` is fitted
    alone (:func:`vanishing_fit`, the same façade segments, the same early give-up as the whole).
    Unstable when every part has at least ``min_quads`` windows and either two parts' calibrated 90 %
    intervals (f +- VP_SD_MULTIPLIER sd) are disjoint, or a part gives no focal length while the whole
    does (its answer then rests on some of the windows only). Fewer windows: not tested (stable).
    Returns (stable, words: the parts' answers, e.g. "unstable: halves give 442 px and no focal length
    (...)"; "" when not tested)."""
    idx = evidence_halves(quads, parts)
    if min(len(i) for i in idx) < min_quads:
        return True, ""
    give_up = vp_max_sd(image_size) / prior_focal(image_size).focal_px
    fits = [vanishing_fit(np.asarray(quads)[i], image_size, wall, segment_cache, give_up_rel_sd=give_up) for i in idx]
    said = [f"no focal length ({f})" if isinstance(f, Unavailable) else f"{f[0]:.0f} px" for f in fits]
    words = ("halves give " if parts == 2 else f"{parts} parts give ") + " and ".join(said)
    answered = [f for f in fits if not isinstance(f, Unavailable)]
    k = VP_SD_MULTIPLIER
    disjoint = any(abs(a[0] - b[0]) > k * (a[1] + b[1]) for n, a in enumerate(answered) for b in answered[n + 1:])
    if disjoint or len(answered) < len(fits):
        why = "90 % intervals disjoint" if disjoint else "a half has no answer"
        return False, (f"unstable: {words}, f = {fit[0]:.0f} +- {fit[1]:.1f} px from all {len(quads)} windows "
                       f"({why}; split by position, issue 35); using the prior")
    return True, words


def vanishing_focal(quads: np.ndarray, image_size: tuple[int, int], wall: WallParams | None = None,
                    segment_cache: SegmentCache | None = None,
                    check_stability: bool | None = None) -> FocalEstimate | Unavailable:
    """The façade's vanishing-point focal length (:func:`vanishing_fit`) from snapped window quads
    (N, 4, 2) px if :func:`vanishing_estimate` accepts it and (check_stability; None: the module's
    VP_STABILITY_CHECK, read at the call) the halves of its windows agree (:func:`vanishing_stability`),
    or why there is none (Unavailable)."""
    fit = vanishing_fit(quads, image_size, wall, segment_cache,
                        give_up_rel_sd=vp_max_sd(image_size) / prior_focal(image_size).focal_px)
    if isinstance(fit, Unavailable):
        return fit
    lines = " and the facade line segments" if wall is not None and wall.lines else ""
    est = vanishing_estimate(*fit, image_size, f" from {len(quads)} window(s){lines}")
    if isinstance(est, Unavailable) or not (VP_STABILITY_CHECK if check_stability is None else check_stability):
        return est
    stable, words = vanishing_stability(quads, image_size, fit, wall, segment_cache)
    if not stable:
        return Unavailable(words)
    return replace(est, detail=est.detail + (f"; stable: {words}" if words else ""))


@dataclass(frozen=True)
class ResolvedK:
    """K (3, 3) from the first usable focal source (:class:`FocalEstimate` ``chosen``), every
    source that gave a value (``estimates``, in rank order), the sources that gave none with why
    (``unavailable``: {source: reason}), and warnings where two sources' intervals do not overlap."""

    K: np.ndarray
    chosen: FocalEstimate
    estimates: tuple[FocalEstimate, ...]
    unavailable: dict
    warnings: tuple[str, ...]

    @property
    def source(self) -> str:
        return self.chosen.source

    @property
    def detail(self) -> str:
        return self.chosen.detail

    def to_json(self) -> dict:
        """windows.json's ``K_source``: source, detail, focal_px, interval_px, candidates, unavailable."""
        return {**self.chosen.to_json(), "candidates": [e.to_json() for e in self.estimates],
                "unavailable": dict(self.unavailable)}


def disagreements(estimates: list[FocalEstimate]) -> list[str]:
    """A warning for each pair of measured sources (not the prior) whose intervals do not overlap."""
    measured = [e for e in estimates if e.source != "prior"]
    return [f"focal sources disagree: {a.source} {a.focal_px:.0f} px [{a.interval_px[0]:.0f}, {a.interval_px[1]:.0f}] "
            f"vs {b.source} {b.focal_px:.0f} px [{b.interval_px[0]:.0f}, {b.interval_px[1]:.0f}]; using {measured[0].source}"
            for i, a in enumerate(measured) for b in measured[i + 1:] if not a.overlaps(b)]


def choose_focal(ranked: list[FocalEstimate | Unavailable | None], names: list[str], image_size: tuple[int, int],
                 principal_point: tuple[float, float] | None = None) -> ResolvedK:
    """The chain's answer: ``ranked`` holds each source's estimate, or why it has none (Unavailable,
    or None for "not given"), in rank order, named by ``names``; the prior closes the chain.
    principal_point (cx, cy) px: kept from the user's K, else the image centre."""
    estimates = [e for e in ranked if isinstance(e, FocalEstimate)] + [prior_focal(image_size)]
    unavailable = {n: e.reason for n, e in zip(names, ranked) if isinstance(e, Unavailable)}
    chosen = estimates[0]
    K = centred_K(chosen.focal_px, image_size)
    if principal_point is not None:
        K[0, 2], K[1, 2] = principal_point
    return ResolvedK(K, chosen, tuple(estimates), unavailable, tuple(disagreements(estimates)))


def resolve_K(photo: str | Path | None, quads: np.ndarray, image_size: tuple[int, int],
              wall: WallParams | None = None, segment_cache: SegmentCache | None = None) -> ResolvedK:
    """Intrinsics for a photo without --K: EXIF, then the façade's vanishing points, then the prior
    (never fails). Both measured sources are computed so that a disagreement can be reported.

    quads: (N, 4, 2) px snapped window quads of the photo; image_size (W, H); wall: the per-wall
    strategy's parameters (default ``WallParams()``; with ``lines`` the photo's façade segments join
    the focal fit, which needs segment_cache, the photo's pipeline.segments.SegmentCache).
    """
    exif = None if photo is None else exif_focal(photo, image_size)  # None: an image without a file (a render)
    return resolve_K_with(exif, quads, image_size, wall, segment_cache)


def resolve_K_with(exif: FocalEstimate | Unavailable | None, quads: np.ndarray, image_size: tuple[int, int],
                   wall: WallParams | None = None, segment_cache: SegmentCache | None = None) -> ResolvedK:
    """:func:`resolve_K` with the photo's EXIF focal length already read (:func:`exif_focal_of_tags`;
    None: the photo has none)."""
    vp = vanishing_focal(quads, image_size, wall, segment_cache)
    return choose_focal([exif if exif is not None else Unavailable("no EXIF focal length"), vp], ["exif", "vanishing points"],
                        image_size)


# ------------------------------------------------------------------ chessboard calibration

@dataclass(frozen=True)
class Calibration:
    """K (3, 3), distortion (5,) OpenCV k1 k2 p1 p2 k3, rms_px: RMS reprojection error over all
    corners; image_size (W, H); n_images: photos where the board was found, of n_given."""

    K: np.ndarray
    distortion: np.ndarray
    rms_px: float
    image_size: tuple[int, int]
    n_images: int
    n_given: int


def board_points(pattern: tuple[int, int], square_m: float) -> np.ndarray:
    """(cols*rows, 3) inner-corner coordinates (m) of a chessboard, z = 0, OpenCV's row-major order."""
    cols, rows = pattern
    g = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2)
    return np.hstack([g * float(square_m), np.zeros((len(g), 1))]).astype(np.float32)


def find_corners(gray: np.ndarray, pattern: tuple[int, int]) -> np.ndarray | None:
    """Sub-pixel inner corners (cols*rows, 2) px of a chessboard in a uint8 gray image, or None."""
    ok, c = cv2.findChessboardCorners(gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        return None
    c = cv2.cornerSubPix(gray, c, (5, 5), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4))
    return c.reshape(-1, 2)


def calibrate_chessboard(images: list[np.ndarray], pattern: tuple[int, int], square_m: float = 1.0,
                         fix_aspect: bool = False) -> Calibration:
    """Calibrate from chessboard photos (uint8 gray or RGB, one size) with ``pattern`` = inner
    corners (cols, rows). Needs the board in >= 3 photos; PipelineError otherwise."""
    if len(pattern) != 2 or min(pattern) < 2:
        raise PipelineError(f"pattern must be (cols, rows) inner corners >= 2, got {pattern}")
    sizes = {im.shape[:2] for im in images}
    if len(sizes) != 1:
        raise PipelineError(f"calibration photos must share one size, got {sorted(sizes)}")
    H, W = sizes.pop()
    obj, img = [], []
    for im in images:
        gray = im if im.ndim == 2 else cv2.cvtColor(im, cv2.COLOR_RGB2GRAY)
        c = find_corners(gray, pattern)
        if c is not None:
            obj.append(board_points(pattern, square_m))
            img.append(c.astype(np.float32))
    if len(img) < 3:
        raise PipelineError(f"chessboard {pattern[0]}x{pattern[1]} found in {len(img)} of {len(images)} photos; need >= 3")
    flags = cv2.CALIB_FIX_ASPECT_RATIO if fix_aspect else 0
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, (W, H), None, None, flags=flags)
    return Calibration(K=np.asarray(K, dtype=np.float64), distortion=np.asarray(dist, dtype=np.float64).ravel()[:5],
                       rms_px=float(rms), image_size=(W, H), n_images=len(img), n_given=len(images))


def calibration_json(cal: Calibration) -> dict:
    """The K.json document ``--K`` reads (pipeline.io.read_camera), with the calibration's quality."""
    W, H = cal.image_size
    return {"K": cal.K.tolist(), "distortion": cal.distortion.tolist(), "width": W, "height": H,
            "reprojection_rms_px": cal.rms_px, "n_images": cal.n_images, "n_given": cal.n_given,
            "source": "fenestra calibrate (OpenCV chessboard calibration)"}
