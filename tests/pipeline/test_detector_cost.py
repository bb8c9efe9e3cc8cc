"""tools/detector_cost.py: its stages add up to the detector the CLI runs, and its verdict."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
import detector_cost as dc  # noqa: E402


def test_the_timed_stages_are_the_detector_the_cli_runs():
    """Network, instances, corners and verifier, run one by one, give detect("default")'s detections."""
    photo = ROOT / "data" / "real" / "curtainwall" / "images" / "img017.jpg"
    image = dc.load_photo(photo)
    assert max(image.shape[:2]) == dc.LONG_SIDE
    times, staged, whole = dc.stage_times(image, *dc.staged_detector(threads=1))
    assert set(times) == set(dc.STAGES) and all(w >= 0 and c >= 0 for w, c in times.values())
    assert len(whole) > 0 and len(staged) >= len(whole)
    kept = [d for d in staged if d.score >= 0.5]  # detect's default score threshold
    assert len(kept) == len(whole)
    for a, b in zip(kept, whole):
        assert a.score == b.score and np.array_equal(np.asarray(a.box), np.asarray(b.box))
        assert (a.corners is None) == (b.corners is None)
        if a.corners is not None:
            assert np.allclose(a.corners, b.corners)


def _result(detect_ms: float, mb: float) -> dict:
    stages = {s: {"wall_ms": 1.0, "cpu_ms": 1.0} for s in dc.STAGES}
    stages["detect"] = {"wall_ms": detect_ms, "cpu_ms": detect_ms}
    return {"stages": stages, "weights_mb": {"default.pt": mb}, "n_photos": 3, "threads": 2, "repeats": 1,
            "cpu": "test", "load_before": 0.0, "load_after": 0.0, "detect_wall_ms_max": detect_ms}


def test_markdown_states_each_target_against_its_figure():
    ok = dc.markdown(_result(250.0, 12.0), "cmd")
    assert "**met** (250 ms)" in ok and "**met** (12.0 MB)" in ok
    slow = dc.markdown(_result(310.0, 61.0), "cmd")
    assert "**not met** (310 ms)" in slow and "**not met** (61.0 MB)" in slow
