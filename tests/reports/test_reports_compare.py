"""`fenestra compare RUN_A RUN_B` on run folders written by the bench's own writers (results,
manifest, summary) from a synthetic table, with changes injected into run B: the expected numbers
are computed here from the two tables with numpy and scipy, not by fenestra.reports.compare."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import wilcoxon
from typer.testing import CliRunner

from fenestra.app.cli import app
from fenestra.bench import manifest, results
from fenestra.conventions import DEFAULTS
from fenestra.reports.compare import CompareError, compare_runs
from fenestra.tolerances import TOL
from synthetic_results import synthetic_results
from test_reports_browser import PAGE_STATE, Browser, find_browser

ROOT = Path(__file__).resolve().parents[2]
CLI = DEFAULTS.label
OTHER = "oracle/bad/lm"


def _base() -> pd.DataFrame:
    """A synthetic table whose snapper "good" rows are labelled as the CLI's method."""
    df = synthetic_results(n_windows=120, seed=3)
    good = df["snapper"] == "good"
    df.loc[good, ["detector", "snapper", "pose", "method"]] = [DEFAULTS.detector, DEFAULTS.snapper, DEFAULTS.pose, CLI]
    return df


def _write(d: Path, df: pd.DataFrame, profile: str = "synthetic", commit: str = "a" * 40) -> Path:
    """A run folder as the bench writes it (table, manifest, summary with commit and config hash)."""
    results.write_results(df, d)
    manifest.seal(d, df, profile)
    results.write_summary(d, {"profile": profile, "seed": 3, "commit": commit, "config_hash": commit[:8]},
                          results.summarize(df), {})
    return d


def _idx(df: pd.DataFrame) -> pd.Series:
    return df["window_id"].str[1:].astype(int)


def _paired(a: pd.DataFrame, b: pd.DataFrame, method: str, col: str) -> tuple[np.ndarray, np.ndarray]:
    """Values of col of one method, evaluable, with a value in both tables, by window id."""
    sa = a[(a.method == method) & a.evaluable].set_index("window_id")[col]
    sb = b[(b.method == method) & b.evaluable].set_index("window_id")[col]
    j = pd.concat([sa.rename("a"), sb.rename("b")], axis=1, join="inner").dropna()
    return j["a"].to_numpy(), j["b"].to_numpy()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A (baseline); B: the CLI method's corner error worse by 0.01 px x window index on even
    windows, window w5 failed, snapper "bad" halved; C: A from another commit; D: the CLI method
    worse by 0.03 px everywhere (significant, under the tolerance); E: another profile."""
    root = tmp_path_factory.mktemp("compare")
    a = _base()
    b = a.copy()
    cli, i = b.method == CLI, _idx(b)
    worse = cli & (i % 2 == 0)
    b.loc[worse, "corner_err_px_snap"] += 0.01 * i[worse]
    b.loc[cli & (b.window_id == "w5"), ["corner_err_px_snap", "aspect_err_rel", "rot_err_deg"]] = np.nan
    b.loc[b.method == OTHER, "corner_err_px_snap"] *= 0.5
    d = a.copy()
    d.loc[d.method == CLI, "corner_err_px_snap"] += 0.03
    paths = {"A": _write(root / "A", a), "B": _write(root / "B", b, commit="b" * 40),
             "C": _write(root / "C", a.copy(), commit="c" * 40), "D": _write(root / "D", d, commit="d" * 40),
             "E": _write(root / "E", a.copy(), profile="smoke")}
    assert not a.loc[(a.method == CLI) & (a.window_id == "w5"), "corner_err_px_snap"].isna().any()
    return paths, a, b, d


def _change(c, method, column):
    (ch,) = [x for x in c.changes if x.method == method and x.metric.column == column]
    return ch


def test_changes_are_the_paired_medians_p90s_and_wilcoxon(runs):
    paths, a, b, _ = runs
    c = compare_runs(paths["A"], paths["B"])
    for method in (CLI, OTHER):
        for col in ("corner_err_px_snap", "aspect_err_rel", "rot_err_deg"):
            x, y = _paired(a, b, method, col)
            ch = _change(c, method, col)
            assert ch.n == x.size > 50
            assert ch.median_a == pytest.approx(np.median(x)) and ch.median_b == pytest.approx(np.median(y))
            assert ch.p90_a == pytest.approx(np.percentile(x, 90)) and ch.p90_b == pytest.approx(np.percentile(y, 90))
            assert ch.worse == pytest.approx(np.mean(y > x)) and ch.better == pytest.approx(np.mean(y < x))
            if np.any(x != y):
                assert ch.p_value == pytest.approx(wilcoxon(y, x).pvalue)
            else:
                assert np.isnan(ch.p_value)
    corner = _change(c, CLI, "corner_err_px_snap")
    assert corner.lost == 1 and corner.gained == 0  # w5 failed in B
    assert corner.worse > 0.4 and corner.better == 0 and corner.regressed
    assert _change(c, OTHER, "corner_err_px_snap").better == 1.0
    assert not _change(c, OTHER, "corner_err_px_snap").regressed  # significant, but better


def test_the_windows_that_changed_most_are_listed_with_their_views(runs):
    paths, a, b, _ = runs
    c = compare_runs(paths["A"], paths["B"])
    x = a[(a.method == CLI) & a.evaluable].set_index("window_id")
    y = b[(b.method == CLI) & b.evaluable].set_index("window_id")
    d = (y.corner_err_px_snap - x.corner_err_px_snap).dropna()
    expected = d.abs().sort_values(ascending=False, kind="stable").index[:10]
    assert list(c.top["window_id"]) == list(expected)
    assert list(c.top["view"]) == list(x.loc[expected, "view"])
    assert c.top["change"].to_numpy() == pytest.approx(d[expected].to_numpy())


def test_cli_exits_1_on_a_regression_of_the_cli_method_and_writes_the_page(runs, tmp_path):
    paths, *_ = runs
    page = tmp_path / "cmp.html"
    r = CliRunner().invoke(app, ["compare", str(paths["A"]), str(paths["B"]), "--html", str(page)])
    assert r.exit_code == 1, r.output
    assert f"REGRESSION of {CLI}: corner error median" in r.output
    assert "commit aaaaaaaaaaaa" in r.output and "commit bbbbbbbbbbbb" in r.output  # runs of two commits
    text = page.read_text()
    assert "<h1>Fenestra run comparison</h1>" in text and "REGRESSION" in text
    # the other method is the gated one: it got better, so no regression
    r = CliRunner().invoke(app, ["compare", str(paths["A"]), str(paths["B"]), "--method", OTHER,
                                 "--html", str(page)])
    assert r.exit_code == 0, r.output
    assert f"No significant regression of {OTHER}" in r.output


def test_no_change_and_a_change_under_the_tolerance_pass(runs, tmp_path):
    paths, a, _, d = runs
    r = CliRunner().invoke(app, ["compare", str(paths["A"]), str(paths["C"]), "--html", str(tmp_path / "c.html")])
    assert r.exit_code == 0, r.output
    assert "No significant regression" in r.output
    c = compare_runs(paths["A"], paths["D"])
    ch = _change(c, CLI, "corner_err_px_snap")
    x, y = _paired(a, d, CLI, "corner_err_px_snap")
    assert ch.d_median == pytest.approx(np.median(y) - np.median(x)) == pytest.approx(0.03)
    assert ch.p_value < TOL.compare_p_value and ch.d_median < TOL.compare_corner_px
    assert not ch.regressed and c.regressions == []


def test_runs_of_different_profiles_are_refused_with_one_line(runs):
    paths, *_ = runs
    with pytest.raises(CompareError, match="profile 'smoke'"):
        compare_runs(paths["A"], paths["E"])
    r = subprocess.run([sys.executable, "-m", "fenestra", "compare", str(paths["A"]), str(paths["E"])],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "'smoke'" in lines[0] and "'synthetic'" in lines[0]


def test_the_page_loads_in_chromium_with_its_figure(runs, tmp_path):
    paths, *_ = runs
    page = tmp_path / "compare.html"
    CliRunner().invoke(app, ["compare", str(paths["A"]), str(paths["B"]), "--html", str(page)])
    b = Browser(find_browser(), tmp_path / "chromium-profile", PAGE_STATE)
    try:
        state = b.open(page.as_uri())
    finally:
        b.close()
    assert state["readyState"] == "complete" and state["h1"] == "Fenestra run comparison"
    assert [(i["id"], i["complete"], i["width"] > 0) for i in state["images"]] == [("compare_corners", True, True)]
    assert state["external"] == [] and state["details"] >= 2 and state["openDetails"] == 0
