"""bench.timing's generated Markdown block: the figures of a run folder, put between the markers."""
from __future__ import annotations

import json

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import timing  # noqa: E402  (tools/timing.py: a lab script, not installed)


def _run(tmp_path):
    run = tmp_path / "run"
    (run / "figures").mkdir(parents=True)
    (run / "results.parquet").write_bytes(b"x" * 3_000_000)
    (run / "figures" / "a.png").write_bytes(b"y" * 500_000)
    meta = {"profile": "default", "commit": "abcdef0123", "wall_time_s": 123.4, "n_views": 480, "n_rows": 9000,
            "methods": ["a/b/lm", "a/b/wall"], "stage_time_s": {"render": 40.0, "evaluate_wall": 70.0, "summarize": 3.0,
                                                                "cpu.detect": 30.0, "cpu.reconstruct": 90.0},
            "peak_rss_mb": {"main": 900.0, "largest_worker": 1500.0}, "load_average": {"before": [0.5, 0, 0],
                                                                                       "after": [1.0, 0, 0]}}
    (run / "summary.json").write_text(json.dumps({"metadata": meta}))
    return run


def test_block_holds_the_run_figures_and_replaces_only_its_markers(tmp_path):
    run = _run(tmp_path)
    doc = timing.from_run(run)
    r = doc["run"]
    assert r["artefact_mb"]["figures"] == 0.5 and r["artefact_mb"]["total"] > 3.5
    assert r["cpu_s"] == {"detect": 30.0, "reconstruct": 90.0} and r["share"]["reconstruct"] == 0.75
    block = timing.markdown(doc, "python tools/timing.py --from-run run")
    assert "| one run | abcdef0 | 480 | 2 | 9000 | **123 s** | 40 s | 70 s | 3.0 s | - | 1.46 GB |" in block
    assert "reconstruct 90 s (75 %), detect 30 s (25 %)" in block and "`python tools/timing.py --from-run run`" in block
    md = tmp_path / "perf.md"
    md.write_text(f"# Title\n\nbefore\n\n{timing.BEGIN}\nold figures\n{timing.END}\n\nafter\n")
    timing.write_markdown(md, block)
    text = md.read_text()
    assert text == f"# Title\n\nbefore\n\n{block}\n\nafter\n" and "old figures" not in text
    log = tmp_path / "time.log"
    log.write_text("\tMaximum resident set size (kbytes): 2097152\n")
    assert timing.from_run(run, log)["run"]["peak_rss_mb"] == {"any_process (time -v)": 2048.0}


def test_fresh_clone_row_and_agreement_with_the_cold_run(tmp_path):
    fig = timing.from_run(_run(tmp_path))["run"]
    doc = {"profile": "default", "cpus": 2, "cold": {**fig, "wall_s": 200.0}, "fresh_clone": {**fig, "wall_s": 226.0}}
    assert timing.agreement(doc) == {"ratio": 1.13, "within": True, "limit": 0.15}
    block = timing.markdown(doc, "python tools/timing.py --fresh-clone c")
    assert "| `git clone`, `make setup`, then `/usr/bin/time make bench` | abcdef0 | 480 | 2 | 9000 | **226 s** |" in block
    assert "1.13 x the wall time (within the +-15 %" in block
    doc["fresh_clone"]["wall_s"] = 240.0  # 1.20: outside
    assert not timing.agreement(doc)["within"] and "**outside**" in timing.markdown(doc, "c")
    assert timing.agreement({"cold": fig}) is None


def test_floor_is_the_detectors_and_the_marginal_render_of_every_view_and_the_ratio_its_multiple(tmp_path):
    """The floor of a run: every learned detector's CPU seconds per view plus the marginal render's,
    times the run's views; the ratio: the CPU seconds of the cold run's stages (its renders'
    included) over it. By hand: 480 views x (0.2 + 0.05 + 0.05) = 144 CPU-s; the cold run's 30 + 90
    + render 24 = 144 CPU-s: 1.00. Its block has its own markers: the timing block stays."""
    fig = timing.from_run(_run(tmp_path))["run"]
    cold = {**fig, **timing.stage_split({"metadata": {"stage_time_s": {**fig["stage_time_s"], "cpu.render": 24.0}}})}
    doc = {"profile": "default", "cpus": 2, "cached_renders": fig, "cold": cold,
           "detector_cost": {"views": 12, "cpu_s_per_view": {"default": 0.2, "maskrcnn": 0.05}},
           "render": {"scene": "fzk-haus", "wall_s": {"10": 1.0, "60": 2.0}, "s_per_view": 0.02, "views_per_s": 50.0,
                      "cpu_s_per_view": 0.05}}
    fl = timing.floor(doc)
    assert fl["floor_cpu_s"] == {"detect": 480 * 0.25, "render": 480 * 0.05}
    assert abs(fl["floor_total_cpu_s"] - 144.0) < 1e-9 and fl["bench_cpu_s"] == 144.0 and abs(fl["ratio"] - 1.0) < 1e-9
    block = timing.floor_markdown(doc, "python tools/timing.py")
    assert block.startswith(timing.FLOOR_BEGIN) and block.endswith(timing.FLOOR_END)
    assert "| detector `default`, per view (12 views) | 0.200 |" in block and "| **floor**: detect 120 + render 24 | **144** |" in block
    assert "(reconstruct 90, detect 30, render 24) | 144 |" in block and "| **ratio** of the run to its floor | **1.00** |" in block
    assert "0.050 CPU-s per view" in timing.markdown(doc, "c")
    assert timing.floor({**doc, "detector_cost": None}) is None and timing.floor_markdown({**doc, "render": None}, "c") is None
    md = tmp_path / "perf.md"
    md.write_text(f"a\n{timing.BEGIN}\nrun figures\n{timing.END}\nb\n{timing.FLOOR_BEGIN}\nold\n{timing.FLOOR_END}\nc\n")
    timing.write_markdown(md, block, timing.FLOOR_BEGIN, timing.FLOOR_END)
    assert md.read_text() == f"a\n{timing.BEGIN}\nrun figures\n{timing.END}\nb\n{block}\nc\n"


def test_fresh_clone_must_be_a_clean_clone_of_head(tmp_path):
    import subprocess

    import pytest

    other = tmp_path / "other"
    subprocess.run(["git", "init", "-q", str(other)], check=True)
    (other / "a").write_text("x")
    subprocess.run(["git", "-C", str(other), "add", "a"], check=True)
    subprocess.run(["git", "-C", str(other), "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "a"], check=True)
    with pytest.raises(SystemExit, match=r"--fresh-clone .*other is at [0-9a-f]{7}, this checkout at"):
        timing.check_clone(other)


def test_a_clone_with_outputs_is_refused_and_left_alone(tmp_path):
    """A clone of HEAD that already holds out/ (renders, runs) is no fresh clone: refused before
    anything runs, and nothing in it is deleted."""
    import subprocess

    import pytest

    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", str(timing.ROOT), str(clone)], check=True)
    (clone / ".venv" / "bin").mkdir(parents=True)
    (clone / ".venv" / "bin" / "python").write_text("")
    (clone / "out" / "bench" / "mine").mkdir(parents=True)
    (clone / "out" / "bench" / "mine" / "keep.txt").write_text("a user's file")
    with pytest.raises(SystemExit, match="has an out/ folder"):
        timing.check_clone(clone)
    assert (clone / "out" / "bench" / "mine" / "keep.txt").read_text() == "a user's file"
