"""Matplotlib figures of a results table (one function per figure; PNG path in, PNG path out).

All figures use evaluable rows only (see bench.evaluate.window_conditions). Missed or failed
windows are not silently dropped: histograms count them in an explicit "no estimate" bar and
recall curves count them as not recalled.
"""
from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from fenestra.bench.results import CORNER_STAGES, STAGE_LABELS  # noqa: E402
from fenestra.conventions import DEFAULTS, PAPER  # noqa: E402
from fenestra.files import write_atomic  # noqa: E402

HIST_MAX_PX = 20.0  # histogram range; larger errors go to the overflow bar
STAGE_COLOURS = {"mask": "#888888", "snap": "#1f77b4", "reproj": "#d62728"}
CONDITIONS = (("incidence_deg", "incidence angle (deg)", False),
              ("distance_m", "distance (m)", False),
              ("window_px", "window size: shortest side (px)", True))


def _evaluable(df: pd.DataFrame) -> pd.DataFrame:
    return df[df["evaluable"].astype(bool)]


LINESTYLES = ("-", "--", ":", "-.")


def main_pose(df: pd.DataFrame) -> str:
    """The pose column the curves and snapper rankings show: the pose with the most (detector,
    snapper) pairs (a designed profile compares snappers under the CLI's pose); among
    equals the paper's solver (fenestra.conventions.PAPER), then the CLI's (DEFAULTS), then by
    name. PAPER's pose for a table with no row (nothing to show)."""
    if df.empty:
        return PAPER.pose
    pairs = df[["pose", "detector", "snapper"]].drop_duplicates().groupby("pose").size()
    return min(pairs.index, key=lambda p: (-int(pairs[p]), p != PAPER.pose, p != DEFAULTS.pose, str(p)))


def line_styles(df: pd.DataFrame) -> dict[str, dict]:
    """{method: matplotlib kwargs}: colour by snapper, line style by detector."""
    snappers = sorted(df["snapper"].unique())
    detectors = sorted(df["detector"].unique())
    cmap = plt.get_cmap("tab10" if len(snappers) <= 10 else "tab20")
    out = {}
    for m, d, s in df[["method", "detector", "snapper"]].drop_duplicates().itertuples(index=False):
        out[m] = {"color": cmap(snappers.index(s) % cmap.N),
                  "linestyle": LINESTYLES[detectors.index(d) % len(LINESTYLES)], "label": m}
    return out


def _legend_right(fig, ax) -> None:
    h, lab = ax.get_legend_handles_labels()
    if h:
        fig.legend(h, lab, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8, frameon=False)


def _save(fig, path: Path, tight: bool = True) -> Path:
    """Write fig as PNG (100 dpi) and close it. tight: lay out and crop to the drawn content
    (two extra layout passes, most of a figure's cost); False for figures with a fixed layout."""
    if tight:
        fig.tight_layout()
    write_atomic(path, lambda p: fig.savefig(p, dpi=100, bbox_inches="tight" if tight else None))
    plt.close(fig)
    return path


def figure8(df: pd.DataFrame, method: str, path: Path) -> Path:
    """The paper's Figure 8 for one method: corner-error histograms at mask-fit, snapped, reprojected.

    Bars of 0.5 px over [0, HIST_MAX_PX]; one overflow bar for larger errors and one for windows
    with no estimate (missed or failed at or before that stage).
    """
    d = _evaluable(df[df["method"] == method])
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4), sharey=True)
    bins = np.arange(0.0, HIST_MAX_PX + 0.5, 0.5)
    for ax, stage in zip(axes, CORNER_STAGES):
        e = d[f"corner_err_px_{stage}"].to_numpy(float)
        fin = e[np.isfinite(e)]
        ax.hist(np.minimum(fin, HIST_MAX_PX - 1e-9), bins=bins, color=STAGE_COLOURS[stage],
                histtype="stepfilled")  # one patch, not one per bar: 3x faster to draw
        over, none = int((fin > HIST_MAX_PX).sum()), int((~np.isfinite(e)).sum())
        ax.bar([HIST_MAX_PX + 2.0, HIST_MAX_PX + 5.5], [over, none], width=1.5,
               color=["#444444", "#bbbbbb"])
        ax.set_xticks([0, 5, 10, 15, HIST_MAX_PX + 2.0, HIST_MAX_PX + 5.5],
                      ["0", "5", "10", "15", f">{HIST_MAX_PX:g}", "none"])
        med = float(np.median(fin)) if fin.size else float("nan")
        ax.set_title(f"{STAGE_LABELS[stage]}: median {med:.2f} px (n={e.size})", fontsize=10)
        ax.set_xlabel("mean corner error (px)")
    axes[0].set_ylabel("windows")
    fig.suptitle(f"Corner error per stage: {method}", fontsize=11)
    fig.subplots_adjust(left=0.06, right=0.99, bottom=0.17, top=0.82, wspace=0.06)  # one per method: fixed
    return _save(fig, path, tight=False)


def _ecdf(e: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """Fraction of e (NaN = not recalled) at or below each x."""
    e = np.where(np.isfinite(e), e, np.inf)
    return (e[None, :] <= xs[:, None]).mean(axis=1) if e.size else np.full(xs.shape, np.nan)


def recall_curves(df: pd.DataFrame, path: Path, max_px: float = 10.0) -> Path:
    """Recall (fraction of evaluable windows within x px) against x, one panel per stage.

    Colour = snapper, line style = detector; pose solver: :func:`main_pose` only (mask-fit and
    snapped corners do not depend on it). Missed/failed windows count as not recalled.
    """
    d = _evaluable(df)
    pose = main_pose(d)
    styles = line_styles(d)
    d = d[d["pose"] == pose]
    xs = np.linspace(0.0, max_px, 201)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for ax, stage in zip(axes, CORNER_STAGES):
        for m, g in sorted(d.groupby("method"), key=lambda kv: kv[0]):
            ax.plot(xs, _ecdf(g[f"corner_err_px_{stage}"].to_numpy(float), xs), lw=1.4, **styles[m])
        for th in (1, 2, 5, 10):
            ax.axvline(th, color="#dddddd", lw=0.8, zorder=0)
        ax.set_title(f"{STAGE_LABELS[stage]} (pose {pose})" if stage == "reproj" else STAGE_LABELS[stage])
        ax.set_xlabel("corner error threshold (px)")
        ax.set_ylim(0, 1.0)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("recall (fraction of evaluable windows)")
    _legend_right(fig, axes[-1])
    return _save(fig, path)


def binned_medians(x: np.ndarray, y: np.ndarray, edges: np.ndarray, min_count: int = 3
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(bin centres, median of finite y per bin (NaN if < min_count), counts) of y against x."""
    idx = np.digitize(x, edges) - 1
    centres = 0.5 * (edges[:-1] + edges[1:])
    med = np.full(centres.shape, np.nan)
    cnt = np.zeros(centres.shape, int)
    for b in range(len(centres)):
        v = y[(idx == b) & np.isfinite(y)]
        cnt[b] = v.size
        if v.size >= min_count:
            med[b] = np.median(v)
    return centres, med, cnt


def condition_edges(x: np.ndarray, log: bool, n_bins: int = 8) -> np.ndarray:
    """Bin edges over the finite range of x (log-spaced if log)."""
    x = x[np.isfinite(x)]
    if x.size == 0:
        return np.array([0.0, 1.0])
    lo, hi = float(x.min()), float(x.max())
    if hi <= lo:
        hi = lo + 1.0
    if log and lo > 0:
        return np.geomspace(lo, hi * (1 + 1e-9), n_bins + 1)
    return np.linspace(lo, hi + 1e-9 * abs(hi), n_bins + 1)


def error_vs_conditions(df: pd.DataFrame, path: Path, column: str = "corner_err_px_snap") -> Path:
    """Binned medians of an error against incidence angle, distance and window pixel size."""
    d = _evaluable(df)
    styles = line_styles(d)
    d = d[d["pose"] == main_pose(d)]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for ax, (cond, label, log) in zip(axes, CONDITIONS):
        edges = condition_edges(d[cond].to_numpy(float), log)
        for m, g in sorted(d.groupby("method"), key=lambda kv: kv[0]):
            c, med, _ = binned_medians(g[cond].to_numpy(float), g[column].to_numpy(float), edges)
            ax.plot(c, med, marker="o", ms=3, lw=1.2, **styles[m])
        if log:
            ax.set_xscale("log")
            ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"median {column}")
    _legend_right(fig, axes[-1])
    fig.suptitle(f"Median {column} against view conditions (bins with >= 3 windows)", fontsize=11)
    return _save(fig, path)


def aspect_rotation(df: pd.DataFrame, path: Path) -> Path:
    """Box plots of relative aspect error and rotation error per method (evaluable, finite)."""
    d = _evaluable(df)
    methods = sorted(d["method"].unique())
    fig, axes = plt.subplots(1, 2, figsize=(13, 0.45 * len(methods) + 1.8))
    floors = {"aspect_err_rel": 1e-4, "rot_err_deg": 1e-2}  # log axis: smaller values drawn at the floor
    for ax, (col, label) in zip(axes, (("aspect_err_rel", "aspect ratio error (relative)"),
                                       ("rot_err_deg", "rotation error (deg)"))):
        data = [np.maximum(d.loc[d["method"] == m, col].dropna().to_numpy(float), floors[col])
                for m in methods]
        data = [v if v.size else np.array([np.nan]) for v in data]
        ax.boxplot(data, orientation="horizontal", whis=(10, 90), showfliers=False)
        ax.set_yticks(range(1, len(methods) + 1), methods, fontsize=8)
        ax.set_xscale("log")
        ax.set_xlim(left=floors[col])
        ax.set_xlabel(f"{label}, log scale; box p25-p75, whiskers p10/p90")
        ax.grid(alpha=0.3, axis="x")
    return _save(fig, path)


def _ranks_panel(ax, ranks: list, ghosts: list, order: list[str], colour) -> bool:
    """One detector's methods on rows ``order`` (top = first): dot at the median, bar to the p90,
    the median written above the dot; ghosts (hollow grey): another bench's medians of the same
    metric. True if anything was drawn."""
    by = {r.snapper: r for r in ranks}
    ghost = {r.snapper: r for r in ghosts}
    drawn = False
    for y, snapper in enumerate(order):
        g = ghost.get(snapper)
        if g is not None and np.isfinite(g.median):
            ax.plot(g.median, y, "o", ms=7, mfc="none", mec="#999999", mew=1.2, zorder=2)
        r = by.get(snapper)
        if r is None or not np.isfinite(r.median):
            continue
        ax.plot([r.median, r.p90], [y, y], color=colour, lw=2.2, solid_capstyle="butt", zorder=3)
        ax.plot(r.p90, y, "|", color=colour, ms=11, mew=2.2, zorder=3)
        ax.plot(r.median, y, "o", color=colour, ms=7, zorder=4)
        ax.annotate(f"{r.median:.3g}", (r.median, y), xytext=(0, 5), textcoords="offset points",
                    ha="center", va="bottom", fontsize=8)
        drawn = True
    return drawn


def ranked_methods(columns: list[tuple[str, dict, dict]], path: Path) -> Path:
    """The report's lead figure: per detector (a row of panels, one colour each), its snappers
    ranked by median error, dot = median, bar = to the p90, log x axis.

    columns: [(title, {detector: [Rank]}, {detector: [Rank]} ghosts)], Rank as in reports.lead
    (.snapper, .median, .p90; lists already ranked); the rows of every column follow the ranking
    of the first column holding that detector, so a method keeps its row across columns and a
    different order on photos shows as a different shape. Ghosts: hollow grey dots (the other
    bench's median of the same metric, e.g. renders' aspect error in the photos column).
    """
    detectors = sorted(set().union(*(c[1].keys() for c in columns)))
    if not detectors:
        raise ValueError("ranked_methods: no detector in any column")
    order = {d: [r.snapper for r in next(c[1][d] for c in columns if d in c[1])] for d in detectors}
    heights = [max(1, len(order[d])) for d in detectors]
    cmap = plt.get_cmap("tab10")
    fig, axes = plt.subplots(len(detectors), len(columns), squeeze=False, sharex="col", sharey="row",
                             figsize=(4.6 * len(columns) + 1.4, 0.36 * sum(heights) + 0.75 * len(detectors) + 0.9),
                             gridspec_kw={"height_ratios": heights})
    for i, det in enumerate(detectors):
        colour = cmap(i % cmap.N)
        for j, (title, ranks, ghosts) in enumerate(columns):
            ax = axes[i, j]
            if not _ranks_panel(ax, ranks.get(det, []), (ghosts or {}).get(det, []), order[det], colour):
                ax.text(0.5, 0.5, "no windows with this truth", transform=ax.transAxes, ha="center",
                        va="center", fontsize=9, color="#777777")
            ax.set_yticks(range(len(order[det])), order[det])
            ax.set_ylim(len(order[det]) - 0.4, -0.8)
            ax.grid(alpha=0.3, axis="x", which="both")
            if i == 0:
                ax.set_title(title, fontsize=10)
        axes[i, 0].set_ylabel(det, color=colour, fontsize=10, fontweight="bold")
    for j, (title, ranks, _) in enumerate(columns):
        ax = axes[-1, j]
        if any(np.isfinite(r.median) for rs in ranks.values() for r in rs):
            ax.set_xscale("log")
            lo, hi = ax.get_xlim()
            subs = (1.0, 2.0, 5.0) if np.log10(hi / lo) <= 2.5 else (1.0,)  # 1-2-5 ticks unless crowded
            ax.xaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=subs))
            ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("log scale; dot: median, bar: to the p90", fontsize=8)
    return _save(fig, path)
