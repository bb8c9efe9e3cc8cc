"""reports.build on a synthetic results table (bench.synthetic: snapper "good" halves the mask-fit
error, "bad" adds to it), so the report's statements can be checked against known structure."""
from __future__ import annotations

import base64
import re

import numpy as np
import pytest
from scipy.stats import wilcoxon

from bench import manifest, results
from bench.synthetic import synthetic_results
from reports.build import build_report, paired_comparison


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
    # fig8 for two methods + recall + conditions + aspect/rotation
    assert len(imgs) == 5
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
