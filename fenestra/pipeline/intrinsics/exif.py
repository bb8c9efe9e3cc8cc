"""The focal length a photo's EXIF states, as a chain entry (:func:`exif_focal`).

FocalLengthIn35mmFilm gives f_px = f35 / 36 mm * max(W, H); else FocalLength (mm) with
FocalPlaneXResolution (px per unit of FocalPlaneResolutionUnit), rescaled from the EXIF
PixelX/YDimension to the photo's size when they are given. Rationals and (num, den) tuples are read
as numbers. Interval: +- EXIF_REL_INTERVAL (nominal focal lengths, focus breathing). A focal length
whose field of view along the long side is outside EXIF_FOV_RANGE_DEG (no camera makes it: a 35 mm
equivalent of 65535 mm is a 0.03 deg view) is refused: EXIF is then unavailable with that reason,
never used.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fenestra.errors import PipelineError
from fenestra.pipeline.intrinsics.focal import FocalEstimate, fov_from_focal
from fenestra.pipeline.io import pil_open
from fenestra.pipeline.types import Unavailable

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
EXIF_REL_INTERVAL = 0.05  # EXIF focal lengths are nominal: +- 5 %


def exif_number(value) -> float | None:
    """An EXIF value as a positive finite float, or None.

    Args:
        value: a number, PIL's IFDRational, a (num, den) tuple (a rational as some writers store
            it; den 0 gives None) or a one-element sequence.
    Returns:
        The number, or None for anything else, zero, negative or not finite.
    """
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
    """The focal length EXIF tags state, for a photo of ``image_size``.

    Args:
        tags: {tag id: value}: FocalLengthIn35mmFilm (0xA405, mm), FocalLength (0x920A, mm),
            FocalPlaneXResolution (0xA20E, px per unit), FocalPlaneResolutionUnit (0xA210: 2 inch,
            3 cm, 4 mm), PixelXDimension / PixelYDimension (0xA002 / 0xA003: the size the
            focal-plane resolution refers to, else the photo's). Numbers, rationals or (num, den).
        image_size: (W, H) px.
    Returns:
        (focal px, how: the tags used, in words), or None if the tags do not give it.
    Raises:
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
    """(focal_px, how) when the field of view of ``focal_px`` (px) along the long side of a (W, H) px
    image is inside EXIF_FOV_RANGE_DEG, else PipelineError naming it, the field of view (deg) and
    the range (also in 35 mm-equivalent mm)."""
    fov = fov_from_focal(focal_px, image_size) if np.isfinite(focal_px) and focal_px > 0 else float("nan")
    lo, hi = EXIF_FOV_RANGE_DEG
    if not lo <= fov <= hi:
        mm = [FULL_FRAME_WIDTH_MM / 2.0 / np.tan(np.radians(a) / 2.0) for a in (hi, lo)]
        raise PipelineError(f"{how} (f = {focal_px:.4g} px) is a {fov:.3g} deg field of view, outside the physical "
                            f"{lo:g}-{hi:g} deg (35 mm equivalent {mm[0]:.1f}-{mm[1]:.0f} mm)")
    return focal_px, how


def read_exif_tags(path: str | Path) -> dict:
    """{tag id: value} of a photo file's EXIF (main IFD and the Exif sub-IFD); {} if it has none or
    cannot be read."""
    from PIL import Image  # noqa: PLC0415  (PIL loads on the first photo file read)

    try:
        with pil_open(path) as im:
            exif = im.getexif()
            tags = dict(exif)
            tags.update(exif.get_ifd(EXIF_IFD))
    except (OSError, ValueError, Image.DecompressionBombError):
        return {}
    return tags


def focal_from_exif(path: str | Path, image_size: tuple[int, int]) -> tuple[float, str] | None:
    """(focal px, how) from the photo file's EXIF (:func:`focal_from_exif_tags`), or None;
    PipelineError for one outside the physical range. image_size: (W, H) px. FocalPlaneXResolution
    refers to the sensor's full resolution; without PixelX/YDimension it is used as is (a photo
    resized after capture then gives a wrong f)."""
    return focal_from_exif_tags(read_exif_tags(path), image_size)


def exif_focal(photo: str | Path, image_size: tuple[int, int]) -> FocalEstimate | Unavailable | None:
    """The photo file's EXIF focal length as a chain entry (:func:`exif_focal_of_tags` of its
    :func:`read_exif_tags`)."""
    return exif_focal_of_tags(read_exif_tags(photo), image_size)


def exif_focal_of_tags(tags: dict, image_size: tuple[int, int]) -> FocalEstimate | Unavailable | None:
    """The EXIF focal length of a photo's tags as a chain entry.

    Args:
        tags: {EXIF tag id: value} (:func:`read_exif_tags`; the bench passes a view's own).
        image_size: (W, H) px of the photo as the pipeline sees it.
    Returns:
        The estimate with interval +- EXIF_REL_INTERVAL; None when the EXIF has no focal length;
        Unavailable(why) when it states one outside EXIF_FOV_RANGE_DEG (the chain records it).
    """
    try:
        found = focal_from_exif_tags(tags, image_size)
    except PipelineError as e:
        return Unavailable(str(e))
    if found is None:
        return None
    f, how = found
    return FocalEstimate("exif", f, (f * (1 - EXIF_REL_INTERVAL), f * (1 + EXIF_REL_INTERVAL)), how)
