"""tools/focal_invariance.py: a copy's vanishing-point answer against its original's, and the
report's table and counts, on runs built by hand."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import focal_invariance as fi  # noqa: E402  (a lab script, not installed)


def _run(copy, vp, warnings=()):
    return fi.FocalRun("a.jpg", copy, vp, "" if vp else "why", ("prior", 800.0, 500.0, 1400.0), tuple(warnings), 1.0)


def test_outcomes_and_stability_by_hand():
    orig = _run("original", (1000.0, 950.0, 1050.0))
    assert fi.outcome(orig, _run("jpeg q80", (1040.0, 1000.0, 1080.0))) == "inside"
    assert fi.outcome(orig, _run("mirror", (1060.0, 1000.0, 1120.0))) == "outside"  # its interval holds 1000: still out
    assert fi.outcome(orig, _run("half size", None)) == "refused"
    none = _run("original", None)
    assert fi.outcome(none, _run("jpeg q80", None)) == "none" and fi.outcome(none, _run("mirror", (900.0, 1, 2))) == "answers"
    assert fi.stable(["inside"] * 3) and fi.stable(["none"] * 3) and not fi.stable(["inside", "refused", "inside"])


def test_copies_are_what_users_make():
    img = np.arange(4 * 6 * 3, dtype=np.uint8).reshape(4, 6, 3)
    assert fi.copy_of(img, "half size").shape == (2, 3, 3)
    assert np.array_equal(fi.copy_of(img, "mirror")[:, 0], img[:, -1])
    assert fi.copy_of(img, "jpeg q80").shape == img.shape


def test_report_counts_and_marks_warned_copies():
    runs = {"x/a.jpg": [_run("original", (1000.0, 950.0, 1050.0)), _run("jpeg q80", (1040.0, 1000.0, 1080.0)),
                        _run("half size", None), _run("mirror", (1010.0, 990.0, 1030.0))],
            "x/b.jpg": [_run("original", None), _run("jpeg q80", (2966.0, 2662.0, 3271.0), ["sources disagree"]),
                        _run("half size", None), _run("mirror", None)]}
    lines = fi.report(runs)
    assert lines[2] == ("| x/a.jpg | 1000 [950, 1050] | 1040 [1000, 1080] (inside) | refused | 1010 [990, 1030] (inside) "
                        "| no |")
    assert lines[3] == "| x/b.jpg | none (prior) | 2966 [2662, 3271] (answers, warned) | none | none | no |"
    assert lines[5].startswith("2 photos; the vanishing points answer on 1 originals; stable: 0 of 2. Per copy: "
                               "jpeg q80: answers 1, inside 1; half size: none 1, refused 1; mirror: inside 1, none 1.")
