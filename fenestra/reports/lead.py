"""The report's lead: each detector's snappers ranked by median corner error on renders (p90 too),
beside the same methods on real photos where a real-photo run exists, and the answer in words.

    lead = make_lead(sim_df, real_df)           # either may be None (not both)
    plots.ranked_methods(lead_columns(lead), path); answer(lead, sim_df, real_df)

Renders rank by the report's headline error, the snapped corner error (``best_method`` ranks by
it; it does not depend on the pose solver, so each detector x snapper is one row, under
``plots.main_pose``). Photos rank by the same error where the real run has labelled quads, else
by the first error in PHOTO_METRICS it measures (the renders' values of that error are drawn
beside them, so the two benches are compared on one metric).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from fenestra.bench.paired import PairedTable, paired_comparison
from fenestra.bench.real.simreal import method_medians, ranking
from fenestra.bench.results import summarize
from fenestra.methods import read_methods
from fenestra.reports.plots import main_pose

SIM_METRIC = "corner_err_px_snap"
PHOTO_METRICS = ("corner_err_px_snap", "aspect_err_rel")  # first one the real run measures
METRIC_LABELS = {"corner_err_px_snap": "snapped corner error (px)",
                 "aspect_err_rel": "aspect ratio error (relative)"}
NAMES = {"corner_err_px_snap": "snapped corner error", "aspect_err_rel": "relative aspect-ratio error"}
SIGNIFICANT_P = 0.05
FEW_WINDOWS = 10  # below this many windows a ranking is stated with a warning


@dataclass(frozen=True)
class Rank:
    """One detector x snapper under the main pose: median and p90 of an error over its n windows
    with a value (evaluable, with the truth the error needs; bench.results.summarize)."""

    detector: str
    snapper: str
    method: str
    median: float
    p90: float
    n: int


@dataclass(frozen=True)
class Lead:
    """What the lead figure and answer show. sim / photo: {detector: [Rank] best first} (None:
    no such run); photo_metric: the error the photos rank by; sim_at_photo: the renders' ranks
    by photo_metric when it is not SIM_METRIC (else None)."""

    sim: dict[str, list[Rank]] | None
    photo: dict[str, list[Rank]] | None
    photo_metric: str | None
    sim_at_photo: dict[str, list[Rank]] | None


def _sort_key(r: Rank) -> tuple:
    return (not math.isfinite(r.median), r.median if math.isfinite(r.median) else 0.0, r.snapper)


def ranks(df: pd.DataFrame, metric: str, results: dict | None = None) -> dict[str, list[Rank]]:
    """{detector: [Rank] sorted by median (no value last, ties by name)} of ``metric`` under the
    main pose; results: summarize(df) if already computed."""
    results = results if results is not None else summarize(df)
    rows = df.loc[df["pose"] == main_pose(df), ["method", "detector", "snapper"]].drop_duplicates()
    out: dict[str, list[Rank]] = {}
    for method, det, snapper in sorted(rows.itertuples(index=False)):
        s = results[method].get(metric) or {}
        out.setdefault(det, []).append(Rank(det, snapper, method, float(s.get("median", np.nan)),
                                            float(s.get("p90", np.nan)), int(s.get("n_valid", 0))))
    return {d: sorted(v, key=_sort_key) for d, v in sorted(out.items())}


def _measured(rk: dict[str, list[Rank]]) -> bool:
    return any(math.isfinite(r.median) for rs in rk.values() for r in rs)


def make_lead(sim_df: pd.DataFrame | None, real_df: pd.DataFrame | None,
              sim_results: dict | None = None, real_results: dict | None = None) -> Lead:
    """The lead of a report: renders' ranks (sim_df) and photos' ranks (real_df), either None;
    sim_results / real_results: their summarize(), if already computed."""
    if sim_df is None and real_df is None:
        raise ValueError("make_lead: needs a synthetic or a real results table, got neither")
    if sim_df is not None and sim_results is None:
        sim_results = summarize(sim_df)
    sim = ranks(sim_df, SIM_METRIC, sim_results) if sim_df is not None else None
    photo, metric = None, None
    if real_df is not None:
        real_results = real_results if real_results is not None else summarize(real_df)
        for m in PHOTO_METRICS:
            photo = ranks(real_df, m, real_results)
            if _measured(photo):
                metric = m
                break
        if metric is None:
            photo = None
    sim_at_photo = (ranks(sim_df, metric, sim_results) if sim_df is not None and metric not in (None, SIM_METRIC)
                    else None)
    return Lead(sim, photo, metric, sim_at_photo)


def lead_columns(lead: Lead) -> list[tuple[str, dict, dict]]:
    """The columns of plots.ranked_methods: renders, then photos (with the renders' values of the
    photos' metric as ghosts when it is not the renders' metric)."""
    cols = []
    if lead.sim is not None:
        cols.append((f"Renders: {METRIC_LABELS[SIM_METRIC]}", lead.sim, {}))
    if lead.photo is not None:
        ghost = " (hollow: renders)" if lead.sim_at_photo else ""
        cols.append((f"Real photos: {METRIC_LABELS[lead.photo_metric]}{ghost}", lead.photo,
                     lead.sim_at_photo or {}))
    return cols


def caption(lead: Lead) -> str:
    """What the lead figure shows, in one paragraph."""
    text = ("Each detector's snappers ranked by median error (dot; the bar reaches the 90th percentile), "
            "best on top, log scale; evaluable windows with the truth the error needs, under the "
            "main pose solver (snapped corners do not depend on it).")
    if lead.photo is not None and lead.sim is not None:
        text += " The photo column keeps the renders' order, so a different order on photos shows as a different shape."
        if lead.sim_at_photo:
            text += (f" The photos have no labelled corners, so they are compared by the {NAMES[lead.photo_metric]}, "
                     "the renders' values of it as hollow grey dots.")
    return text


def _v(x: float, metric: str) -> str:
    """A value of ``metric`` in words: px to 0.01 px, relative errors to 3 significant digits."""
    if not math.isfinite(x):
        return "-"
    return f"{x:.2f} px" if metric.startswith("corner_err_px") else f"{x:.3g}"


def _verdict(c: dict) -> str:
    """How the runner-up compares with the best, paired (c: paired_comparison(runner-up, best))."""
    if not (math.isfinite(c["p_value"]) and c["p_value"] < SIGNIFICANT_P):
        return "is not clearly worse"
    return "is clearly worse" if c["a_better"] < 0.5 else "is better on most of the same windows despite its higher median"


def _sim_sentence(det: str, rk: list[Rank], sim_df: pd.DataFrame, table: PairedTable | None = None) -> str:
    best = rk[0]
    text = (f"Renders, detector **{det}**: **{best.snapper}** is best, median {_v(best.median, SIM_METRIC)} "
            f"(p90 {_v(best.p90, SIM_METRIC)}, {best.n} windows"
            + (", too few to trust the order" if best.n < FEW_WINDOWS else "") + ")")
    measured = [r for r in rk if math.isfinite(r.median)]
    if len(measured) > 1:
        nxt = measured[1]
        c = paired_comparison(sim_df if table is None else table, nxt.method, best.method, SIM_METRIC)
        p = "-" if not math.isfinite(c["p_value"]) else f"{c['p_value']:.2g}"
        text += (f". The runner-up, {nxt.snapper} ({_v(nxt.median, SIM_METRIC)}), {_verdict(c)}: on the same "
                 f"{c['n']} windows the median of {nxt.snapper} - {best.snapper} is {_v(c['median_diff'], SIM_METRIC)} and "
                 f"{nxt.snapper} is better on {100 * c['a_better']:.0f} % of them (Wilcoxon p = {p})")
        if len(measured) > 2:
            text += f". The worst, {measured[-1].snapper}, has {_v(measured[-1].median, SIM_METRIC)}"
    return text + "."


def _photo_sentence(det: str, rk: list[Rank], lead: Lead, sim_df: pd.DataFrame | None,
                    real_df: pd.DataFrame) -> str:
    m = lead.photo_metric
    measured = [r for r in rk if math.isfinite(r.median)]
    if not measured:
        return f"Real photos, detector **{det}**: no window has the truth the {NAMES[m]} needs."
    best = measured[0]
    text = (f"Real photos, detector **{det}**, by {NAMES[m]}: **{best.snapper}** is best, median "
            f"{_v(best.median, m)} (p90 {_v(best.p90, m)}, {best.n} windows"
            + (", too few to trust the order" if best.n < FEW_WINDOWS else "") + ")")
    if sim_df is not None and det in (lead.sim or {}):
        r = ranking(method_medians(sim_df, m, det), method_medians(real_df, m, det))
        chosen = lead.sim[det][0]
        if r is not None and r["best_sim"] == r["best_real"]:
            text += f"; by the same error renders choose it too (Spearman {r['spearman']:.2f} over {r['n']} snappers)"
        elif r is not None:
            text += (f"; by the same error renders choose {read_methods([r['best_sim']])[r['best_sim']].snapper}, which ranks "
                     f"{r['best_sim_real_rank']:.0f} of {r['n']} here and costs {_v(r['regret'], m)} in median "
                     f"(Spearman {r['spearman']:.2f})")
        if m != SIM_METRIC:
            text += f"; by {NAMES[SIM_METRIC]} they choose {chosen.snapper}"
    return text + "."


def answer(lead: Lead, sim_df: pd.DataFrame | None, real_df: pd.DataFrame | None,
           sim_table: PairedTable | None = None) -> list[str]:
    """The plain-words answer under the lead figure: per detector, the best snapper and by how
    much, on renders and on photos, each with its numbers (medians, paired differences on the
    same windows, ranks). sim_table: sim_df's PairedTable, if already made."""
    out = []
    table = (sim_table if sim_table is not None else PairedTable(sim_df)) if lead.sim else None
    for det, rk in (lead.sim or {}).items():
        if any(math.isfinite(r.median) for r in rk):
            out.append(_sim_sentence(det, rk, sim_df, table))
        else:
            out.append(f"Renders, detector **{det}**: no snapped corner error was measured.")
    if real_df is None:
        out.append("No real-photo run is part of this report: `make real` writes one to out/bench/real, "
                   "and `fenestra report RUN --real out/bench/real` adds its column.")
    elif lead.photo is None:
        out.append("The real-photo run measures none of " + ", ".join(METRIC_LABELS[m] for m in PHOTO_METRICS)
                   + " (no window has the labels they need).")
    else:
        if lead.photo_metric != SIM_METRIC:
            out.append(f"The photos have no labelled corners; they rank by the {NAMES[lead.photo_metric]} "
                       "(windows of known aspect ratio).")
        out += [_photo_sentence(det, rk, lead, sim_df, real_df) for det, rk in lead.photo.items()]
    return out
