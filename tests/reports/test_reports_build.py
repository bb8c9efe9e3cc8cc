"""reports.build on a synthetic results table (bench.synthetic: snapper "good" halves the mask-fit
error, "bad" adds to it), so the report's statements can be checked against known structure; a
second synthetic table stands for a real-photo run where the order is reversed."""
from __future__ import annotations

import ast
import base64
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import wilcoxon
from typer.testing import CliRunner

from fenestra.bench import manifest, results
from fenestra.bench.real.simreal import write_simreal
from synthetic_results import synthetic_results
from fenestra.reports.build import build_report, paired_comparison
from fenestra.reports.lead import SIM_METRIC, ranks

ROOT = Path(__file__).resolve().parents[2]
REAL_SNAP = {"good": (1.4, 0.5), "bad": (0.7, 0.0)}  # on the "photos", bad is the better snapper


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    df = synthetic_results(n_windows=80, seed=3)
    results.write_results(df, d)
    manifest.seal(d, df, "synthetic")
    results.write_summary(d, {"profile": "synthetic", "seed": 3}, results.summarize(df),
                          {"oracle": {"bbox_AP": 0.9, "segm_AP": 0.8, "n_gt": 80}})
    html, md = build_report(d)
    return d, df, html, md


def test_report_files_and_embedded_images(built):
    d, _, html, md = built
    text = html.read_text()
    imgs = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)
    # lead + fig8 for two methods + recall + conditions + aspect/rotation
    assert len(imgs) == 6
    assert all(base64.b64decode(i)[:8] == b"\x89PNG\r\n\x1a\n" for i in imgs)
    assert "src=\"figures/" not in text  # self-contained
    mdt = md.read_text()
    for ref in re.findall(r"\]\((figures/[^)]+\.png)\)", mdt):
        assert (d / ref).is_file()
    assert "Detection (COCO)" in mdt and "0.90" in mdt


def test_report_says_which_snapper_is_best(built):
    _, _, _, md = built
    mdt = md.read_text()
    assert "the best snapper is **good**" in mdt
    assert "The worst snapper, bad" in mdt


def test_paired_comparison_matches_scipy(built):
    _, df, _, _ = built
    c = paired_comparison(df, "oracle/good/lm", "oracle/bad/lm")
    ev = df[df.evaluable]
    a = ev[ev.method == "oracle/good/lm"].set_index("window_id").corner_err_px_snap
    b = ev[ev.method == "oracle/bad/lm"].set_index("window_id").corner_err_px_snap
    ok = a.notna() & b.notna()
    assert c["n"] == int(ok.sum())
    assert c["median_diff"] == pytest.approx(np.median(a[ok] - b[ok]))
    assert c["p_value"] == pytest.approx(wilcoxon(a[ok], b[ok]).pvalue)
    assert c["a_better"] == 1.0  # good = 0.5 e < bad = 1.5 e + 1 for every window


def test_report_of_missing_folder_is_clear(tmp_path):
    with pytest.raises(FileNotFoundError, match="not a run folder"):
        build_report(tmp_path)


# ---------------------------------------------------------------- the lead: one figure, the answer

def _write_run(d: Path, df, profile: str, kind: str | None = None) -> Path:
    results.write_results(df, d)
    manifest.seal(d, df, profile)
    results.write_summary(d, {"profile": profile, "seed": 0, **({"kind": kind} if kind else {})},
                          results.summarize(df), {})
    return d


def _snap(df, snapper):
    """Snapped corner errors of one snapper's evaluable rows with a value (independent of reports)."""
    ev = df[df.evaluable & (df.snapper == snapper)]
    return ev.set_index("window_id").corner_err_px_snap.dropna()


@pytest.fixture(scope="module")
def with_real(tmp_path_factory):
    """A synthetic run and a "real-photo" run (kind real) whose snapper order is reversed; the
    synthetic run's report made by the CLI with --real."""
    from fenestra.app.cli import app

    root = tmp_path_factory.mktemp("lead")
    sim_df = synthetic_results(n_windows=80, seed=3)
    real_df = synthetic_results(n_windows=40, seed=9, snap_factor=REAL_SNAP)
    sim = _write_run(root / "sim", sim_df, "synthetic")
    real = _write_run(root / "real", real_df, "real-synthetic", kind="real")
    r = CliRunner().invoke(app, ["report", str(sim), "--real", str(real)])
    assert r.exit_code == 0, r.output
    return sim, sim_df, real, real_df


def test_report_leads_with_the_ranked_figure_then_folds_the_details(built):
    d, _, html, md = built
    text = html.read_text()
    first_img = text.index("<img ")
    assert text[first_img:].startswith('<img id="lead_ranked"')
    assert text.index("<h2>Which method is best</h2>") < first_img < text.index("<details>")
    mdt = md.read_text()
    n_h2 = len(re.findall(r"^## ", mdt, flags=re.M))
    assert text.count("<details><summary><h2>") == n_h2 - 1  # every h2 but the lead's is folded
    assert text.count("<details>") == text.count("</details>")
    assert mdt.index("![lead_ranked](figures/lead_ranked.png)") < mdt.index("## What this means")
    assert (d / "figures" / "lead_ranked.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "No real-photo run is part of this report" in mdt


def test_lead_ranks_are_the_medians_and_p90s_of_the_table(built):
    _, df, _, _ = built
    (rk,) = ranks(df, SIM_METRIC).values()
    assert [r.snapper for r in rk] == ["good", "bad"]
    for r in rk:
        e = _snap(df, r.snapper).to_numpy()
        assert r.median == pytest.approx(np.median(e)) and r.p90 == pytest.approx(np.percentile(e, 90))
        assert r.n == e.size


def test_lead_answer_says_what_is_best_and_by_how_much(built):
    _, df, _, md = built
    mdt = md.read_text()
    good, bad = _snap(df, "good"), _snap(df, "bad")
    diff = (bad - good).dropna()
    assert (f"Renders, detector **oracle**: **good** is best, median {np.median(good):.2f} px "
            f"(p90 {np.percentile(good, 90):.2f} px, {good.size} windows)") in mdt
    assert (f"The runner-up, bad ({np.median(bad):.2f} px), is clearly worse: on the same {diff.size} windows "
            f"the median of bad - good is {np.median(diff):.2f} px and bad is better on 0 % of them") in mdt


def test_real_run_fills_the_photo_column_and_the_answer(with_real):
    sim, _, real, real_df = with_real
    mdt = (sim / "report.md").read_text()
    good, bad = _snap(real_df, "good"), _snap(real_df, "bad")
    assert f"Real photos: {real}." in mdt
    assert (f"Real photos, detector **oracle**, by snapped corner error: **bad** is best, median "
            f"{np.median(bad):.2f} px (p90 {np.percentile(bad, 90):.2f} px, {bad.size} windows); by the same "
            f"error renders choose good, which ranks 2 of 2 here and costs "
            f"{np.median(good) - np.median(bad):.2f} px in median") in mdt



def _png_width(path: Path) -> int:
    return int.from_bytes(path.read_bytes()[16:20], "big")  # IHDR width


def test_photo_column_widens_the_lead_figure(built, with_real):
    """Renders only: one column of panels; with a real run: renders and photos side by side."""
    one, two = _png_width(built[0] / "figures" / "lead_ranked.png"), _png_width(with_real[0] / "figures" / "lead_ranked.png")
    assert 1.6 * one < two < 2.4 * one


def test_real_run_report_finds_its_synthetic_counterpart(with_real):
    sim, sim_df, real, _ = with_real
    write_simreal(sim, real)
    mdt = build_report(real)[1].read_text()
    assert f"Renders: {sim}. Real photos: this run." in mdt
    assert f"Renders, detector **oracle**: **good** is best, median {np.median(_snap(sim_df, 'good')):.2f} px" in mdt


def test_real_dir_must_be_a_real_photo_run(with_real):
    sim, _, real, _ = with_real
    with pytest.raises(ValueError, match="not a real-photo run folder"):
        build_report(sim, real_dir=sim)
    with pytest.raises(ValueError, match="is itself a real-photo run"):
        build_report(real, real_dir=real)


# ---------------------------------------------------------------- import direction

def _imports(path: Path) -> list[str]:
    """Absolute module names imported anywhere in a file (function bodies included)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out += [node.module] + [f"{node.module}.{a.name}" for a in node.names]
    return out


REPORTS_READ_FROM_BENCH = {"fenestra.bench.results", "fenestra.bench.manifest", "fenestra.bench.paired",
                           "fenestra.bench.real.simreal"}
PKG = ROOT / "fenestra"


def _floor(name: str) -> str:
    """The floor of an imported module: "bench" for fenestra.bench.x, "" outside a floor."""
    parts = name.split(".")
    return parts[1] if parts[0] == "fenestra" and len(parts) > 1 else ""


def test_bench_and_reports_do_not_import_each_other():
    """The data flows bench -> reports: reports read bench's tables through its results contract
    (REPORTS_READ_FROM_BENCH), bench never imports reports, and only the CLI's composition root
    (fenestra/app/cli.py) joins them."""
    for path in sorted((PKG / "bench").rglob("*.py")):
        assert not [n for n in _imports(path) if _floor(n) == "reports"], f"{path} imports reports"
    for path in sorted((PKG / "reports").rglob("*.py")):
        # a package on the way to an allowed module ("from fenestra.bench import paired" names it) is fine
        bad = sorted(m for m in _imports(path) if _floor(m) == "bench" and not any(
            m == a or m.startswith(a + ".") or a.startswith(m + ".") for a in REPORTS_READ_FROM_BENCH))
        assert not bad, f"{path} imports {bad}; reports read bench only through {sorted(REPORTS_READ_FROM_BENCH)}"
    importers = {p.relative_to(ROOT).as_posix() for p in PKG.rglob("*.py")
                 if not p.is_relative_to(PKG / "reports") and any(_floor(n) == "reports" for n in _imports(p))}
    assert importers == {"fenestra/app/cli.py"}


def test_bench_refuses_a_real_dir_that_is_not_a_real_run_before_running(with_real):
    """fenestra bench --real checks the folder before rendering anything (a synthetic run is refused)."""
    from fenestra.app.cli import app

    sim, _, _, _ = with_real
    r = CliRunner().invoke(app, ["bench", "--profile", "smoke", "--real", str(sim), "--no-report"])
    assert isinstance(r.exception, ValueError) and "not a real-photo run" in str(r.exception)


def test_report_of_box_only_photos_with_the_oracle_only(tmp_path):
    """A real run whose photos are labelled with boxes and whose only detector is the oracle has
    no evaluable row (the oracle needs masks): its report is still written, and says so."""
    from fenestra.bench.real.profile import real_profile_from_dict
    from fenestra.bench.runner import run_benchmark
    from fenestra.reports.cli import write_report
    from user_datasets import curtain_panes, write_yolo

    n = write_yolo(tmp_path / "boxes", curtain_panes(1))
    prof = real_profile_from_dict({
        "name": "boxes", "kind": "real",
        "methods": {"detectors": ["oracle"], "snappers": ["none", "hough"], "pose_solvers": ["lm"]},
        "datasets": [{"name": "boxes", "format": "yolo", "path": str(tmp_path / "boxes")}]})
    info = run_benchmark(prof, out_dir=tmp_path / "run", progress=False, report=write_report)
    df = results.load_results(info.run_dir)
    assert len(df) == 2 * n > 0 and not df["evaluable"].any()
    md = (info.run_dir / "report.md").read_text()
    assert f"{2 * n} rows (2 method combinations); 0 are evaluable" in md
    assert "With detector oracle, no corner error was measured" in md
    assert (info.run_dir / "report.html").is_file() and (info.run_dir / "figures" / "recall_curves.png").is_file()


def test_second_report_reuses_every_figure_and_redraws_changed_ones(tmp_path):
    """A report of an unchanged run draws no figure again (the lead figure included) and writes
    the same report.md; a run whose snapped errors changed gets those figures drawn anew."""
    df = synthetic_results(n_windows=30, seed=5)
    results.write_results(df, tmp_path)
    manifest.seal(tmp_path, df, "synthetic")
    _, md = build_report(tmp_path)
    figs = tmp_path / "figures"
    first = {p.name: p.stat().st_mtime_ns for p in figs.glob("*.png")}
    text = md.read_text()
    assert "lead_ranked.png" in first and len(first) > 3
    _, md = build_report(tmp_path)
    assert {p.name: p.stat().st_mtime_ns for p in figs.glob("*.png")} == first and md.read_text() == text
    df["corner_err_px_snap"] = df["corner_err_px_snap"] * 2
    results.write_results(df, tmp_path)
    manifest.seal(tmp_path, df, "synthetic")
    build_report(tmp_path)
    again = {p.name: p.stat().st_mtime_ns for p in figs.glob("*.png")}
    assert again.keys() == first.keys()
    assert again["lead_ranked.png"] != first["lead_ranked.png"] and again["recall_curves.png"] != first["recall_curves.png"]
    assert again["aspect_rotation.png"] == first["aspect_rotation.png"]  # aspect and rotation did not change


def test_figure8_has_the_papers_method_though_it_never_runs_the_main_pose():
    """One figure 8 per detector x snapper: under the main pose where the pair ran it, else under
    its own pose (the paper's harris runs under lm only)."""
    import pandas as pd

    from fenestra.reports import build, plots

    rows = [("default", "refine", "wall+lines"), ("default", "harris", "wall+lines"), ("default", "harris", "lm"),
            ("maskrcnn", "harris", "lm"), ("maskrcnn", "refine", "wall+lines")]
    df = pd.DataFrame([{"detector": d, "snapper": s, "pose": p, "method": f"{d}/{s}/{p}"} for d, s, p in rows])
    assert plots.main_pose(df) == "wall+lines"
    got = [m for m, _ in build.figure8_groups(df)]
    assert got == ["default/harris/wall+lines", "default/refine/wall+lines", "maskrcnn/harris/lm",
                   "maskrcnn/refine/wall+lines"]
