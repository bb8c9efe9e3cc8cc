"""`fenestra reconstruct` / pipeline.reconstruct_photo on photos without intrinsics: always an
answer with its source, detections and failures always written (issue 24).

The street photos are the spb_facades test split in ../shared/real (not shipped: skipped when absent)."""
from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipeline.cli import run_reconstruct

ROOT = Path(__file__).resolve().parents[1]
SPB = Path(os.environ.get("FENESTRA_SPB", ROOT.parent / "shared" / "real" / "spb_facades"))
needs_spb = pytest.mark.skipif(not (SPB / "images" / "img_185.jpg").is_file(), reason=f"no spb photos in {SPB}")


def test_blank_photo_without_K_is_written_with_its_failures(tmp_path):
    """A photo with no usable façade: no EXIF, no vanishing points; the prior answers, the one
    (too small) detection is written with its failure, and the overlay exists."""
    photo, masks = tmp_path / "blank.png", tmp_path / "masks.png"
    cv2.imwrite(str(photo), np.full((240, 320, 3), 128, np.uint8))
    inst = np.zeros((240, 320), np.uint16)
    inst[100:102, 100:102] = 1  # a 2 x 2 px blob: no quad
    cv2.imwrite(str(masks), inst)
    doc = run_reconstruct(photo, tmp_path / "out", masks=masks, snapper="none")
    saved = json.loads((tmp_path / "out" / "windows.json").read_text())
    assert saved["K_source"]["source"] == "prior" and saved["K_source"] == doc["K_source"]
    lo, hi = saved["K_source"]["interval_px"]
    assert lo < saved["K"][0][0] < hi
    assert len(saved["windows"]) == 1 and saved["windows"][0]["failure"]
    assert (tmp_path / "out" / "overlay.png").is_file()


@needs_spb
def test_street_photo_without_K_always_gives_an_output(tmp_path):
    """img_185 stopped with "focal length unobservable" and wrote nothing (issue 24)."""
    doc = run_reconstruct(SPB / "images" / "img_185.jpg", tmp_path / "out", export=False)
    saved = json.loads((tmp_path / "out" / "windows.json").read_text())
    assert saved["K_source"]["source"] in ("exif", "vanishing points", "prior")
    assert saved["K_source"]["interval_px"][0] <= doc["K"][0][0] <= saved["K_source"]["interval_px"][1]
    assert len(saved["windows"]) >= 5 and (tmp_path / "out" / "overlay.png").is_file()
