"""tools/detector_batching.py: batching helpers, the verdict, and a batch's detections against the
registry's per-view ``detect``."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
import detector_batching as db  # noqa: E402


def test_chunks_are_consecutive_and_cover_every_view():
    assert db.chunks(list(range(7)), 3) == [[0, 1, 2], [3, 4, 5], [6]]
    assert db.chunks(list(range(4)), 1) == [[0], [1], [2], [3]]
    assert db.chunks(list(range(4)), 8) == [[0, 1, 2, 3]]
    with pytest.raises(ValueError, match="positive"):
        db.chunks([1, 2], 0)


def test_stack_views_keeps_each_view_at_its_index_and_refuses_unequal_sizes():
    import torch

    views = [torch.full((1, 3, 4, 6), float(i)) for i in range(3)]
    x = db.stack_views(views)
    assert x.shape == (3, 3, 4, 6) and x.is_contiguous(memory_format=torch.channels_last)
    assert [float(x[i].mean()) for i in range(3)] == [0.0, 1.0, 2.0]
    with pytest.raises(ValueError, match="one size"):
        db.stack_views([torch.zeros(1, 3, 4, 6), torch.zeros(1, 3, 4, 8)])
    with pytest.raises(ValueError, match="one size"):
        db.stack_views([torch.zeros(2, 3, 4, 6)])
    with pytest.raises(ValueError, match="no views"):
        db.stack_views([])


def test_verdict_needs_a_batch_ten_percent_cheaper_than_one():
    def rows(*ratios):
        return [{"detector": "d", "threads": 1, "batch": b, "detect_cpu_ratio": r} for b, r in zip((1, 2, 4), ratios)]

    assert db.verdict(rows(1.0, 0.95, 0.91), "d")["pays"] is False
    v = db.verdict(rows(1.0, 0.95, 0.90), "d")
    assert v["pays"] is True and v["best_batch"] == 4
    assert db.verdict(rows(1.0, 1.13, 1.2), "d") == {"detector": "d", "threads": 1, "best_batch": 1,
                                                    "best_ratio": 1.0, "threshold": 0.9, "pays": False}
    two = [{"detector": "d", "threads": 2, "batch": b, "detect_cpu_ratio": r, "detect_cpu_ms": ms}
           for b, r, ms in ((1, 1.0, 160.0), (2, 0.85, 136.0))]
    one = [{"detector": "d", "threads": 1, "batch": 1, "detect_cpu_ratio": 1.0, "detect_cpu_ms": 140.0}]
    v = db.verdict(one + two, "d", threads=2)
    assert v["pays"] is True and v["best_batch"] == 2 and v["vs_one_thread"] == pytest.approx(136 / 140)
    assert "vs_one_thread" not in db.verdict(two, "d", threads=2)
    with pytest.raises(ValueError, match="no rows"):
        db.verdict(rows(1.0), "d", threads=2)
    assert db.ratio(130.0, 100.0) == pytest.approx(1.3)
    with pytest.raises(ValueError):
        db.ratio(1.0, 0.0)


def test_batch_of_two_views_detects_what_the_registry_detects_per_view():
    """The default detector's split (input, one forward of the batch, per-view post-processing)
    gives each of 2 synthetic facades the registry's detections, and the same logits."""
    import torch

    from fenestra.pipeline.detectors import detect
    from fenestra.pipeline.session import CANDIDATE_SCORE_MIN

    rng = np.random.default_rng(0)
    images = []
    for k in range(2):
        im = np.full((192, 256, 3), (180 + 20 * k, 160, 140), np.uint8)
        for x in range(20 + 10 * k, 220, 60):
            for y in (30, 110):
                im[y:y + 45, x:x + 30] = (40, 50, 60)
                im[y + 20:y + 23, x:x + 30] = 220  # a transom
        images.append(np.clip(im + rng.normal(0, 6, im.shape), 0, 255).astype(np.uint8))
    split = db.split_detector("default")
    torch.set_num_threads(1)
    reference = [detect("default", im, CANDIDATE_SCORE_MIN, threads=1) for im in images]
    check = db.check_outputs(split, images, 2, reference)
    assert check["detections_agree"], check["disagreements"]
    assert check["max_abs_logit_diff"] < 1e-4 and check["max_abs_feature_diff"] < 1e-4
    assert sum(len(r) for r in reference) > 0  # the check compared something
