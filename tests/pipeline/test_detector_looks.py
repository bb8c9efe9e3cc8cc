"""The shipped detector under two looks of one house (issue #36): the same cameras, once with a
plaster wall and dark frames, once with brick and light frames (the look on which the detector once
lost 42 % of `duplex`'s windows). Its recall must hold under both: on `office-a`, a building family
it never saw, and on `duplex`, a training house whose adjacent windows stand a few px apart.

Ground truth: the renderer's instance map (independent of the detector); a window counts when at
least MIN_PX of its pixels are visible and it does not touch the border; it is found when a
detection's mask overlaps its instance with IoU >= 0.5.
"""
from __future__ import annotations

import numpy as np
import pytest

from fenestra.pipeline.detectors import detect
from fenestra.renders.base import RenderSettings
from fenestra.renders.materials import sample_look
from fenestra.renders.sampler import SamplerConfig, sample_views
from fenestra.scenes.loader import load_scene

MIN_PX = 400  # visible window pixels for a window to count (about 20 x 20 px)
MIN_RECALL = 0.85  # issue #36: <= 10 % missed on every bench house under every look, with slack for 6 views
N_VIEWS = 6


def _look_seed(wall_style: str, frame_light: bool) -> int:
    """The first render seed whose classic look has this wall style and a light (or dark) frame."""
    for s in range(2000):
        lk = sample_look(np.random.default_rng(s), "classic")
        light = np.mean(lk.frame_rgb) > 0.8
        if lk.wall_style == wall_style and light == frame_light and (light or np.mean(lk.frame_rgb) < 0.3):
            return s
    raise AssertionError(f"no seed below 2000 draws a {wall_style} look with a {'light' if frame_light else 'dark'} frame")


def _recall(rgb: np.ndarray, instances: np.ndarray) -> tuple[int, int]:
    """(windows found, windows counted) of detect("default") on one view."""
    ids, counts = np.unique(instances[instances > 0], return_counts=True)
    border = set(np.unique(np.concatenate([instances[0], instances[-1], instances[:, 0], instances[:, -1]])))
    gt = [i for i, c in zip(ids, counts) if c >= MIN_PX and i not in border]
    masks = [d.mask for d in detect("default", rgb)]
    found = 0
    for i in gt:
        m = instances == i
        found += any((m & d).sum() / max((m | d).sum(), 1) >= 0.5 for d in masks)
    return found, len(gt)


@pytest.fixture(scope="module")
def views(request):
    scene = load_scene(request.param)
    cfg = SamplerConfig(width=640, height=480, street_fraction=0.5)
    return scene, [v.camera for v in sample_views(scene, cfg, N_VIEWS, seed=3).views]


def _found_under(scene, cameras, wall_style: str, frame_light: bool) -> tuple[int, int]:
    """(found, counted) over the cameras, rendered in the first look of that kind."""
    from fenestra.renders.raster import RasterRenderer

    seed = _look_seed(wall_style, frame_light)
    assert sample_look(np.random.default_rng(seed), "classic").wall_style == wall_style
    found = counted = 0
    with RasterRenderer(scene, RenderSettings(seed=seed)) as r:
        for cam in cameras:
            out = r.render(cam)
            f, n = _recall(out.rgb, out.instances)
            found, counted = found + f, counted + n
    assert counted >= 10, f"only {counted} windows in view: the test measures nothing"
    print(f"{scene.name}, {wall_style} wall: {found}/{counted} windows found")
    return found, counted


DUPLEX_GAP = ("detector v7 with mirror-averaged maps (the shipped weights) on duplex's 24 windows in these 6 views: 18 "
              "found on plaster with dark frames, 14 on dark brick with light frames (v7 without the mirror: 19 and 14; v6: "
              "17 and 11; v5: 21 and 13; v4: 20 and 14; v3: 19 and 13; over 40 views and seeds 0-2, profile "
              "trained-seeds, the shipped detector finds 92 % of duplex's windows, 89 % at seed 0; v7 without the mirror "
              "90 %, v6 80 %, v5 77 %); adjacent windows merge into one mask more often on brick. Issue #36's target "
              "(<= 10 % missed under every look) is not met on duplex (docs/experiments.md, 'Maps averaged over the "
              "mirror image'); strict: the test fails once a detector meets it, and the mark goes.")


@pytest.mark.parametrize("views", [
    "office-a", pytest.param("duplex", marks=pytest.mark.xfail(strict=True, reason=DUPLEX_GAP))], indirect=True)
def test_default_detector_recall_holds_under_both_looks(views):
    scene, cameras = views
    rates = {}
    for wall_style, frame_light in (("plaster", False), ("brick", True)):
        found, counted = _found_under(scene, cameras, wall_style, frame_light)
        rates[wall_style] = found / counted
    assert min(rates.values()) >= MIN_RECALL, rates
    assert abs(rates["plaster"] - rates["brick"]) <= 0.1, rates
