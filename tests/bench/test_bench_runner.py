"""The benchmark end to end on real renders of a bundled IFC house (renders/ + pipeline/).

One module-scoped run of the smoke profile's views (fzk-haus, 20 raster views) with the oracle
detector, two real snappers and a deliberately broken one (registered only inside this test)
feeds every test here. The smoke gates were set from a full smoke run, so the real snappers must
pass them here exactly as there, and the broken one must not.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from fenestra.bench import gates, results
from fenestra.methods import Method
from fenestra.bench.profiles import load_profile
from fenestra.bench.runner import run_benchmark
from fenestra.reports.build import build_report


def _shift5(gray, quad, params):
    """A broken snapper: moves every corner 3 px right and 4 px down (5 px)."""
    return np.asarray(quad, float) + [3.0, 4.0], {}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    from fenestra.pipeline.snappers import SNAPPERS
    from fenestra.pipeline.snappers.base import Snapper
    from fenestra.pipeline.snappers.none import NoneParams

    SNAPPERS.register(Snapper("shift5", _shift5, NoneParams, description="broken: 5 px off", test_median_px=5.0))
    commits = iter(["a" * 40])  # HEAD as the run starts; any later read (a commit made during the run) differs
    real_commit, results._commit = results._commit, lambda: next(commits, "b" * 40)
    try:
        root = tmp_path_factory.mktemp("bench")
        methods = (Method("oracle", "none", "lm"), Method("oracle", "linefit", "lm"),
                   Method("oracle", "shift5", "lm"))
        info = run_benchmark(load_profile("smoke"), out_dir=root / "run", workers=1, progress=False,
                             methods=methods, renders_dir=root / "renders", report=build_report)
    finally:
        SNAPPERS.unregister("shift5")
        results._commit = real_commit
    return info


def test_provenance_is_read_when_the_run_starts(run):
    """summary.json names the commit the run started at and the sha256 of every shipped weights file."""
    import hashlib
    from pathlib import Path

    meta = json.loads((run.run_dir / "summary.json").read_text())["metadata"]
    assert meta["commit"] == "a" * 40
    models = Path(results.__file__).resolve().parents[1] / "pipeline" / "models"
    assert meta["models"] == {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(models.glob("*.pt"))}


def test_every_gt_window_has_a_row_per_method(run):
    df = results.load_results(run.run_dir)
    n_gt = 0
    for view_json in (run.run_dir.parent / "renders").glob("*/views/*/view.json"):
        meta = json.loads(view_json.read_text())
        n_gt += len(meta["windows"])
        v = df[df.view == view_json.parent.name]
        for w in meta["windows"]:
            assert set(v[v.window_id == w["id"]].method) == {"oracle/none/lm", "oracle/linefit/lm",
                                                             "oracle/shift5/lm"}
    assert n_gt > 0 and len(df) == 3 * n_gt
    assert df.evaluable.sum() > 0
    assert set(df.status) <= {"ok", "missed", "failed"}
    assert (run.run_dir / "report.html").is_file() and (run.run_dir / "summary.json").is_file()


def test_broken_snapper_moves_corners_by_5px(run):
    df = results.load_results(run.run_dir)
    ev = df[df.evaluable & (df.status == "ok")]
    a = ev[ev.snapper == "none"].set_index(["view", "window_id"]).corner_err_px_snap
    b = ev[ev.snapper == "shift5"].set_index(["view", "window_id"]).corner_err_px_snap
    j = a.to_frame("none").join(b.rename("shift5"), how="inner")
    # triangle inequality per corner: |e_shift - e_none| <= 5 px for each corner, so the means too
    assert np.all(np.abs(j.shift5 - j.none) <= 5.0 + 1e-9)
    assert j.shift5.median() > 3.0


def test_smoke_gates_fail_broken_snapper_only(run):
    # the bundled smoke gates that apply to any oracle method ("oracle/*/*") or to the real
    # snappers run here with a per-window solver (pose = { per_wall = false }); gates on other
    # detectors/snappers/strategies would rightly report "no method"
    wanted = ("oracle/*/*", "oracle/none/*", "oracle/linefit/*")
    g = [x for x in gates.load_gates() if x.profile == "smoke" and x.method in wanted
         and (x.method == "oracle/*/*" or x.pose == (("per_wall", False),))]
    assert {x.method for x in g} == set(wanted)
    v = gates.check(run.run_dir, g)
    bad = {x.method for x in v}
    assert "oracle/shift5/lm" in bad, v
    assert not bad - {"oracle/shift5/lm"}, [str(x) for x in v]


def test_report_apart_runs_in_a_child_and_raises_its_error_as_one_line(tmp_path):
    """The bench CLI's report runs in a spawned process (its memory never adds to the evaluation's):
    what it writes is there afterwards, and its failure comes back as one FenestraError line."""
    import os

    import pytest

    from fenestra.bench.runner import report_apart
    from fenestra.errors import FenestraError
    from fenestra.reports.cli import write_report

    report_apart(os.mkdir, tmp_path / "made-by-the-child")
    assert (tmp_path / "made-by-the-child").is_dir()
    with pytest.raises(FenestraError) as e:
        report_apart(write_report, tmp_path / "not-a-run")
    msg = str(e.value)
    assert "\n" not in msg and str(tmp_path / "not-a-run") in msg, msg
