"""Sim-to-real: does a method ranking measured on renders hold on real photos?

    from fenestra.bench.real.simreal import simreal_table
    doc = simreal_table(load_results("out/bench/smoke"), load_results("out/bench/real"))

For every metric that both runs measure (finite medians for at least two common methods of a
detector), the methods of each detector are ranked on each bench by their median over evaluable
windows (rank 1 = lowest error). Metrics that do not depend on the pose solver (corner errors
before the pose, aspect ratio) rank snappers under one pose solver (``lm`` when present), so a
snapper is not counted twice. Per ranking: Spearman's rho and Kendall's tau (scipy) with their
p-values, the per-method differences real - synthetic, and the snapper choice: the method best on
renders, its rank on photos and its regret there (its real median minus the real best). The gap
per detector is the ratio real / synthetic of its pooled median error (all its methods' evaluable
rows with a value): the sim-to-real gap later detector work is judged on.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import kendalltau, rankdata, spearmanr

from fenestra.bench.paired import paired_comparison
from fenestra.bench.results import TRUTH_FLAGS, _jsonable, load_results
from fenestra.conventions import PAPER
from fenestra.files import write_text
from fenestra.methods import read_methods

METRICS = ("aspect_err_rel", "corner_err_px_mask", "corner_err_px_snap", "corner_err_px_reproj", "iou_2d")
POSE_FREE = ("aspect_err_rel", "corner_err_px_mask", "corner_err_px_snap")
HIGHER_IS_BETTER = ("iou_2d",)
SIMREAL_JSON = "simreal.json"


def _rows_with_truth(df: pd.DataFrame, metric: str) -> pd.DataFrame:
    """Evaluable rows that carry the truth ``metric`` needs (bench.results.TRUTH_FLAGS)."""
    ev = df[df["evaluable"].astype(bool)]
    flag = TRUTH_FLAGS.get(metric)
    return ev[ev[flag].astype(bool)] if flag in ev.columns else ev


def method_medians(df: pd.DataFrame, metric: str, detector: str) -> pd.Series:
    """{method: median of ``metric``} of one detector's evaluable rows with a value (NaN-free)."""
    if metric not in df.columns:
        return pd.Series(dtype=float)
    d = _rows_with_truth(df[df["detector"] == detector], metric)
    if metric in POSE_FREE and len(d):
        poses = sorted(d["pose"].unique())
        d = d[d["pose"] == (PAPER.pose if PAPER.pose in poses else poses[0])]
    return d.groupby("method")[metric].median().dropna()


def window_count(df: pd.DataFrame, metric: str, detector: str) -> int:
    """Windows with a value of ``metric`` for the detector's method with the most of them."""
    med = method_medians(df, metric, detector)
    d = _rows_with_truth(df[df["method"].isin(med.index)], metric)
    return int(d.groupby("method")[metric].count().max()) if len(d) else 0


def ranking(sim: pd.Series, real: pd.Series, higher_better: bool = False) -> dict | None:
    """Side-by-side ranks of the methods common to both series (>= 2), rank correlations,
    per-method real - sim differences and the regret on photos of the method best on renders."""
    common = sorted(set(sim.index) & set(real.index))
    if len(common) < 2:
        return None
    s, r = sim[common].to_numpy(float), real[common].to_numpy(float)
    sign = -1.0 if higher_better else 1.0
    rs, rr = rankdata(sign * s), rankdata(sign * r)
    rho, p_rho = spearmanr(s, r) if len(common) > 2 else (float("nan"), float("nan"))
    tau, p_tau = kendalltau(s, r) if len(common) > 2 else (float("nan"), float("nan"))
    pick_sim, pick_real = int(np.argmin(sign * s)), int(np.argmin(sign * r))
    return {"methods": [{"method": m, "sim": float(a), "sim_rank": float(x), "real": float(b),
                         "real_rank": float(y), "real_minus_sim": float(b - a)}
                        for m, a, x, b, y in sorted(zip(common, s, rs, r, rr), key=lambda t: t[2])],
            "n": len(common), "spearman": float(rho), "spearman_p": float(p_rho),
            "kendall": float(tau), "kendall_p": float(p_tau),
            "best_sim": common[pick_sim], "best_real": common[pick_real],
            "best_sim_real_rank": float(rr[pick_sim]),
            "regret": float(sign * (r[pick_sim] - r[pick_real])),
            "regret_rel": float(sign * (r[pick_sim] - r[pick_real]) / abs(r[pick_real])) if r[pick_real] else float("nan")}


def gap_ratios(sim_df: pd.DataFrame, real_df: pd.DataFrame) -> dict[str, dict[str, float]]:
    """{detector: {metric: real pooled median / synthetic pooled median}} where both exist."""
    out: dict[str, dict[str, float]] = {}
    for det in sorted(set(sim_df["detector"]) & set(real_df["detector"])):
        for metric in METRICS:
            if metric in HIGHER_IS_BETTER or metric not in sim_df or metric not in real_df:
                continue
            a = _rows_with_truth(sim_df[sim_df["detector"] == det], metric)[metric].dropna()
            b = _rows_with_truth(real_df[real_df["detector"] == det], metric)[metric].dropna()
            if len(a) and len(b) and a.median() > 0:
                out.setdefault(det, {})[metric] = float(b.median() / a.median())
    return out


def paired_on_photos(real_df: pd.DataFrame, r: dict, metric: str) -> dict:
    """The render-chosen method against the photo-best one on the same photographed windows
    (bench.paired.paired_comparison: n, medians, median difference, share better, Wilcoxon p)."""
    return paired_comparison(_rows_with_truth(real_df, metric), r["best_sim"], r["best_real"], metric)


def simreal_table(sim_df: pd.DataFrame, real_df: pd.DataFrame) -> dict:
    """{"rankings": [{detector, metric, ...ranking(), paired}], "gap": gap_ratios(), "answer": [sentences]}."""
    rankings = []
    for det in sorted(set(sim_df["detector"]) & set(real_df["detector"])):
        for metric in METRICS:
            r = ranking(method_medians(sim_df, metric, det), method_medians(real_df, metric, det),
                        metric in HIGHER_IS_BETTER)
            if r is not None:
                rankings.append({"detector": det, "metric": metric, **r,
                                 "n_windows_sim": window_count(sim_df, metric, det),
                                 "n_windows_real": window_count(real_df, metric, det)})
                rankings[-1]["paired"] = paired_on_photos(real_df, rankings[-1], metric)
    return {"rankings": rankings, "gap": gap_ratios(sim_df, real_df), "answer": answer(rankings)}


def _snapper(method: str) -> str:
    return read_methods([method])[method].snapper


def answer(rankings: list[dict]) -> list[str]:
    """Plain-words answers to "does choosing a snapper on renders choose the right one for
    photos?", one per ranking, with its numbers."""
    out = []
    for r in rankings:
        same = r["best_sim"] == r["best_real"]
        corr = (f"rank correlation over {r['n']} methods: Spearman {r['spearman']:.2f} (p = {r['spearman_p']:.2g}), "
                f"Kendall {r['kendall']:.2f}")
        unit = "px" if "px" in r["metric"] else ("" if r["metric"] == "iou_2d" else "(relative)")
        head = (f"{r['detector']} masks, {r['metric']} ({r['n_windows_sim']} rendered / "
                f"{r['n_windows_real']} photographed windows per method): ")
        if same:
            out.append(head + f"yes: renders choose {_snapper(r['best_sim'])}, also the best on photos; {corr}.")
        else:
            out.append(head + f"no: renders choose {_snapper(r['best_sim'])}, which ranks "
                       f"{r['best_sim_real_rank']:.0f} of {r['n']} on photos (best there: {_snapper(r['best_real'])}); "
                       f"choosing on renders costs {r['regret']:.3g} {unit} in median on photos "
                       f"({100 * r['regret_rel']:.0f} % of the best; paired on the same {r['paired']['n']} "
                       f"windows it is better on {100 * r['paired']['a_better']:.0f} %, Wilcoxon p = "
                       f"{r['paired']['p_value']:.2g}); {corr}.")
    return out


def write_simreal(sim_dir: Path, real_dir: Path) -> Path:
    """simreal.json in the real run folder, from the two runs' results tables."""
    doc = simreal_table(load_results(sim_dir), load_results(real_dir))
    doc["sim_run"], doc["real_run"] = str(sim_dir), str(real_dir)
    p = Path(real_dir) / SIMREAL_JSON
    return write_text(p, json.dumps(_jsonable(doc), indent=2))  # NaN written as null; atomically: listed by the run's listing
