"""Two bench runs of one profile, window by window: did a change help, where, and is it significant?

    fenestra compare RUN_A RUN_B [--method LABEL] [--html PATH] [--top 10]

A is the baseline, B the run after the change. Windows are paired by key (house, view, window id:
``fenestra.bench.paired.PAIR_KEY``) and method; a window counts where it is evaluable in both runs
and, for each error, has that error's truth (``fenestra.bench.results.TRUTH_FLAGS``). Per method
present in both runs and per error of :data:`METRICS`: the median and p90 of A and of B over the
same paired windows, the share of windows B made better and worse, the two-sided paired Wilcoxon
signed-rank test of B - A, and how many windows lost (A had a value, B none: missed or failed)
or gained a value. A **regression** of a method: some error's median over the paired windows got
worse by more than its tolerance (``fenestra.tolerances.TOL.compare_*``) with Wilcoxon p <
``TOL.compare_p_value`` (0.01). The command exits 1 on a regression of the gated method (the
CLI's, ``fenestra.conventions.DEFAULTS``, unless ``--method``), else 0.

Runs from different commits compare (their commits and config hashes are shown); runs of
different profiles do not (:class:`CompareError`). Pure functions here; the command is
:func:`fenestra.reports.cli.compare`.
"""
from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import wilcoxon

from fenestra import outputs
from fenestra.bench.manifest import (COMPARE_PREFIX, KEY_COLUMNS, MANIFEST_JSON, RUN_JSON, load_manifest,
                                     load_verified_results, verify_table)
from fenestra.bench.paired import PAIR_KEY
from fenestra.bench.results import RESULTS_CSV, RESULTS_PARQUET, SUMMARY_JSON, TRUTH_FLAGS, load_summary, parquet_columns
from fenestra.conventions import DEFAULTS
from fenestra.errors import FenestraError
from fenestra.tolerances import TOL

TOP_WINDOWS = 10  # the windows that changed most, listed


@dataclass(frozen=True)
class Metric:
    """An error column of the results table, how it is shown, and its regression tolerance."""

    column: str
    name: str
    unit: str
    scale: float  # shown value = scale * stored value (aspect: fraction -> %)
    tolerance: float  # in the stored unit

    def show(self, x: float, signed: bool = False) -> str:
        if x is None or not math.isfinite(x):
            return "-"
        return f"{self.scale * x:{'+' if signed else ''}.{3 if self.unit == 'px' else 2}f}"


METRICS = (Metric("corner_err_px_snap", "corner error", "px", 1.0, TOL.compare_corner_px),
           Metric("aspect_err_rel", "aspect error", "%", 100.0, TOL.compare_aspect_rel),
           Metric("rot_err_deg", "rotation error", "deg", 1.0, TOL.compare_rot_deg))


class CompareError(FenestraError):
    """Two runs that cannot be compared (other profiles, no method or window in common)."""


@dataclass(frozen=True)
class Change:
    """One method's change of one error from run A to run B, over the windows paired in both."""

    method: str
    metric: Metric
    n: int  # paired windows with the error's value in both runs
    median_a: float
    median_b: float
    p90_a: float
    p90_b: float
    better: float  # share of the n windows where B < A
    worse: float  # share where B > A
    p_value: float  # two-sided paired Wilcoxon of B - A; NaN if n < 5 or no difference
    lost: int  # windows with a value in A and none in B (missed or failed after the change)
    gained: int

    @property
    def d_median(self) -> float:
        return self.median_b - self.median_a

    @property
    def d_p90(self) -> float:
        return self.p90_b - self.p90_a

    @property
    def regressed(self) -> bool:
        """Median worse by more than the tolerance, and significant (module doc)."""
        return bool(self.p_value < TOL.compare_p_value and self.d_median > self.metric.tolerance)


@dataclass(frozen=True)
class RunInfo:
    path: Path
    profile: str
    commit: str | None
    config_hash: str | None


@dataclass(frozen=True)
class Comparison:
    a: RunInfo
    b: RunInfo
    gated: str  # the method whose regression fails the command
    changes: tuple[Change, ...]  # the gated method, then A's order; METRICS' order within a method
    only_a: tuple[str, ...]  # methods of one run only
    only_b: tuple[str, ...]
    top: pd.DataFrame  # the gated (else the first) method's windows that changed most
    pairs: pd.DataFrame  # that method's paired rows (key, <column>_a, <column>_b)
    focus: str | None  # that method, None when no method is in both

    @property
    def regressions(self) -> list[Change]:
        return [c for c in self.changes if c.method == self.gated and c.regressed]


def run_info(run_dir: Path) -> RunInfo:
    """Profile, commit and config hash of a run folder (its summary.json)."""
    meta = load_summary(run_dir).get("metadata", {})
    return RunInfo(Path(run_dir), str(meta.get("profile")), meta.get("commit"), meta.get("config_hash"))


def load_columns(run_dir: Path) -> pd.DataFrame:
    """The columns a comparison reads of a run's results table, checked against its manifest like
    ``load_verified_results`` (its rows and the file's sha256), reading only those columns of the
    Parquet (a default run's table has ~70 columns and a million rows)."""
    p = run_dir / RESULTS_PARQUET
    if not p.is_file():
        return load_verified_results(run_dir)  # a CSV-only run, or the loader's one-line error
    have = parquet_columns(p)
    want = [*KEY_COLUMNS, *PAIR_KEY, "evaluable", *(m.column for m in METRICS),
            *(TRUTH_FLAGS[m.column] for m in METRICS if m.column in TRUTH_FLAGS)]
    missing = [c for c in ("method", "evaluable", *(m.column for m in METRICS)) if c not in have]
    if missing:
        raise CompareError(f"{p} lacks column(s) {missing}: not a results table")
    df = pd.read_parquet(p, columns=[c for c in dict.fromkeys(want) if c in have])
    verify_table(run_dir, df, load_manifest(run_dir, expand=False))
    return df


def _prepared(df: pd.DataFrame, key: list[str]) -> pd.DataFrame:
    """Evaluable rows: key, method, each metric (NaN where the row lacks its truth)."""
    ev = df[df["evaluable"].astype(bool)]
    out = ev[[*key, "method"]].copy()
    for m in METRICS:
        v = ev[m.column].astype(float)
        flag = TRUTH_FLAGS.get(m.column)
        out[m.column] = v
        out["has:" + m.column] = ev[flag].astype(bool) if flag in ev.columns else True
    dup = out.duplicated([*key, "method"])
    if dup.any():
        raise CompareError(f"{int(dup.sum())} rows share a window key {key} + method, e.g. "
                           f"{out.loc[dup, [*key, 'method']].iloc[0].tolist()}")
    return out


def _wilcoxon(a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    if d.size < 5 or not np.any(d != 0):
        return float("nan")
    return float(wilcoxon(b, a, zero_method="wilcox").pvalue)


def _change(method: str, m: Metric, g: pd.DataFrame) -> Change:
    a, b = g[m.column + "_a"].to_numpy(float), g[m.column + "_b"].to_numpy(float)
    truth = g["has:" + m.column + "_a"].to_numpy(bool) & g["has:" + m.column + "_b"].to_numpy(bool)
    fa, fb = np.isfinite(a) & truth, np.isfinite(b) & truth
    both = fa & fb
    a, b = a[both], b[both]
    n = int(both.sum())
    med = (lambda x: float(np.median(x))) if n else (lambda x: float("nan"))
    p90 = (lambda x: float(np.percentile(x, 90))) if n else (lambda x: float("nan"))
    return Change(method, m, n, med(a), med(b), p90(a), p90(b),
                  float(np.mean(b < a)) if n else float("nan"), float(np.mean(b > a)) if n else float("nan"),
                  _wilcoxon(a, b), int((fa & ~fb).sum()), int((~fa & fb).sum()))


def _top(pairs: pd.DataFrame, key: list[str], n: int) -> pd.DataFrame:
    """The n windows whose corner error changed most (|B - A|, both with a value), largest first."""
    c = METRICS[0].column
    d = pairs[c + "_b"] - pairs[c + "_a"]
    t = pairs.assign(change=d)[d.notna()]
    order = np.argsort(-t["change"].abs().to_numpy(), kind="stable")
    return t.iloc[order[:n]][[*key, *(f"{m.column}_{s}" for m in METRICS for s in "ab"), "change"]]


def compare_runs(run_a: str | Path, run_b: str | Path, method: str | None = None,
                 top: int = TOP_WINDOWS) -> Comparison:
    """The comparison of run B against baseline run A (module doc); CompareError for runs of
    different profiles or with no window in common. method: the gated method (default: the CLI's);
    CompareError when a method given is not in both runs (a typo never passes as "nothing gated")."""
    a, b = run_info(Path(run_a)), run_info(Path(run_b))
    if a.profile != b.profile:
        raise CompareError(f"{b.path} is a run of profile {b.profile!r}, {a.path} of {a.profile!r}: "
                           "compare two runs of one profile")
    dfa, dfb = load_columns(a.path), load_columns(b.path)
    key = [k for k in PAIR_KEY if k in dfa.columns and k in dfb.columns]
    pa, pb = _prepared(dfa, key), _prepared(dfb, key)
    ma, mb = [str(m) for m in pd.unique(dfa["method"])], [str(m) for m in pd.unique(dfb["method"])]
    gated = method or DEFAULTS.label
    if method is not None and not (method in ma and method in mb):
        where = "neither run" if method not in ma and method not in mb else f"only {a.path if method in ma else b.path}"
        raise CompareError(f"--method {method[:100]!r} is in {where}, so nothing could be gated; methods of both runs: "
                           f"{', '.join(m for m in ma if m in set(mb))[:300] or 'none'}")
    common = sorted((m for m in ma if m in set(mb)), key=lambda m: m != gated)  # the gated method first
    if not common:
        raise CompareError(f"no method is in both {a.path} and {b.path} (A: {ma[:3]}..., B: {mb[:3]}...)")
    merged = pa.merge(pb, on=[*key, "method"], how="inner", suffixes=("_a", "_b"))
    if merged.empty:
        raise CompareError(f"no evaluable window of {a.path} is in {b.path} (paired by {key} and method)")
    by = dict(tuple(merged.groupby("method", sort=False)))
    changes = tuple(_change(meth, m, by.get(meth, merged.iloc[:0])) for meth in common for m in METRICS)
    focus = gated if gated in common else common[0]
    pairs = by.get(focus, merged.iloc[:0])
    return Comparison(a, b, gated, changes, tuple(m for m in ma if m not in set(mb)),
                      tuple(m for m in mb if m not in set(ma)), _top(pairs, key, top), pairs, focus)


# ---------------------------------------------------------------- text and page

def _p(p: float) -> str:
    return "-" if not math.isfinite(p) else f"{p:.2g}"


def _share(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{100 * x:.0f} %"


def change_row(c: Change) -> list[str]:
    m = c.metric
    return [c.method, f"{m.name} ({m.unit})", str(c.n), f"{m.show(c.median_a)} -> {m.show(c.median_b)}",
            m.show(c.d_median, signed=True), f"{m.show(c.p90_a)} -> {m.show(c.p90_b)}", m.show(c.d_p90, signed=True),
            _share(c.better), _share(c.worse), _p(c.p_value), str(c.lost), str(c.gained),
            "REGRESSION" if c.regressed else ""]


CHANGE_HEADER = ["method", "error", "windows", "median A -> B", "change", "p90 A -> B", "change",
                 "better", "worse", "Wilcoxon p", "lost", "gained", ""]


def _run_line(r: RunInfo) -> str:
    return f"{r.path} (commit {(r.commit or 'unknown')[:12]}, config {r.config_hash or 'unknown'})"


def verdict(c: Comparison) -> str:
    """One sentence: the gated method regressed (naming each error), did not, or is not in both runs."""
    if not any(ch.method == c.gated for ch in c.changes):
        return f"The gated method {c.gated} is not in both runs: nothing gated."
    rule = (f"a median worse by more than its tolerance (corner {TOL.compare_corner_px} px, aspect "
            f"{100 * TOL.compare_aspect_rel:g} %, rotation {TOL.compare_rot_deg} deg) with Wilcoxon p < {TOL.compare_p_value}")
    if not c.regressions:
        return f"No significant regression of {c.gated} ({rule})."
    what = "; ".join(f"{r.metric.name} median {r.metric.show(r.median_a)} -> {r.metric.show(r.median_b)} {r.metric.unit} "
                     f"(p = {_p(r.p_value)}, worse on {_share(r.worse)} of {r.n} windows)" for r in c.regressions)
    return f"REGRESSION of {c.gated}: {what} ({rule})."


def top_rows(c: Comparison) -> tuple[list[str], list[list[str]]]:
    key = [k for k in PAIR_KEY if k in c.top.columns]
    header = [*key, *(f"{m.name} A -> B ({m.unit})" for m in METRICS), "corner change"]
    rows = [[*(str(r[k]) for k in key), *(f"{m.show(r[m.column + '_a'])} -> {m.show(r[m.column + '_b'])}" for m in METRICS),
             METRICS[0].show(r["change"], signed=True)] for _, r in c.top.iterrows()]
    return header, rows


def text(c: Comparison) -> str:
    """What the command prints."""
    def table(header, rows):
        w = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
        return "\n".join("  ".join(str(x).ljust(n) for x, n in zip(r, w)).rstrip() for r in [header, *rows])

    lines = [f"A: {_run_line(c.a)}", f"B: {_run_line(c.b)}", f"profile {c.a.profile}; "
             f"{len({ch.method for ch in c.changes})} methods in both"
             + (f", {len(c.only_a)} only in A" if c.only_a else "") + (f", {len(c.only_b)} only in B" if c.only_b else ""),
             "", table(CHANGE_HEADER, [change_row(ch) for ch in c.changes])]
    if c.focus is not None and len(c.top):
        lines += ["", f"The {len(c.top)} windows of {c.focus} whose corner error changed most:", table(*top_rows(c))]
    return "\n".join([*lines, "", verdict(c)])


def _scatter(c: Comparison, path: Path) -> Path | None:
    """Corner error in A against B for the focus method's paired windows (log axes, diagonal)."""
    import matplotlib.pyplot as plt  # noqa: PLC0415 (matplotlib: imported when first used, not at the package's import)

    col = METRICS[0].column
    a, b = c.pairs[col + "_a"].to_numpy(float), c.pairs[col + "_b"].to_numpy(float)
    ok = np.isfinite(a) & np.isfinite(b)
    if not ok.any():
        return None
    lo = max(1e-3, float(min(a[ok].min(), b[ok].min())))
    hi = max(lo * 10, float(max(a[ok].max(), b[ok].max())))
    fig, ax = plt.subplots(figsize=(5.5, 5.0))
    ax.scatter(np.maximum(a[ok], lo), np.maximum(b[ok], lo), s=6, alpha=0.5, color="#1f77b4")
    ax.plot([lo, hi], [lo, hi], color="#444444", lw=1)
    ax.set(xscale="log", yscale="log", xlabel="corner error in A (px)", ylabel="corner error in B (px)",
           title=f"{c.focus}: {int(ok.sum())} windows (below the diagonal: better in B)")
    ax.title.set_fontsize(9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_html(c: Comparison, path: str | Path) -> Path:
    """A self-contained page like report.html: the verdict and the figure first, then the tables
    (folded)."""
    from fenestra.reports.build import to_html  # noqa: PLC0415 (fenestra.reports.build loads SciPy, matplotlib, pandas, shapely: imported when first used)

    path = Path(path)
    with tempfile.TemporaryDirectory() as tmp:
        fig = _scatter(c, Path(tmp) / "compare_corners.png") if c.focus else None
        sections = [("h1", "Fenestra run comparison"), ("p", f"A (baseline): {_run_line(c.a)}."),
                    ("p", f"B: {_run_line(c.b)}. Profile `{c.a.profile}`."), ("h2", "Verdict"), ("p", verdict(c)),
                    *([("img", fig)] if fig else []), ("fold",),
                    ("h2", "Every method in both runs"), ("table", CHANGE_HEADER, [change_row(ch) for ch in c.changes])]
        if c.focus is not None and len(c.top):
            sections += [("h2", f"The {len(c.top)} windows of {c.focus} that changed most"), ("table", *top_rows(c))]
        if c.only_a or c.only_b:
            sections += [("h2", "Methods of one run only"),
                         ("p", f"Only in A: {', '.join(c.only_a) or 'none'}. Only in B: {', '.join(c.only_b) or 'none'}.")]
        page = to_html(sections).replace("<title>Fenestra report</title>", "<title>Fenestra run comparison</title>")
    outputs.write_file(path, lambda p: p.write_text(page, encoding="utf-8"), *_page_rule(path, c.a.path, c.b.path))
    return path


PAGE_SUFFIXES = (".html", ".htm")
RUN_FILES = (RESULTS_PARQUET, RESULTS_CSV, MANIFEST_JSON, RUN_JSON, SUMMARY_JSON)  # what a comparison reads of a run


def _page_rule(path: Path, run_a: Path, run_b: Path) -> tuple:
    """(kind, hosts, inputs, option) of fenestra.outputs.write_file for the comparison page at
    ``path``: inside one of the two runs it is one of the run's files (kind bench), named
    COMPARE_PREFIX*.html so that the run's next ``fenestra bench`` clears it; elsewhere a file of
    its own (kind files, also allowed into another run folder). CompareError for a name that is
    not a page (PAGE_SUFFIXES) or a run's page not named so; the runs' files are inputs."""
    if path.suffix.lower() not in PAGE_SUFFIXES:
        raise CompareError(f"--html {path}: a comparison page is an .html file; name one (e.g. compare.html)")
    in_run = path.parent.resolve() in (Path(run_a).resolve(), Path(run_b).resolve())
    if in_run and not path.name.startswith(COMPARE_PREFIX):
        raise CompareError(f"--html {path}: a comparison page inside a run folder is named {COMPARE_PREFIX}*.html "
                           "(the run's next bench clears it); choose such a name or another folder")
    inputs = tuple(Path(r) / f for r in (run_a, run_b) for f in RUN_FILES)
    return ("bench", (), inputs, "--html") if in_run else (outputs.FILES_KIND, ("bench",), inputs, "--html")


def check_page(path: str | Path, run_a: str | Path, run_b: str | Path) -> None:
    """CompareError / fenestra.outputs.OwnershipError (one line) when the comparison page may not be
    written at ``path`` (:func:`_page_rule`): checked before the runs are compared."""
    outputs.check_file(Path(path), *_page_rule(Path(path), Path(run_a), Path(run_b)))


__all__ = ["METRICS", "Change", "Comparison", "CompareError", "check_page", "compare_runs", "text", "verdict",
           "write_html"]
