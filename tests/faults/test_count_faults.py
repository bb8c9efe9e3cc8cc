"""Every count is bounded at load, and memory stays bounded on every photo the defaults admit.

A count beyond its bound in fenestra.conventions.LIMITS (a profile's procedural houses and views,
``render --views``, ``scenes make``'s storeys and windows, a dataset's photos) is one error line,
exit 2, naming the key, its value and the bound, within seconds and in little memory (it once grew
until the kernel killed it). A photo at the pixel bound with a detection across its whole width
stays under 3 GB.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import json
import time
from pathlib import Path

import cv2
import numpy as np
import pytest


from fault_helpers import TINY_PROFILE, run_measured


def profile_with(old: str, new: str):
    """A builder: the tiny profile with ``old`` replaced by ``new``, benchmarked."""
    def build(d: Path) -> list:
        assert old in TINY_PROFILE
        (d / "p.toml").write_text(TINY_PROFILE.replace(old, new))
        return ["bench", "--profile", "p.toml", "--out", "run"]
    return build


def coco_of(n_images: int):
    """A builder: a COCO file listing ``n_images`` photos (none on disk: the count is refused first)."""
    def build(d: Path) -> list:
        (d / "ds").mkdir()
        doc = {"images": [{"id": i, "file_name": f"{i}.png", "width": 64, "height": 48} for i in range(n_images)],
               "categories": [{"id": 1, "name": "window"}], "annotations": []}
        (d / "ds" / "annotations.json").write_text(json.dumps(doc))
        return ["check-data", "ds", "--format", "coco"]
    return build


# (case, builder -> command line, the error line's needles: the key, its value, the bound's name)
COUNTS = [
    ("profile procedural = 1e9", profile_with("procedural = 0", "procedural = 1000000000"),
     ["scenes.procedural = 1000000000 is more than the 1000 allowed", "LIMITS.max_procedural_houses"]),
    ("profile views_per_house = 1e9", profile_with("views_per_house = 3", "views_per_house = 1000000000"),
     ["render.views_per_house = 1000000000 is more than the 10000 allowed", "LIMITS.max_views_per_dataset"]),
    ("profile 1000 houses x 10000 views", profile_with("procedural = 0\n[render]\nrenderer = \"pyrender\"\n"
                                                       "views_per_house = 3",
                                                       "procedural = 999\n[render]\nrenderer = \"pyrender\"\n"
                                                       "views_per_house = 10000"),
     ["houses x render.views_per_house (1000 x 10000) = 10000000 is more than the 100000 allowed",
      "LIMITS.max_views_per_run"]),
    ("render --views 1e9", lambda d: ["render", "--views", "1000000000", "--width", "160", "--height", "120"],
     ["--views = 1000000000 is more than the 10000 allowed", "LIMITS.max_views_per_dataset"]),
    ("scenes make --storeys 1e8", lambda d: ["scenes", "make", "h.ifc", "--storeys", "100000000"],
     ["storeys = 100000000 is more than the 100 allowed", "LIMITS.max_storeys"]),
    ("scenes make --windows-per-wall 1e8", lambda d: ["scenes", "make", "h.ifc", "--windows-per-wall", "100000000"],
     ["windows_per_wall = 100000000 is more than the 100 allowed", "LIMITS.max_windows_per_wall"]),
    ("scenes make 4 walls x 100 storeys x 100 windows", lambda d: ["scenes", "make", "h.ifc", "--storeys", "100",
                                                                    "--windows-per-wall", "100",
                                                                    "--footprint", "0,0;10,0;10,8;0,8"],
     ["walls x storeys x windows_per_wall (4 x 100 x 100) = 40000 is more than the 10000 allowed",
      "LIMITS.max_house_windows"]),
    ("COCO file of 100001 photos", coco_of(100_001),
     ["'images' lists 100001 photos, more than the 100000 a dataset may have", "LIMITS.max_dataset_photos"]),
]


@pytest.mark.parametrize("case, build, needles", COUNTS, ids=[c for c, _, _ in COUNTS])
def test_a_count_beyond_its_bound_is_one_line_within_seconds(case, build, needles, tmp_path):
    args = build(tmp_path)
    t0 = time.perf_counter()
    rc, err, gb = run_measured(args, tmp_path, max_gb=6.0, timeout=120)  # unbounded, it once took 24 GB
    seconds = time.perf_counter() - t0
    assert rc == 2 and "Traceback" not in err, (rc, err[-2000:])
    lines = [ln for ln in err.splitlines() if ln.startswith("error: ")]
    assert len(lines) == 1, err[-2000:]
    for n in needles:
        assert n in lines[0], lines[0]
    assert gb < 1.0 and seconds < 60, (gb, seconds)
    assert not (tmp_path / "h.ifc").exists()


def test_the_bundled_profiles_are_within_the_bounds():
    """Every bundled profile loads, the largest (scale: 5 bundled + 15 procedural houses x 500
    views) among them: the bounds leave room."""
    from fenestra.bench.profiles import available_profiles, load_profile

    loaded = {n: load_profile(n) for n in available_profiles()}
    scale = loaded["scale"].source
    assert (scale.scenes.procedural, scale.render.views_per_house) == (15, 500)


# ---------------------------------------------------------------- memory on the largest admitted photo

def test_an_all_black_photo_at_the_pixel_bound_stays_under_3_GB(tmp_path):
    """12000 x 12400 px (149 Mpx, under the 150 Mpx default): the learned detector finds one void
    across the whole width; its full-resolution crop is fitted, listed and drawn without copies of
    its size in int64 or int32 (it peaked at 3.82 GB)."""
    cv2.imwrite(str(tmp_path / "black.png"), np.zeros((12400, 12000, 3), np.uint8))
    rc, err, gb = run_measured(["reconstruct", "black.png", "--fx", "10000", "--out", "o"], tmp_path)
    assert rc == 0, err[-2000:]
    assert gb < 3.0, gb
    doc = json.loads((tmp_path / "o" / "windows.json").read_text())
    assert doc["image_size"] == [12000, 12400]


def test_a_full_width_detection_costs_at_most_twice_its_mask():
    """The quad fit of a full-width crop (3000 x 3000 of a 3000 x 4000 photo) allocates at most
    twice the mask's bytes (the uint16 labels of its blobs: it was three times, with a padded copy
    and int32 labels), and its box for the overlay a row and a column (it was two int64 indices per
    pixel: 16 times). Measured with tracemalloc, which sees numpy's and OpenCV's arrays."""
    import tracemalloc

    from fenestra.pipeline.photo import detection_boxes
    from fenestra.pipeline.quad import QuadParams
    from fenestra.pipeline.reconstruct import fit_sparse
    from fenestra.pipeline.types import Detection

    m = np.zeros((3000, 3000), bool)
    m[10:2990, :] = True
    det = Detection(mask=m, box=np.array([-0.5, 509.5, 2999.5, 3489.5]), score=0.9, origin=(0, 500))
    tracemalloc.start()
    try:
        fit = fit_sparse(det, QuadParams(), (4000, 3000))
        fit_peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.reset_peak()
        boxes = detection_boxes([det])
        box_peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert fit.failure.code == "touches_border" and boxes == {0: (0, 510, 2999, 3489)}
    assert fit_peak <= 2.1 * m.nbytes, fit_peak / m.nbytes
    assert box_peak <= 0.05 * m.nbytes, box_peak / m.nbytes
