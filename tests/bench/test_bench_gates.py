"""bench.gates and bench.results on a synthetic results table (bench.synthetic: known answers).

The end-to-end gate test with a deliberately broken snapper on real renders is in
tests/bench/test_bench_runner.py.
"""
from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from fenestra.bench import gates, manifest, results
from fenestra.bench.profiles import ProfileError, available_profiles, load_profile, profile_from_dict
from synthetic_results import synthetic_results


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    df = synthetic_results(n_windows=120, seed=1)
    results.write_results(df, d)
    manifest.seal(d, df, "synthetic")
    results.write_summary(d, {"profile": "synthetic"}, results.summarize(df))
    return d


GATES = [
    gates.Gate("synthetic", "oracle/*/*", "corner_err_px_snap.median", max=2.0),
    gates.Gate("synthetic", "oracle/*/*", "corner_err_px_snap.recall.5", min=0.8),
    gates.Gate("synthetic", "oracle/*/*", "detection_rate", min=0.9),
]


def test_summary_matches_independent_computation(run_dir):
    df = results.load_results(run_dir)
    s = results.load_summary(run_dir)["results"]["oracle/good/lm"]
    ev = df[(df.method == "oracle/good/lm") & df.evaluable]
    e = ev.corner_err_px_snap.to_numpy()
    assert s["n_evaluable"] == len(ev)
    assert s["corner_err_px_snap"]["median"] == pytest.approx(np.nanmedian(e))
    assert s["corner_err_px_snap"]["recall"]["2"] == pytest.approx(np.sum(e <= 2) / len(e))
    assert s["detection_rate"] == pytest.approx(np.mean(ev.status != "missed"))
    # snapped error = 0.5 x lognormal(median 2 px): median close to 1 px
    assert 0.8 < s["corner_err_px_snap"]["median"] < 1.2


def test_gates_pass_good_fail_bad(run_dir):
    v = gates.check(run_dir, GATES)
    failed = {(x.method, x.metric) for x in v}
    assert ("oracle/bad/lm", "corner_err_px_snap.median") in failed
    assert ("oracle/bad/lm", "corner_err_px_snap.recall.5") in failed
    assert not any(x.method == "oracle/good/lm" for x in v)
    bad = next(x for x in v if x.metric == "corner_err_px_snap.median")
    assert bad.value > 3.0 and "<= 2" in str(bad) and "oracle/bad/lm" in str(bad)


def test_gate_matching_nothing_is_a_violation(run_dir):
    v = gates.check(run_dir, [gates.Gate("synthetic", "maskrcnn/*/*", "detection_rate", min=0.5)])
    assert len(v) == 1 and v[0].value is None and "maskrcnn" in str(v[0])
    with pytest.raises(gates.GateError, match="no gates for profile 'synthetic'"):
        gates.check(run_dir, [gates.Gate("smoke", "*", "detection_rate", min=0.5)])


def test_gates_file_errors_name_the_entry(tmp_path):
    p = tmp_path / "g.toml"
    p.write_text('[[gate]]\nprofile = "smoke"\nmethod = "*"\nmetric = "x"\nmaxx = 1\n')
    with pytest.raises(gates.GateError, match="gate #1.*'maxx'"):
        gates.load_gates(p)
    p.write_text('[[gate]]\nprofile = "smoke"\nmethod = "*"\nmetric = "x"\n')
    with pytest.raises(gates.GateError, match="neither 'min' nor 'max'"):
        gates.load_gates(p)


def test_bundled_gates_file_loads():
    g = gates.load_gates()
    assert g and all(x.profile in available_profiles() for x in g)


def test_gate_cli_exit_codes(run_dir, tmp_path):
    p = tmp_path / "g.toml"
    p.write_text('[[gate]]\nprofile = "synthetic"\nmethod = "oracle/*/*"\n'
                 'metric = "corner_err_px_snap.median"\nmax = 2.0\n')
    r = subprocess.run([sys.executable, "-m", "fenestra", "gate", str(run_dir), "--gates", str(p)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1
    assert "oracle/bad/lm: corner_err_px_snap.median =" in r.stderr and "<= 2" in r.stderr
    p.write_text(p.read_text().replace("max = 2.0", "max = 50.0"))
    r = subprocess.run([sys.executable, "-m", "fenestra", "gate", str(run_dir), "--gates", str(p)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr


def test_results_table_needs_columns(tmp_path):
    df = synthetic_results(n_windows=4).drop(columns=["rot_err_deg"])
    with pytest.raises(ValueError, match="rot_err_deg"):
        results.write_results(df, tmp_path)


def test_summary_json_has_no_nan(run_dir):
    text = (run_dir / "summary.json").read_text()
    assert "NaN" not in text
    json.loads(text)


def test_profiles_load_and_validate():
    for name in ("smoke", "default", "photoreal"):
        p = load_profile(name)
        assert p.name == name and len(p.config_hash()) == 8
    assert load_profile("smoke").source.render.renderer == "pyrender"
    assert load_profile("photoreal").source.render.renderer == "mitsuba"
    with pytest.raises(ProfileError, match="unknown key\\(s\\) \\['view'\\]"):
        profile_from_dict({"name": "x", "render": {"view": 3}})
    with pytest.raises(ProfileError, match="'views_per_house' has bad value 'many'"):
        profile_from_dict({"name": "x", "render": {"views_per_house": "many"}})
    with pytest.raises(ProfileError, match="render.views_per_house has bad value 0"):
        profile_from_dict({"name": "x", "render": {"views_per_house": 0}})
    with pytest.raises(ProfileError, match="unknown profile 'nope'"):
        load_profile("nope")
    # the hash changes with anything that changes results, not with the description
    a = profile_from_dict({"name": "x", "description": "a"})
    assert a.config_hash() == profile_from_dict({"name": "x", "description": "b"}).config_hash()
    assert a.config_hash() != profile_from_dict({"name": "x", "seed": 1}).config_hash()


def test_profile_names_are_checked_against_the_registries(monkeypatch):
    import dataclasses

    from fenestra.bench.runner import plan_methods
    from fenestra.pipeline.reconstruct import POSES
    from fenestra.pipeline.snappers import SNAPPERS
    from fenestra.renders.backends import RENDERERS

    snappers = list(SNAPPERS)
    with pytest.raises(ProfileError, match=rf"x: methods.snappers: unknown snapper 'sift'; choose from "
                                           rf"{re.escape(str(snappers))}"):
        profile_from_dict({"name": "x", "methods": {"snappers": ["none", "sift"]}}, where="x")
    with pytest.raises(ProfileError, match=rf"render.renderer has bad value 'povray'; registered: "
                                           rf"{re.escape(str(list(RENDERERS)))}"):
        profile_from_dict({"name": "x", "render": {"renderer": "povray"}})
    # K withheld is a typed field of the method, not a '+noK' name
    with pytest.raises(ProfileError, match=r"methods.pose_solvers: unknown pose strategy 'wall\+noK'"):
        profile_from_dict({"name": "x", "methods": {"pose_solvers": ["wall+noK"]}})
    with pytest.raises(ProfileError, match=r"methods.detectors: unknown detector 'all'"):
        profile_from_dict({"name": "x", "methods": {"detectors": ["all", "oracle"]}})
    with pytest.raises(ProfileError, match="methods.detectors: empty detector selection"):
        profile_from_dict({"name": "x", "methods": {"detectors": []}})
    with pytest.raises(ProfileError, match=r"methods.pose_solvers: unknown capability \['round'\]"):
        profile_from_dict({"name": "x", "methods": {"pose_solvers": {"round": True}}})
    with pytest.raises(ProfileError, match=r"methods.withhold_K must be"):
        profile_from_dict({"name": "x", "methods": {"withhold_K": []}})
    # selection by capability: per-window solvers, and K withheld only where the strategy fits f
    p = profile_from_dict({"name": "x", "methods": {"pose_solvers": {"per_wall": False}, "snappers": ["none"]}})
    assert [m.pose for m in plan_methods(p)[0]] == POSES.where(per_wall=False) == ["lm", "ippe"]
    p = profile_from_dict({"name": "x", "methods": {"pose_solvers": ["lm", "wall"], "snappers": ["none"],
                                                    "withhold_K": [False, True]}})
    assert [m.label for m in plan_methods(p)[0]] == ["oracle/none/lm", "oracle/none/wall", "oracle/none/wall+noK"]
    # a strategy registered anywhere is accepted (and run by ["all"]) with no edit to bench/
    monkeypatch.setitem(SNAPPERS, "tmp", dataclasses.replace(SNAPPERS["none"], name="tmp"))
    assert profile_from_dict({"name": "x", "methods": {"snappers": ["tmp"]}}).methods.snappers == ("tmp",)


def test_suggested_gates_pass_their_own_run_and_catch_a_worse_one(run_dir, tmp_path):
    summary = results.summarize(results.load_results(run_dir))
    text = gates.suggest_gates(summary, "synthetic", margin=0.5)
    p = tmp_path / "g.toml"
    p.write_text(text)
    g = gates.load_gates(p)
    assert {x.method for x in g} >= {"oracle/*/*", "oracle/good/*", "oracle/bad/*"}
    assert gates.check(run_dir, g) == []
    # the same windows with every snapped error doubled break the snapped-error ceilings
    worse = results.load_results(run_dir)
    worse["corner_err_px_snap"] *= 2.0
    v = gates.check_results(results.summarize(worse), "synthetic", g)
    assert any(x.metric == "corner_err_px_snap.median" and x.method == "oracle/good/lm" for x in v)


@pytest.mark.slow
def test_cli_bench_smoke_then_gate(tmp_path):
    out = tmp_path / "smoke"
    r = subprocess.run([sys.executable, "-m", "fenestra", "bench", "--profile", "smoke", "--out", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "wall time" in r.stdout and "report:" in r.stdout
    r = subprocess.run([sys.executable, "-m", "fenestra", "gate", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr


def test_gates_suggested_from_several_runs_take_the_worst(run_dir, tmp_path):
    """Several runs (seeds) suggest bounds from the worst run: a run twice as bad passes the gates of
    both runs and breaks those of the good run alone."""
    good = results.summarize(results.load_results(run_dir))
    worse_df = results.load_results(run_dir)
    worse_df["corner_err_px_snap"] *= 2.0
    worse = results.summarize(worse_df)
    one, both = tmp_path / "one.toml", tmp_path / "both.toml"
    one.write_text(gates.suggest_gates(good, "synthetic", margin=0.0))
    both.write_text(gates.suggest_gates([good, worse], "synthetic", margin=0.0))
    assert "(2 runs, the worst sets each bound)" in both.read_text()
    assert gates.check_results(worse, "synthetic", gates.load_gates(both)) == []
    assert gates.check_results(good, "synthetic", gates.load_gates(both)) == []
    broken = gates.check_results(worse, "synthetic", gates.load_gates(one))
    assert any(v.metric == "corner_err_px_snap.median" for v in broken)
