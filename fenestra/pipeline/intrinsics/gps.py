"""Where a photo was taken, from its EXIF GPS sub-IFD: latitude, longitude, altitude and heading
(windows.json's ``gps`` and model.ifc's site)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fenestra.pipeline.intrinsics.exif import exif_number
from fenestra.pipeline.io import pil_open

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
    """:func:`~fenestra.pipeline.intrinsics.exif.exif_number`, with 0 allowed (an altitude at sea
    level, a heading due north)."""
    try:
        if value is not None and float(value) == 0.0:
            return 0.0
    except (TypeError, ValueError, ZeroDivisionError):
        pass
    return exif_number(value)


def gps_from_exif_tags(gps: dict) -> dict | None:
    """The position an EXIF GPS IFD states.

    Args:
        gps: {tag: value} of the GPS sub-IFD (GPS_IFD's tags).
    Returns:
        {"latitude_deg", "longitude_deg" (north and east positive), "altitude_m" (below sea level
        negative), "heading_deg" (GPSImgDirection when its reference is true north, degrees
        clockwise)}, each of the last two None when absent; or None when the photo gives no
        latitude and longitude, or ones outside [-90, 90] / [-180, 180] degrees.
    """
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
    """The photo file's EXIF position (:func:`gps_from_exif_tags`), or None (none, or unreadable)."""
    from PIL import Image  # noqa: PLC0415  (PIL loads on the first photo file read)

    try:
        with pil_open(path) as im:
            return gps_from_exif_tags(dict(im.getexif().get_ifd(GPS_IFD)))
    except (OSError, ValueError, Image.DecompressionBombError):
        return None
