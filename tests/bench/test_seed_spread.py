"""tools/seed_spread.py: a learned detector's per-house figures over seeds, median and min-max."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import seed_spread  # noqa: E402
from synthetic_results import synthetic_results  # noqa: E402

from fenestra.methods import DEFAULT_QUAD_SOURCE  # noqa: E402


def test_cell_median_and_range_by_hand():
    assert seed_spread.spread([0.5, None, 0.9, 0.6]) == (0.6, 0.5, 0.9)
    assert seed_spread.spread([None, None]) is None
    assert seed_spread.cell([0.58, 0.94, 0.86], 100, " %", 0) == "**86** % [58–94] (58, 94, 86)"
    assert seed_spread.cell([3.6, None], 1, " px", 2) == "**3.60** px [3.60–3.60] (3.60, -)"
    assert seed_spread.cell([None], 1, " px", 2) == "-"


def test_table_per_house_from_results_tables():
    """Two seeds' results tables (synthetic, known misses), two houses: each house's detection rate
    and corner median in the table are those counted here with numpy, per seed, then their median
    and range; the house the default detector trained on is flagged."""
    per_seed, truth = {}, {}
    for seed in (0, 1):
        df = synthetic_results(n_windows=80, seed=seed, miss_rate=0.1 + 0.3 * seed)
        df = df[df["snapper"] == "good"].assign(detector="default", snapper="refine", pose="wall+lines")
        df["house"] = np.where(np.arange(len(df)) % 2 == 0, "duplex", "samplehouse4")
        per_seed[seed] = seed_spread.house_figures(df, "default/refine/wall+lines")
        for house, rows in df.groupby("house"):
            ev = rows[rows["evaluable"]]
            truth[seed, house] = ((ev["status"] != "missed").mean(), np.median(ev["corner_err_px_snap"].dropna()))
    lines = seed_spread.table(per_seed, "default")
    assert lines[0].startswith("| house | to the detector | evaluable windows (per seed) | detected |")
    rows = {ln.split("|")[1].strip().strip("*"): [c.strip() for c in ln.strip("|").split("|")] for ln in lines[2:]}
    assert set(rows) == {"duplex", "samplehouse4", "held-out families", "trained-on houses"}
    assert rows["duplex"][1] == "trained on" and rows["samplehouse4"][1] == "**held out**"
    for label, house in (("held-out families", "samplehouse4"), ("trained-on houses", "duplex")):
        assert rows[label][2:] == rows[house][2:]  # one house of each role: the pooled row is that house's
    doc = seed_spread.spread_json(per_seed, "default", {"method": "default/refine/wall+lines"})
    assert doc["seeds"] == [0, 1] and doc["houses"]["samplehouse4"]["role"] == "held out"
    rate = doc["houses"]["held-out families"]["figures"]["detection_rate"]
    truth_rates = [truth[s, "samplehouse4"][0] for s in (0, 1)]
    assert np.allclose(rate["seeds"], truth_rates, atol=1e-3) and rate["min"] == min(rate["seeds"])
    for house in ("duplex", "samplehouse4"):
        cells = rows[house]
        rates = [truth[s, house][0] for s in (0, 1)]
        assert rates[1] < rates[0]  # the second seed misses more: the range is not one value
        assert cells[3] == seed_spread.cell(rates, 100, " %", 0), (house, cells[3], rates)
        med = [truth[s, house][1] for s in (0, 1)]  # the figures are rounded, then the median is rounded again: 0.01 px
        shown = [float(x) for x in cells[6].replace("*", " ").replace("[", " ").replace("]", " ").replace("–", " ")
                 .replace("(", " ").replace(")", " ").replace(",", " ").replace("px", " ").split()]
        assert np.allclose(shown, [np.median(med), min(med), max(med), *med], atol=0.011), (shown, med)
    # the JSON gives the same table back (--from-json: a table of other weights, written later)
    doc = json.loads(json.dumps(doc))
    assert seed_spread.table(seed_spread.per_seed_from_json(doc), "default") == lines


def test_cached_run_is_reused_only_with_this_commit_and_these_weights(tmp_path):
    """A run folder stands for a fresh run only when its summary names this commit and the sha256
    of every shipped weights file (checked here against the files' own digests)."""
    import hashlib
    import json

    from fenestra.bench.results import _commit

    weights = {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
               for p in sorted((ROOT / "fenestra" / "pipeline" / "models").glob("*.pt"))}
    assert "default.pt" in weights and "refine.pt" in weights
    run = tmp_path / "heldout-seeds-s0-abc"
    assert not seed_spread.reusable(run)  # no folder
    run.mkdir()
    (run / "results.parquet").write_bytes(b"x")
    for meta, ok in (({"commit": _commit(), "models": weights}, True),
                     ({"commit": _commit(), "models": {**weights, "refine.pt": "0" * 64}}, False),
                     ({"commit": "f" * 40, "models": weights}, False),
                     ({"commit": _commit()}, False)):  # a run from before the digests were recorded
        (run / "summary.json").write_text(json.dumps({"metadata": meta}))
        assert seed_spread.reusable(run) == ok, meta
    (run / "summary.json").write_text("{not json")
    assert not seed_spread.reusable(run)
    (run / "results.parquet").unlink()
    (run / "summary.json").write_text(json.dumps({"metadata": {"commit": _commit(), "models": weights}}))
    assert not seed_spread.reusable(run)


def test_a_method_with_a_quad_source_takes_its_own_rows():
    """Two quad sources of one detector/snapper/pose in one table: a label naming the source takes
    that source's rows only (the bench writes the default source's label without it); a 3-part
    label, the rows of every source (a profile's run holds one)."""
    df = synthetic_results(n_windows=40, seed=0, miss_rate=0.0)
    df = df[df["snapper"] == "good"].assign(detector="default", snapper="refine", pose="wall+lines",
                                            house="samplehouse4")
    other = df.assign(method="default/refine/wall+lines/mask+corners", status="missed")
    both = pd.concat([df.assign(method="default/refine/wall+lines"), other])
    own = seed_spread.house_figures(both, "default/refine/wall+lines/mask+corners")["samplehouse4"]
    assert own["detection_rate"] == 0.0
    default = seed_spread.house_figures(both, f"default/refine/wall+lines/{DEFAULT_QUAD_SOURCE}")["samplehouse4"]
    assert default["detection_rate"] == 1.0
