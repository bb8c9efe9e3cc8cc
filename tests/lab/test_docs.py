"""The docs say what the code and the committed results say.

- README.md's generated blocks, docs/results.md and docs/DESIGN.md's defaults block are what
  lab.docs renders from the committed docs/results/summary.json (byte for byte);
- the README carries no figure outside its generated blocks;
- the defaults the README and DESIGN.md state are fenestra.conventions.DEFAULTS;
- the generator's figures are the medians of the results table, computed here independently
  (a run written by bench's own writers from bench.synthetic's table).
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from fenestra.bench import manifest, results
from synthetic_results import synthetic_results
from fenestra.conventions import DEFAULTS, PAPER
from lab import docs
from lab.docs import blocks, figures, roles
from lab.docs import text as doc_text

ROOT = Path(__file__).resolve().parents[2]
PATHS = docs.DocPaths.for_markdown(ROOT / "docs" / "results.md")
GENERATED = ("results", "defaults", "detector")
# A figure: a number with a unit of a measurement, or any decimal number (outside code). Licence and
# standard versions ("CC BY 4.0") are names, not figures.
UNIT_FIGURE = re.compile(r"(?<![\w./:-])\d+(?:[.,]\d+)?\s*(?:px|%|°|deg\b|ms\b|s\b|min\b|h\b|GB\b|MB\b|×|x\b|AP\b)")
DECIMAL = re.compile(r"(?<![\w./:-])\d+\.\d+")
NOT_FIGURES = ("CC BY 4.0",)


# ---------------------------------------------------------------- the committed docs

def test_committed_docs_are_what_the_committed_summary_renders():
    assert PATHS.summary.is_file(), "docs/results/summary.json is missing: make docs"
    assert docs.stale(PATHS) == [], "regenerate with `python -m lab.docs` (or `make docs` after a bench run)"


def test_committed_summary_is_small_and_names_its_runs():
    doc = json.loads(PATHS.summary.read_text())
    assert PATHS.summary.stat().st_size < 48_000  # 23 methods of the default profile: about 1.7 kB each
    pv = doc["synthetic"]["provenance"]
    assert pv["profile"] and pv["config_hash"] and pv["commit"] and pv["date"]
    results_md = PATHS.markdown.read_text()
    for key in ("profile", "config_hash", "commit"):
        assert str(pv[key]) in results_md
    assert "python -m lab.docs RUN --real out/bench/real" in results_md


def _outside_generated(text: str) -> str:
    for name in GENERATED:
        text = re.sub(rf"<!-- {name}:begin -->.*?<!-- {name}:end -->", "", text, flags=re.S)
    text = re.sub(r"```.*?```", "", text, flags=re.S)  # code blocks: commands and their arguments
    text = re.sub(r"`[^`]*`", "", text)  # inline code: options, file names, versions
    text = re.sub(r"<[^>]+>", "", text)  # HTML tags (image widths)
    for name in NOT_FIGURES:
        text = text.replace(name, "")
    return text


def test_readme_has_no_figure_outside_its_generated_blocks():
    prose = _outside_generated((ROOT / "README.md").read_text())
    found = UNIT_FIGURE.findall(prose) + DECIMAL.findall(prose)
    assert found == [], f"figures typed by hand in README.md: {found}"


def test_the_figure_check_catches_figures():
    """The check itself: a typed figure outside the blocks is found, the same inside is not."""
    for typed in ("cuts it to 1.39 px", "on 56 % of windows", "median 0.28°", "in 300 s", "AP 42.7"):
        assert UNIT_FIGURE.findall(_outside_generated(typed)) + DECIMAL.findall(_outside_generated(typed))
    inside = "<!-- results:begin -->\n1.39 px, 56 %\n<!-- results:end -->\n`--width 0.0932`, CC BY 4.0"
    assert UNIT_FIGURE.findall(_outside_generated(inside)) + DECIMAL.findall(_outside_generated(inside)) == []


def test_readme_is_a_front_page():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 150
    assert text.count("<img ") == 1
    answer = blocks.block(text, "results")
    assert sum(1 for line in answer.splitlines() if line.startswith("|---")) == 1  # one table
    prose = [p for p in answer.split("\n\n") if p.strip() and not p.lstrip().startswith("|")]
    assert len(prose) == 1  # one paragraph
    for link in re.findall(r"\]\(([^)#]+)\)", text):
        assert (ROOT / link).exists(), link


def _stated_defaults(text: str) -> dict[str, str]:
    """detector/snapper/pose named in a defaults statement (read here, not by the generator)."""
    first = text.split("The paper's method")[0]
    return {k: re.search(rf"{k} `([^`]+)`", first).group(1) for k in ("detector", "snapper", "pose")}


@pytest.mark.parametrize("doc", ["README.md", "docs/DESIGN.md"])
def test_stated_defaults_are_the_code_defaults(doc):
    text = (ROOT / doc).read_text()
    stated = _stated_defaults(blocks.block(text, "defaults"))
    assert stated == {"detector": DEFAULTS.detector, "snapper": DEFAULTS.snapper, "pose": DEFAULTS.pose}
    assert blocks.block(text, "defaults").strip() == doc_text.defaults_text()


def test_design_states_no_other_default_pose():
    """Outside its generated block DESIGN.md names no default pose or snapper of its own."""
    text = re.sub(r"<!-- defaults:begin -->.*?<!-- defaults:end -->", "", (ROOT / "docs/DESIGN.md").read_text(), flags=re.S)
    assert not re.search(r"default[^.]{0,40}\b(pose|snapper)\b[^.]{0,10}`(?!" + re.escape(DEFAULTS.pose) + ")", text)


def test_training_houses_are_make_data_s():
    """TRAINED_ON is the bundled-house loop of lab/scripts/make_data.sh; samplehouse4 held out."""
    script = (ROOT / "lab" / "scripts" / "make_data.sh").read_text()
    houses = tuple(re.search(r"^for house in ([^;]+); do", script, re.M).group(1).split())
    assert all(v == houses for v in roles.TRAINED_ON.values())
    assert "samplehouse4" not in houses and "samplehouse4" in script


# ---------------------------------------------------------------- the generator on a run

def _learned_run(d: Path) -> tuple[Path, "pd.DataFrame"]:  # noqa: F821
    """A synthetic run of the CLI default detector on two houses, one trained on, one held out."""
    df = synthetic_results(n_windows=120, seed=5)
    df["detector"] = DEFAULTS.detector
    df["house"] = np.where(df["window_id"].str[1:].astype(int) % 2 == 0, "fzk-haus", "samplehouse4")
    df["rot_err_deg"] = df["corner_err_px_snap"] * 0.5  # any pose figure, known per row
    df["method"] = df["detector"] + "/" + df["snapper"] + "/" + df["pose"]
    results.write_results(df, d)
    manifest.seal(d, df, "synthetic")
    results.write_summary(d, {"profile": "synthetic", "seed": 5, "config_hash": "abc123", "commit": "f" * 40,
                              "n_views": 30, "datasets": {"fzk-haus": "x", "samplehouse4": "y"}},
                          results.summarize(df), {})
    return d, df


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return _learned_run(tmp_path_factory.mktemp("run"))


def r_pose(doc) -> str:
    """The pose of the per-house table of the CLI default detector."""
    return doc["synthetic"]["per_house"][DEFAULTS.detector]["pose"]


def _median(df, **where) -> float:
    ev = df[df.evaluable.astype(bool)]
    for k, v in where.items():
        ev = ev[ev[k] == v]
    return float(np.median(ev["corner_err_px_snap"].dropna()))


def test_generated_figures_are_the_tables_medians(run, tmp_path):
    d, df = run
    doc = figures.collect(d)
    snap = doc["synthetic"]["snap"][DEFAULTS.detector]
    assert [r["snapper"] for r in snap] == ["good", "bad"]
    for r in snap:
        assert r["median"] == pytest.approx(_median(df, snapper=r["snapper"]), rel=1e-3)
    houses = {r["house"]: r for r in doc["synthetic"]["per_house"][DEFAULTS.detector]["rows"]}
    assert houses["fzk-haus"]["trained"] and not houses["samplehouse4"]["trained"]
    assert houses["held-out families"]["together"] and not houses["samplehouse4"]["together"]
    for h, real in (("fzk-haus", "fzk-haus"), ("samplehouse4", "samplehouse4"), ("held-out families", "samplehouse4"),
                    ("trained-on houses", "fzk-haus")):
        r = houses[h]
        assert r["snap_median"] == pytest.approx(_median(df, snapper="good", house=real), rel=1e-3)
        ev = df[df.evaluable.astype(bool) & (df.snapper == "good") & (df.house == real) & (df.pose == r_pose(doc))]
        close = sum(1 for v in ev["corner_err_px_snap_max"] if v == v and v <= 5.0)  # NaN (no quad) is not close
        assert r["all_corners_close"] == pytest.approx(close / len(ev), abs=1e-3)
        assert r["quad_rate"] == pytest.approx(ev["corner_err_px_snap"].notna().mean(), abs=1e-3)
    table = doc_text.lead_table(doc["synthetic"])
    assert f"**{_median(df, snapper='good'):.2f} px" in table[2]  # the best is bold
    pv = doc["synthetic"]["provenance"]
    assert (pv["profile"], pv["config_hash"], pv["commit"], pv["commit_source"]) == ("synthetic", "abc123", "f" * 12, "run")


def test_a_run_without_the_cli_default_method_says_so(run):
    d, _ = run
    doc = figures.collect(d)
    assert doc["synthetic"]["default_method"] == {"method": f"{DEFAULTS.detector}/{DEFAULTS.snapper}/{DEFAULTS.pose}",
                                                  "in_run": False}
    text = doc_text.answer(doc)
    assert f"`{DEFAULTS.detector}/{DEFAULTS.snapper}/{DEFAULTS.pose}`" in text and "is not part of" in text
    assert "--snapper good --pose lm" in text  # the recommendation: best snapper, best K-known pose


def test_lab_command_writes_the_docs_and_they_render_again_identically(run, tmp_path):
    from lab.docs.__main__ import main

    d, _ = run
    (tmp_path / "docs").mkdir()
    readme = tmp_path / "README.md"
    readme.write_text("# x\n<!-- results:begin -->\n<!-- results:end -->\n<!-- defaults:begin -->\nold\n<!-- defaults:end -->\n")
    assert main([str(d), "--markdown", str(tmp_path / "docs" / "results.md")]) == 0
    paths = docs.DocPaths.for_markdown(tmp_path / "docs" / "results.md")
    assert paths.summary.is_file() and paths.markdown.is_file()
    assert f"pose `{DEFAULTS.pose}`" in blocks.block(readme.read_text(), "defaults")
    assert docs.stale(paths) == []
    readme.write_text(readme.read_text().replace("**", ""))
    assert docs.stale(paths) == [readme]


def test_fill_block_needs_exactly_one_pair():
    with pytest.raises(ValueError, match="'results'"):
        blocks.fill_block("no markers", "results", "x")
    one = "a\n<!-- results:begin -->\nold\n<!-- results:end -->\nb"
    assert blocks.fill_block(one, "results", "new") == "a\n<!-- results:begin -->\nnew\n<!-- results:end -->\nb"
    with pytest.raises(ValueError, match="found 2"):
        blocks.fill_block(one + one, "results", "x")


def test_paper_snapper_is_marked():
    syn = {"snap": {"oracle": [{"snapper": PAPER.snapper, "median": 1.0, "p90": 2.0, "n": 3}]},
           "detection": {"oracle": {"learned": False, "detection_rate": 1.0}}}
    assert f"`{PAPER.snapper}` (paper" in doc_text.lead_table(syn)[0]


@pytest.mark.parametrize("p_value, default_p90, says", [
    (0.001, 2.0, "its worst cases are smaller"),        # recommendation lower on the same windows, default's tails smaller
    (0.001, 3.0, "`fenestra.conventions.DEFAULTS` should follow it"),  # better there too: change DEFAULTS
    (0.4, 3.0, "the default is not worse than"),         # no clear paired difference
])
def test_why_the_cli_keeps_its_default_follows_the_numbers(p_value, default_p90, says):
    d = {"rot_median": 0.26, "rot_p90": default_p90, "aspect_median": 0.032, "aspect_p90": 0.19 * default_p90 / 2}
    rec = {"rot_median": 0.25, "rot_p90": 2.5, "aspect_median": 0.034, "aspect_p90": 0.21}
    c = {"recommended": "default/lsd/building+lines", "n": 866, "median_diff": 0.007, "a_better": 0.46, "p_value": p_value}
    text = doc_text._why_default(c, rec, d)
    assert says in text and "866 windows" in text and "default/lsd/building+lines" in text
    assert doc_text._why_default(None, rec, d) == ""


def test_readme_detector_line_is_the_summary_s_held_out_families():
    """The README's detector block (tools/model_card_real.py --readme) quotes the committed
    summary's held-out-families row of the CLI default detector, and names the real-photo sets."""
    text = blocks.block((ROOT / "README.md").read_text(), "detector")
    doc = json.loads(PATHS.summary.read_text())
    rows = {r["house"]: r for r in doc["synthetic"]["per_house"][DEFAULTS.detector]["rows"]}
    unseen = rows[roles.ROLE_GROUPS["held out"]]
    assert f"corner error median {unseen['snap_median']:.2f} px" in text
    assert f"within 5 px for {100 * unseen['all_corners_close']:.0f} %" in text
    assert "validation photos" in text and "test photos" in text and "tools/model_card_real.py" in text


def _bim_run(d: Path) -> tuple[Path, "pd.DataFrame"]:  # noqa: F821
    """A synthetic run holding the CLI's method with BIM columns whose values are known per row."""
    from fenestra.bench.evaluate import BIM_COLUMNS

    df = synthetic_results(n_windows=60, seed=7)
    df = df[df["snapper"] == df["snapper"].iloc[0]].copy()
    df["detector"], df["snapper"], df["pose"] = DEFAULTS.detector, DEFAULTS.snapper, DEFAULTS.pose
    df["method"] = f"{DEFAULTS.detector}/{DEFAULTS.snapper}/{DEFAULTS.pose}"
    rng = np.random.default_rng(3)
    for c in BIM_COLUMNS:
        df[c] = np.nan
    ok = (df["status"] == "ok").to_numpy()
    df["K_source"] = np.where(ok, "K", None)
    df["scale_source"] = np.where(ok, "assumed", None)
    df["scale_source_storey"] = np.where(ok, np.where(rng.random(len(df)) < 0.25, "assumed", "storey_m"), None)
    df["exported"] = np.where(ok, (rng.random(len(df)) < 0.8).astype(float), np.nan)
    for c in ("width_err_m", "height_err_m", "pos_err_m", "width_err_m_storey", "height_err_m_storey", "pos_err_m_storey"):
        df[c] = np.where(ok, rng.uniform(0.0, 0.5, len(df)), np.nan)
    results.write_results(df, d)
    manifest.seal(d, df, "synthetic")
    results.write_summary(d, {"profile": "synthetic", "seed": 7, "config_hash": "abc124", "commit": "e" * 40,
                              "n_views": 10, "datasets": {"fzk-haus": "x"}}, results.summarize(df), {})
    return d, df


def test_bim_figures_are_the_tables_medians(tmp_path):
    """The BIM sentence (README and results.md) quotes the CLI method's metric errors: the
    medians of its evaluable reconstructed windows, computed here from the table."""
    d, df = _bim_run(tmp_path / "run")
    doc = figures.collect(d)
    b = doc["synthetic"]["default_method"]["bim"]
    ev = df[df.evaluable.astype(bool) & (df.status == "ok")]
    for c in ("width_err_m", "height_err_m", "width_err_m_storey"):
        assert b[c]["median"] == pytest.approx(float(np.median(ev[c])), rel=1e-3)
    assert b["exported_rate"] == pytest.approx(float(ev["exported"].mean()), abs=1e-3)
    assert b["assumed_rate_storey"] == pytest.approx(float((ev["scale_source_storey"] == "assumed").mean()), abs=1e-3)
    text = doc_text.answer(doc)
    assert f"width off by {np.median(ev['width_err_m']):.2f} m" in text and "`--known-storey`" in text
    assert "no window of known size" in text  # no real run: said, not left out


def test_bim_sentence_quotes_the_cli_method_s_export_precision(tmp_path):
    """The export precision on renders (summary.json's per-method ``export`` block, counted per
    detection by the bench: not in the table) reaches the BIM figures and the sentence; a run
    without the block says nothing of it."""
    d, _ = _bim_run(tmp_path / "run")
    cli = f"{DEFAULTS.detector}/{DEFAULTS.snapper}/{DEFAULTS.pose}"
    assert "export precision" not in doc_text.answer(figures.collect(d))
    s = json.loads((d / "summary.json").read_text())
    s["results"][cli]["export"] = {"n_exported": 40, "n_matched": 37, "n_on_ignore": 2, "n_on_nothing": 1,
                                   "n_views": 10, "precision": 37 / 40}
    (d / "summary.json").write_text(json.dumps(s))
    doc = figures.collect(d)
    assert doc["synthetic"]["default_method"]["bim"]["export"] == {"precision": 0.925, "n_exported": 40, "n_matched": 37,
                                                                   "n_on_ignore": 2, "n_on_nothing": 1}
    text = doc_text.answer(doc)
    assert ("export precision on the renders is 92.5 %: of the 40 detections it exports, 37 are labelled windows, "
            "2 lie on a door or glazing") in text


def test_docs_without_a_real_run_keep_the_committed_real_figures(tmp_path):
    """`make docs` with no real run keeps the real-photo figures already in the summary, marked as
    kept with their own provenance (never deleted)."""
    d, _ = _bim_run(tmp_path / "run")
    paths = docs.DocPaths.for_markdown(tmp_path / "docs" / "results.md")
    paths.summary.parent.mkdir(parents=True)
    committed = json.loads((ROOT / "docs" / "results" / "summary.json").read_text())
    assert committed["real"] is not None
    paths.summary.write_text(json.dumps({**committed, "synthetic": None}))
    docs.write_docs(d, paths.markdown, force=True)  # a committed summary no manifest lists: replaced with --force
    doc = json.loads(paths.summary.read_text())
    assert doc["real"]["kept"] and doc["real"]["provenance"] == committed["real"]["provenance"]
    text = paths.markdown.read_text()
    assert "Kept from an earlier real-photo run" in text and "No real-photo run was given" not in text


def test_house_figures_count_thin_and_oblique_windows_by_hand():
    """The quad shares among thin (aspect >= 3 or <= 1/3) and oblique (60-80 deg) windows: counted
    here from the rows' ground-truth aspect, incidence and snapped error, independently."""
    df = synthetic_results(n_windows=90, seed=3)
    df = df[df["snapper"] == df["snapper"].iloc[0]].copy()
    n = len(df)
    df["gt_aspect"] = np.where(np.arange(n) % 3 == 0, 4.0, np.where(np.arange(n) % 3 == 1, 0.2, 1.1))
    df["incidence_deg"] = np.where(np.arange(n) % 2 == 0, 70.0, 20.0)
    df.loc[df.index[::5], "corner_err_px_snap"] = np.nan  # every 5th row: no quad
    figs = figures.house_figures(df)
    ev = df[df["evaluable"].astype(bool)]
    thin = ev[(ev["gt_aspect"] >= 3) | (ev["gt_aspect"] <= 1 / 3)]
    obl = ev[(ev["incidence_deg"] >= 60) & (ev["incidence_deg"] < 80)]
    assert figs["n_thin"] == len(thin) and figs["n_oblique"] == len(obl) and 0 < len(thin) < len(ev)
    assert figs["thin_quad_rate"] == pytest.approx(thin["corner_err_px_snap"].notna().mean(), abs=1e-3)
    assert figs["oblique_quad_rate"] == pytest.approx(obl["corner_err_px_snap"].notna().mean(), abs=1e-3)
    assert figs["thin_quad_rate"] < 1.0
