"""tools/focal_sources.py: one row per view of the K-withheld methods, figures per focal source."""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import focal_sources  # noqa: E402  (a lab script, not installed)


def test_one_row_per_view_and_the_shares_by_hand():
    rows = pd.DataFrame({
        "house": ["a", "a", "a", "b", "b", "b"], "view": ["1", "1", "2", "1", "1", "1"],
        "detector": ["d"] * 6, "method": ["d/s/wall+lines+noK"] * 5 + ["d/s/wall+lines"],
        "K_source": ["vanishing points", "vanishing points", "prior", "vanishing points", "vanishing points", None],
        "focal_err_rel": [0.02, 0.02, 0.30, 0.04, None, None],
        "evaluable": [True, True, True, True, True, True]})
    views = focal_sources.view_rows(rows)
    assert sorted(zip(views.house, views.view)) == [("a", "1"), ("a", "2"), ("b", "1")]  # K given rows left out
    lines = focal_sources.source_lines(views, "all")
    assert lines[0] == "  all: 3 views"
    assert "prior: 1 views (33 %), focal error median 30.0 %" in lines[1]
    assert "vanishing points: 2 views (67 %), focal error median 3.0 % p90 3.8 %" in lines[2]
    assert focal_sources.source_lines(views.iloc[:0], "none") == ["  none: no view"]
