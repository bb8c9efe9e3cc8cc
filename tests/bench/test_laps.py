"""bench.runner.Laps: the summarize stage's parts, each the wall time since the previous lap."""
from __future__ import annotations

import time

from fenestra.bench.runner import Laps


def test_laps_split_the_elapsed_time_into_named_parts():
    stage_s: dict[str, float] = {"render": 1.0}
    t0 = time.perf_counter()
    lap = Laps(stage_s, "summarize.")
    time.sleep(0.02)
    lap("table")
    time.sleep(0.01)
    lap("statistics")
    total = time.perf_counter() - t0
    assert set(stage_s) == {"render", "summarize.table", "summarize.statistics"}
    assert stage_s["summarize.table"] >= 0.02 and stage_s["summarize.statistics"] >= 0.01
    assert stage_s["summarize.table"] + stage_s["summarize.statistics"] <= total
