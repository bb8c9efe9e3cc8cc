"""The photo's EXIF GPS position reaches windows.json and model.ifc's site (issue 35, item 4).

Truth: the degrees/minutes/seconds written into the test photo's EXIF here, converted by hand."""
from __future__ import annotations

from pathlib import Path

import ifcopenshell
import numpy as np
import ifcopenshell.util.geolocation
import pytest
from PIL import Image

from fenestra import reconstruct_photo
from fenestra.pipeline.intrinsics import gps_from_exif, gps_from_exif_tags

ROOT = Path(__file__).resolve().parents[2]
EX = ROOT / "examples" / "curtainwall"
# 33 deg 51' 54" S, 151 deg 12' 36" W (a made-up place), 12.5 m below sea level
GPS = {1: "S", 2: (33.0, 51.0, 54.0), 3: "W", 4: (151.0, 12.0, 36.0), 5: 1, 6: 12.5, 16: "T", 17: 120.0}
LAT, LON = -(33 + 51 / 60 + 54 / 3600), -(151 + 12 / 60 + 36 / 3600)


def _photo_with_gps(tmp_path: Path, gps: dict) -> Path:
    im = Image.open(EX / "img017.jpg")
    exif = Image.Exif()
    exif[0x8825] = gps
    out = tmp_path / "gps.jpg"
    im.save(out, "JPEG", quality=95, exif=exif)
    return out


def test_gps_tags_by_hand():
    g = gps_from_exif_tags(GPS)
    assert g["latitude_deg"] == pytest.approx(LAT, abs=1e-9) and g["longitude_deg"] == pytest.approx(LON, abs=1e-9)
    assert g["altitude_m"] == pytest.approx(-12.5) and g["heading_deg"] == pytest.approx(120.0)
    north = gps_from_exif_tags({1: "N", 2: ((52, 1), (30, 1), (0, 1)), 3: "E", 4: (13.0, 24.0, 0.0), 16: "M", 17: 30.0})
    assert gps_from_exif_tags({**GPS, 6: 0, 17: 0.0})["altitude_m"] == 0.0  # sea level, due north: 0, not unknown
    assert gps_from_exif_tags({**GPS, 17: 0.0})["heading_deg"] == 0.0
    assert north == {"latitude_deg": 52.5, "longitude_deg": 13.4, "altitude_m": None, "heading_deg": None}  # magnetic
    assert gps_from_exif_tags({}) is None
    assert gps_from_exif_tags({1: "N", 2: (95.0, 0.0, 0.0), 3: "E", 4: (1.0, 0.0, 0.0)}) is None  # no such latitude
    assert gps_from_exif_tags({1: "N", 2: (10.0, 0.0), 3: "E", 4: (1.0, 0.0, 0.0)}) is None  # not a triple


def test_exif_position_reaches_windows_json_and_the_ifc_site(tmp_path):
    photo = _photo_with_gps(tmp_path, GPS)
    assert gps_from_exif(photo)["latitude_deg"] == pytest.approx(LAT, abs=1e-9)
    doc = reconstruct_photo(photo, tmp_path / "out", K_json=EX / "K.json", masks=EX / "panes017.png").to_json()
    assert doc["gps"]["longitude_deg"] == pytest.approx(LON, abs=1e-9)
    site = ifcopenshell.open(str(tmp_path / "out" / "model.ifc")).by_type("IfcSite")[0]
    assert ifcopenshell.util.geolocation.dms2dd(*site.RefLatitude) == pytest.approx(LAT, abs=1e-6)
    assert ifcopenshell.util.geolocation.dms2dd(*site.RefLongitude) == pytest.approx(LON, abs=1e-6)
    # the heading (120 deg, east-south-east): the model's +y is the view direction, so true north
    # lies 120 deg counter-clockwise from +y in the plan: (-sin 120, cos 120)
    f = ifcopenshell.open(str(tmp_path / "out" / "model.ifc"))
    north = {c.TrueNorth.DirectionRatios for c in f.by_type("IfcGeometricRepresentationContext")}  # sub-contexts inherit it
    assert len(north) == 1 and np.allclose(north.pop(), (-np.sin(np.radians(120)), np.cos(np.radians(120))))
    conv = f.by_type("IfcMapConversion")[0]
    # the model's x axis (heading + 90 = 210 deg) in grid coordinates, convergence at this point by hand
    lon0 = -183 + 6 * (int((LON + 180) // 6) % 60 + 1)
    gamma = np.degrees(np.arctan(np.tan(np.radians(LON - lon0)) * np.sin(np.radians(LAT))))
    bearing = np.radians(210.0 - gamma)
    assert np.allclose((conv.XAxisAbscissa, conv.XAxisOrdinate), (np.sin(bearing), np.cos(bearing)), atol=1e-9)
    # a photo without GPS: no position, no site reference
    doc = reconstruct_photo(EX / "img017.jpg", tmp_path / "plain", K_json=EX / "K.json", masks=EX / "panes017.png").to_json()
    assert doc["gps"] is None
    assert ifcopenshell.open(str(tmp_path / "plain" / "model.ifc")).by_type("IfcSite")[0].RefLatitude is None
