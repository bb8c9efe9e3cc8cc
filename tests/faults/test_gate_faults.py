"""Gates see dropped samples: a results table missing rows, methods or values, or its manifest, is refused.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from fenestra.bench import manifest

from fault_helpers import (TINY_GATES, TINY_PROFILE, fenestra, one_line_error, view_dirs)


# ---------------------------------------------------------------- 1. gates see dropped samples

@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    """A complete tiny benchmark run (3 views, oracle x 2 snappers) and its gates file."""
    d = tmp_path_factory.mktemp("bench")
    (d / "tiny.toml").write_text(TINY_PROFILE)
    (d / "gates.toml").write_text(TINY_GATES)
    r = fenestra("bench", "--profile", "tiny.toml", "--out", "run", "--workers", "1", cwd=d)
    assert r.returncode == 0, r.stderr[-3000:]
    ok = fenestra("gate", "run", "--gates", "gates.toml", cwd=d)
    assert ok.returncode == 0 and "all gates passed" in ok.stdout, ok.stderr
    return d


def tampered(bench_run: Path, name: str, edit) -> Path:
    """A copy of the run whose results.parquet went through ``edit(df) -> df``."""
    dst = bench_run / name
    shutil.copytree(bench_run / "run", dst)
    df = edit(pd.read_parquet(dst / "results.parquet"))
    df.to_parquet(dst / "results.parquet", index=False)
    return dst


def test_gate_refuses_a_table_missing_a_method(bench_run):
    run = tampered(bench_run, "no-linefit", lambda df: df[df.method != "oracle/linefit/lm"])
    n = json.loads((bench_run / "run" / "manifest.json").read_text())["n_rows"] // 2
    line = one_line_error(fenestra("gate", run.name, "--gates", "gates.toml", cwd=bench_run),
                          f"lacks {n} of {2 * n} expected rows", f"oracle/linefit/lm: {n}")
    assert "oracle/none/lm" not in line
    one_line_error(fenestra("report", run.name, cwd=bench_run), f"lacks {n} of {2 * n}")


def test_gate_refuses_a_table_missing_single_windows(bench_run):
    def drop_worst(df):  # the two worst evaluable rows of one method, as a cherry-picker would
        worst = df[df.method == "oracle/none/lm"].sort_values("corner_err_px_snap").index[-2:]
        return df.drop(index=worst)
    run = tampered(bench_run, "no-worst", drop_worst)
    one_line_error(fenestra("gate", run.name, "--gates", "gates.toml", cwd=bench_run),
                   "lacks 2 of", "oracle/none/lm: 2")


def test_gate_refuses_overwritten_values(bench_run):
    def hide_errors(df):
        df = df.copy()
        df["status"] = "ok"
        df["corner_err_px_snap"] = df["corner_err_px_snap"].fillna(0.0) * 0.5
        return df
    run = tampered(bench_run, "edited", hide_errors)
    one_line_error(fenestra("gate", run.name, "--gates", "gates.toml", cwd=bench_run),
                   "results.parquet was modified after the run")


def test_gate_refuses_a_run_without_manifest(bench_run):
    run = tampered(bench_run, "no-manifest", lambda df: df)
    (run / "manifest.json").unlink()
    one_line_error(fenestra("gate", run.name, "--gates", "gates.toml", cwd=bench_run), "no manifest.json")


def test_manifest_lists_every_gt_window_of_every_view(bench_run):
    """Expected rows = each view.json's windows x methods, computed here from the renders."""
    m = manifest.load_manifest(bench_run / "run")
    want = sorted([("fzk-haus", v.name, str(w["id"]), meth) for v in view_dirs(bench_run)
                   for w in json.loads((v / "view.json").read_text())["windows"]
                   for meth in ("oracle/none/lm", "oracle/linefit/lm")])
    assert sorted(m["rows"]) == want and m["n_rows"] == len(want) > 0
    # stored compactly (each view's windows, the methods), and only the Parquet table is written
    assert "rows" not in json.loads((bench_run / "run" / "manifest.json").read_text())
    assert set(m["sha256"]) == {"results.parquet"} and not (bench_run / "run" / "results.csv").exists()


def test_manifest_rows_compact_form_round_trips_and_falls_back_to_rows():
    views = [("h", "000", ["w1", "w2"]), ("h", "001", ["w3"]), ("g", "000", ["w1"])]
    product = [(h, v, w, m) for h, v, ws in views for w in ws for m in ("a/x/lm", "b/y/wall")]
    doc = manifest.compact_rows(product)
    assert doc == {"methods": ["a/x/lm", "b/y/wall"], "views": [list(v) for v in views]}
    assert manifest.expand_rows(doc) == product
    for odd in (product[:-1], product + [product[0]], [product[1], product[0], *product[2:]]):
        doc = manifest.compact_rows(odd)  # not every window x method once, in order: row by row
        assert "views" not in doc and manifest.expand_rows(doc) == odd
    assert manifest.expand_rows(manifest.compact_rows([])) == []


def test_bench_refuses_a_foreign_folder_and_force_leaves_nothing_stale(bench_run):
    foreign = bench_run / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    one_line_error(fenestra("bench", "--profile", "tiny.toml", "--out", "foreign", cwd=bench_run),
                   "not empty", "--force")
    other = bench_run / "other-profile"
    shutil.copytree(bench_run / "run", other)
    (bench_run / "tiny2.toml").write_text(TINY_PROFILE.replace("views_per_house = 3", "views_per_house = 2"))
    one_line_error(fenestra("bench", "--profile", "tiny2.toml", "--out", other.name, "--no-report", cwd=bench_run),
                   "holds a run of profile 'tiny'", "--force")
    r = fenestra("bench", "--profile", "tiny2.toml", "--out", other.name, "--no-report", "--force",
                 "--workers", "1", cwd=bench_run)
    assert r.returncode == 0, r.stderr[-2000:]
    assert not (other / "report.html").exists() and not (other / "figures").exists()  # the old run's
    assert json.loads((other / "run.json").read_text())["profile_hash"] != \
        json.loads((bench_run / "run" / "run.json").read_text())["profile_hash"]
    assert fenestra("gate", other.name, "--gates", "gates.toml", cwd=bench_run).returncode == 0


def test_profile_with_infinite_min_window_px_is_refused(tmp_path):
    (tmp_path / "p.toml").write_text(TINY_PROFILE + "[evaluation]\nmin_window_px = inf\n")
    one_line_error(fenestra("bench", "--profile", "p.toml", cwd=tmp_path), "min_window_px = inf")
    assert not (tmp_path / "out").exists()
