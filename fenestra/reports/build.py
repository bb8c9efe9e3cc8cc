"""Report of a benchmark run, regenerated from its results alone.

    from fenestra.reports.build import build_report
    html, md = build_report("out/bench/smoke", real_dir="out/bench/real")
    # or: fenestra report out/bench/smoke --real out/bench/real

Writes ``report.md`` with PNG plots beside it (``figures/``) and a self-contained ``report.html``
(the same content, images embedded as base64, no external file). Both lead with one figure (each
detector's snappers ranked by median corner error, renders beside real photos; reports.lead) and
the answer in words; in the HTML every later section is folded in a ``<details>``. Inputs:
results.parquet (or .csv), checked against the run's manifest.json (bench.manifest), and, when
present, summary.json (metadata and detection AP); summary statistics are recomputed from the
table. The photo column comes from ``real_dir`` (a real-photo run) for a synthetic run, and from
the synthetic run named in simreal.json for a real run.

reports/ reads what bench/ writes (bench.results, bench.manifest, bench.paired, bench.real.simreal)
and bench/ never imports reports/; the CLI composes the two (fenestra/app/cli.py).
"""
from __future__ import annotations

import base64
import dataclasses
import hashlib
import html as html_lib
import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from fenestra import outputs
from fenestra.bench.manifest import KIND as RUN_KIND, load_verified_results
from fenestra.bench.paired import PairedTable, paired_comparison
from fenestra.bench.real.simreal import SIMREAL_JSON
from fenestra.bench.results import CORNER_STAGES, STAGE_LABELS, load_summary, summarize
from fenestra.errors import DatasetError
from fenestra.files import write_text
from fenestra.methods import read_methods
from fenestra.reports import lead as lead_mod
from fenestra.reports import plots
from fenestra.reports.real import real_sections
from fenestra.userfiles import read_json
from fenestra.reports.walls import wall_sections

LEAD_TITLE = "Which method is best"
LEAD_FIGURE = "lead_ranked.png"


# ---------------------------------------------------------------- numbers

def best_method(results: dict, column: str = "corner_err_px_snap", methods=None) -> str | None:
    """Method with the lowest median of ``column`` (ties: higher detection rate, then name)."""
    cands = [(r[column]["median"], -np.nan_to_num(r["detection_rate"]), m)
             for m, r in results.items() if methods is None or m in methods]
    cands = [c for c in cands if c[0] is not None and np.isfinite(c[0])]
    return min(cands)[2] if cands else None


def comparison_rows(df: pd.DataFrame, results: dict, column: str = "corner_err_px_snap",
                    table: PairedTable | None = None) -> list[dict]:
    """Each method against the best one (lowest median ``column``) on the same windows; table:
    df's PairedTable, if already made."""
    best = best_method(results, column)
    if best is None:
        return []
    rows, table = [], table if table is not None else PairedTable(df)
    for m in results:
        if m == best:
            continue
        c = table.compare(m, best, column)
        rows.append({"method": m, "vs": best, **c})
    return sorted(rows, key=lambda r: (np.nan_to_num(r["median_a"], nan=np.inf), r["method"]))


def _fmt(x, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if abs(x) != 0 and (abs(x) < 10 ** -digits or abs(x) >= 1e5):
        return f"{x:.1e}"
    return f"{x:.{digits}f}"


def _md_table(header: list[str], rows: list[list]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(_fmt(v) if not isinstance(v, str) else v for v in r) + " |" for r in rows]
    return "\n".join(out)


def headline_rows(results: dict) -> tuple[list[str], list[list]]:
    header = ["method", "evaluable", "detected", "failed", "mask med px", "snap med px",
              "snap p90 px", "snap max px", "reproj med px", "R@1px", "R@2px", "R@5px",
              "aspect p90", "rot med deg", "normal med deg", "trans med m"]
    rows = []
    for m, r in results.items():
        s = r["corner_err_px_snap"]
        rows.append([m, r["n_evaluable"], r["detection_rate"], r["failure_rate"],
                     r["corner_err_px_mask"]["median"], s["median"], s["p90"], s["max"],
                     r["corner_err_px_reproj"]["median"], s["recall"]["1"], s["recall"]["2"],
                     s["recall"]["5"], r["aspect_err_rel"]["p90"], r["rot_err_deg"]["median"],
                     r["normal_err_deg"]["median"], r["trans_err_m"]["median"]])
    return header, rows


def _where_gap(df: pd.DataFrame, a: str, b: str) -> str | None:
    """Sentence on the condition bin where method a's median snapped error beats b's the most."""
    ev = df[df["evaluable"].astype(bool)]
    best = None
    for cond, label, log in plots.CONDITIONS:
        edges = plots.condition_edges(ev[cond].to_numpy(float), log, n_bins=4)
        ga, gb = ev[ev["method"] == a], ev[ev["method"] == b]
        _, ma, ca = plots.binned_medians(ga[cond].to_numpy(float), ga["corner_err_px_snap"].to_numpy(float), edges, 5)
        _, mb, _ = plots.binned_medians(gb[cond].to_numpy(float), gb["corner_err_px_snap"].to_numpy(float), edges, 5)
        for i in range(len(ma)):
            if np.isfinite(ma[i]) and np.isfinite(mb[i]):
                gap = mb[i] - ma[i]
                if best is None or gap > best[0]:
                    best = (gap, label, edges[i], edges[i + 1], ma[i], mb[i], ca[i])
    if best is None or best[0] <= 0:
        return None
    gap, label, lo, hi, ma, mb, n = best
    return (f"The gap is largest for {label} in [{_fmt(lo, 1)}, {_fmt(hi, 1)}] ({n} windows): "
            f"{_fmt(ma)} px against {_fmt(mb)} px.")


def narrative(df: pd.DataFrame, results: dict, table: PairedTable | None = None) -> list[str]:
    """A few sentences saying what the numbers mean, generated from them; table: df's
    PairedTable, if already made."""
    out = []
    ev = df[df["evaluable"].astype(bool)]
    n_rows, n_ev = len(df), len(ev)
    reasons = df.loc[~df["evaluable"].astype(bool), "eval_reason"].value_counts().to_dict() \
        if "eval_reason" in df.columns else {}
    out.append(f"{n_rows} rows ({df['method'].nunique()} method combinations); {n_ev} are evaluable"
               + (f", the rest are not ({', '.join(f'{k}: {v}' for k, v in reasons.items())})."
                  if reasons else "."))
    methods = read_methods(results)
    table = table if table is not None else PairedTable(df)
    for det in sorted(df["detector"].unique()):
        ms = [m for m in results if methods[m].detector == det]
        best = best_method(results, methods=ms)
        if best is None:
            out.append(f"With detector {det}, no corner error was measured: no method produced a snapped "
                       "quad, or (real photos) no window has a labelled quad.")
            continue
        r = results[best]
        snapper = methods[best].snapper
        text = (f"With detector **{det}**, the best snapper is **{snapper}** ({best}): median "
                f"snapped corner error {_fmt(r['corner_err_px_snap']['median'])} px "
                f"(mask-fit alone {_fmt(r['corner_err_px_mask']['median'])} px), "
                f"{_fmt(100 * (r['corner_err_px_snap']['recall']['2'] or 0), 0)}% of evaluable windows within 2 px, "
                f"{_fmt(100 * r['detection_rate'], 0)}% detected.")
        # the other snappers with the same detector and pose (and K condition, quad source)
        others = [m for m in ms if m != best and dataclasses.replace(methods[m], snapper=methods[best].snapper) == methods[best]]
        worst = max(others, key=lambda m: np.nan_to_num(results[m]["corner_err_px_snap"]["median"],
                                                         nan=np.inf), default=None)
        if worst is not None:
            c = table.compare(best, worst)
            text += (f" The worst snapper, {methods[worst].snapper}, has median "
                     f"{_fmt(c['median_b'])} px on the same {c['n']} windows (paired median "
                     f"difference {_fmt(c['median_diff'])} px, {methods[best].snapper} better on "
                     f"{_fmt(100 * c['a_better'], 0)}% of them, Wilcoxon p = {_fmt(c['p_value'], 3)}).")
            where = _where_gap(df, best, worst)
            if where:
                text += " " + where
        out.append(text)
        rot_best = min(ms, key=lambda m: np.nan_to_num(results[m]["rot_err_deg"]["median"], nan=np.inf))
        rr = results[rot_best]
        out.append(f"Pose with {det}: the lowest median rotation error is {_fmt(rr['rot_err_deg']['median'])} deg "
                   f"(p90 {_fmt(rr['rot_err_deg']['p90'])} deg, normal {_fmt(rr['normal_err_deg']['median'])} deg) "
                   f"for {rot_best}; aspect ratio p90 relative error there is {_fmt(rr['aspect_err_rel']['p90'], 3)}.")
    return out


# ---------------------------------------------------------------- documents

def figure8_groups(df: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """(method, its rows) of one figure 8 per detector x snapper, by method label: the mask-fit and
    snapped panels do not depend on the pose, so a pair's figure is its rows under the main pose
    (plots.main_pose), or under its first pose where the pair never ran the main one (the paper's
    method: harris under lm only)."""
    main = plots.main_pose(df)
    out = []
    for _, g in df.groupby(["detector", "snapper"], sort=True):
        poses = sorted(g["pose"].unique())
        pose = main if main in poses else poses[0]
        sub = g[g["pose"] == pose]
        out += list(sub.groupby("method", sort=True))
    return sorted(out, key=lambda mg: mg[0])


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


FIGURE_INDEX = "index.json"  # figures/index.json: each figure's file -> the digest of its inputs
_CORNERS = tuple(f"corner_err_px_{s}" for s in CORNER_STAGES)
_STYLED = ("method", "detector", "snapper", "pose", "evaluable")  # plots.line_styles, main_pose, _evaluable
FIGURE_COLUMNS = {  # what each figure reads: its digest hashes these columns only
    "figure8": ("method", "evaluable", *_CORNERS),
    "recall_curves": (*_STYLED, *_CORNERS),
    "error_vs_conditions": (*_STYLED, *(c for c, _, _ in plots.CONDITIONS), "corner_err_px_snap"),
    "aspect_rotation": ("method", "evaluable", "aspect_err_rel", "rot_err_deg"),
}


def _digest(*parts) -> str:
    """sha256 of the plotting code (fenestra/reports/plots.py) and the figure's inputs (tables hashed by
    their values, index and column names; anything else by repr)."""

    h = hashlib.sha256(Path(plots.__file__).read_bytes())
    for x in parts:
        if isinstance(x, pd.DataFrame):
            h.update(repr((list(x.columns), [str(t) for t in x.dtypes])).encode())
            h.update(pd.util.hash_pandas_object(x, index=True).to_numpy().tobytes())
        else:
            h.update(repr(x).encode())
    return h.hexdigest()


def make_figures(df: pd.DataFrame, fig_dir: Path, lead: list | None = None) -> dict[str, list[Path]]:
    """Every figure of the report as PNGs in fig_dir; {section: [paths]}; each figure gets only
    its FIGURE_COLUMNS of the table. A figure whose inputs
    (its rows of the table, its name, the plotting code) have the digest recorded for its file in
    ``figures/index.json`` by an earlier report of this folder is reused, not drawn again; any
    other file in fig_dir that an earlier report wrote (listed in fig_dir's parent's manifest,
    fenestra.outputs) is removed (no stale figure stays beside them). lead: the columns of
    the lead figure (reports.lead.lead_columns; LEAD_FIGURE, under "lead"; none if empty)."""
    fig_dir.mkdir(parents=True, exist_ok=True)
    try:
        old = json.loads((fig_dir / FIGURE_INDEX).read_text())
    except (OSError, ValueError):
        old = {}
    index: dict[str, str] = {}

    def draw(fn, data, name: str, *args) -> Path:
        if fn.__name__ in FIGURE_COLUMNS:
            data = data[[c for c in FIGURE_COLUMNS[fn.__name__] if c in data.columns]]
        path = fig_dir / name
        key = _digest(fn.__name__, name, *args, data)
        if not (old.get(name) == key and path.is_file()):
            fn(data, *args, path) if args else fn(data, path)
        index[name] = key
        return path

    figs = {"fig8": [draw(plots.figure8, g, f"fig8_{_safe(m)}.png", m) for m, g in figure8_groups(df)]}
    figs["recall"] = [draw(plots.recall_curves, df, "recall_curves.png")]
    figs["conditions"] = [draw(plots.error_vs_conditions, df, "error_vs_conditions.png")]
    figs["aspect_rotation"] = [draw(plots.aspect_rotation, df, "aspect_rotation.png")]
    figs["lead"] = [draw(plots.ranked_methods, lead, LEAD_FIGURE)] if lead else []
    stale = [f"{fig_dir.name}/{p.name}" for p in fig_dir.iterdir() if p.name not in index and p.name != FIGURE_INDEX]
    outputs.remove_owned(fig_dir.parent, stale)  # an earlier report's figures; never a file it did not write
    write_text(fig_dir / FIGURE_INDEX, json.dumps(index, indent=1))
    return figs


def _sections(df: pd.DataFrame, results: dict, summary: dict | None, figs: dict,
              table: PairedTable | None = None) -> list[tuple]:
    """Report content as ("h", text) / ("p", text) / ("table", header, rows) / ("img", path);
    table: df's PairedTable (made here if None)."""
    table = table if table is not None else PairedTable(df)
    meta = (summary or {}).get("metadata", {})
    s: list[tuple] = [("h1", f"Fenestra benchmark report: {meta.get('profile', df['profile'].iloc[0] if 'profile' in df else '?')}")]
    if meta:
        st = meta.get("stage_time_s") or {}
        s.append(("p", f"Commit {meta.get('commit') or 'unknown'}, seed {meta.get('seed')}, "
                       f"config hash {meta.get('config_hash')}, wall time {_fmt(meta.get('wall_time_s'), 1)} s "
                       f"({', '.join(f'{k} {_fmt(v, 1)} s' for k, v in st.items())})."))
        if meta.get("skipped_detectors"):
            s.append(("p", "Skipped detectors: " + "; ".join(f"{k} ({v})" for k, v in meta["skipped_detectors"].items())))
    s.append(("h2", "What this means"))
    s += [("p", t) for t in narrative(df, results, table)]
    s.append(("h2", "Strategy comparison"))
    s.append(("p", "Statistics over evaluable windows. Medians over windows with an estimate; recall (R@x px, "
                   "snapped corners) counts missed and failed windows as not recalled."))
    s.append(("table", *headline_rows(results)))
    comp = comparison_rows(df, results, table=table)
    if comp:
        s.append(("h3", f"Paired against the best method ({comp[0]['vs']}), snapped corner error on the same windows"))
        s.append(("table", ["method", "n paired", "median px", "best median px", "median diff px",
                            "method better on", "Wilcoxon p"],
                  [[r["method"], r["n"], r["median_a"], r["median_b"], r["median_diff"], r["a_better"],
                    r["p_value"]] for r in comp]))
    s += wall_sections(df, table)
    det = (summary or {}).get("detection") or {}
    if det:
        s.append(("h2", "Detection (COCO)"))
        s.append(("table", ["detector", "bbox AP", "bbox AP50", "segm AP", "segm AP50", "segm AP75",
                            "detections", "false positives", "GT instances"],
                  [[d, v.get("bbox_AP"), v.get("bbox_AP50"), v.get("segm_AP"), v.get("segm_AP50"),
                    v.get("segm_AP75"), v.get("n_detections"), v.get("false_positives"), v.get("n_gt")]
                   for d, v in det.items()]))
    s.append(("h2", "Recall curves"))
    s += [("img", p) for p in figs["recall"]]
    s.append(("h2", "Error against view conditions"))
    s += [("img", p) for p in figs["conditions"]]
    s.append(("h2", "Aspect ratio and rotation errors"))
    s += [("img", p) for p in figs["aspect_rotation"]]
    s.append(("h2", "Figure 8 per detector x snapper: corner error at mask-fit, snapped, reprojected"))
    s.append(("p", f"Reprojected corners after the {plots.main_pose(df)} pose (mask-fit and snapped corners do "
                   "not depend on the pose); every pose's reprojected errors are in the tables above."))
    s += [("img", p) for p in figs["fig8"]]
    timing = meta.get("stage_ms_per_view") or {}
    if timing:
        per_win = meta.get("stage_ms_per_window") or {}
        s.append(("h2", "Where the time goes"))
        s.append(("p", f"CPU milliseconds per stage (summed over worker processes; executor "
                       f"{meta.get('executor', 'local')}, {meta.get('workers')} workers), per view and per "
                       "ground-truth window: a regression in any stage shows here. The reconstruct.* rows break "
                       "reconstruct down by the pipeline's own timings_ms (wall clock)."))
        s.append(("table", ["stage", "ms per view", "ms per window"],
                  [[k, v, per_win.get(k)] for k, v in sorted(timing.items(), key=lambda kv: -kv[1])]))
    if "eval_reason" in df.columns:
        s.append(("h2", "Rows by outcome"))
        tab = df.assign(outcome=np.where(df["evaluable"].astype(bool), df["status"], "not evaluable: " + df["eval_reason"].astype(str)))
        counts = tab.groupby(["method", "outcome"]).size().unstack(fill_value=0)
        s.append(("table", ["method", *counts.columns], [[m, *map(int, r)] for m, r in counts.iterrows()]))
    return s


def _to_md(sections: list[tuple], base: Path) -> str:
    out = []
    for sec in sections:
        kind = sec[0]
        if kind in ("h1", "h2", "h3"):
            out.append("#" * int(kind[1]) + " " + sec[1])
        elif kind == "p":
            out.append(sec[1])
        elif kind == "table":
            out.append(_md_table(sec[1], sec[2]))
        elif kind == "img":
            out.append(f"![{sec[1].stem}]({sec[1].relative_to(base).as_posix()})")
        elif kind == "fold":
            out.append("---")
    return "\n\n".join(out) + "\n"


def _inline_html(text: str) -> str:
    """Escaped text with the Markdown the sections use: **bold** and `code`."""
    text = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", html_lib.escape(text))
    return re.sub(r"`(.+?)`", r"<code>\1</code>", text)


def to_html(sections: list[tuple]) -> str:
    """One self-contained page: images as data URIs (each <img> with the id of its file's stem);
    after a ("fold",) marker every h2 opens a closed <details> holding its section."""
    esc = html_lib.escape
    body = []
    folding = in_details = False
    for sec in sections:
        kind = sec[0]
        if kind == "fold":
            folding = True
        elif kind == "h2" and folding:
            body.append(("</details>" if in_details else "")
                        + f"<details><summary><h2>{esc(sec[1])}</h2></summary>")
            in_details = True
        elif kind in ("h1", "h2", "h3"):
            body.append(f"<{kind}>{esc(sec[1])}</{kind}>")
        elif kind == "p":
            body.append("<p>" + _inline_html(sec[1]) + "</p>")
        elif kind == "table":
            head = "".join(f"<th>{esc(h)}</th>" for h in sec[1])
            rows = "".join("<tr>" + "".join(f"<td>{esc(v if isinstance(v, str) else _fmt(v))}</td>" for v in r)
                           + "</tr>" for r in sec[2])
            body.append(f"<table><tr>{head}</tr>{rows}</table>")
        elif kind == "img":
            b64 = base64.b64encode(sec[1].read_bytes()).decode("ascii")
            body.append(f'<img id="{esc(sec[1].stem)}" alt="{esc(sec[1].stem)}" src="data:image/png;base64,{b64}">')
    if in_details:
        body.append("</details>")
    style = ("body{font-family:sans-serif;max-width:1300px;margin:2em auto;color:#222}"
             "summary{cursor:pointer}summary h2{display:inline;font-size:1.25em}details{margin:0.6em 0}"
             "table{border-collapse:collapse;font-size:12px;margin:1em 0}"
             "td,th{border:1px solid #ccc;padding:3px 6px;text-align:right}"
             "td:first-child,th:first-child{text-align:left}img{max-width:100%}")
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Fenestra report</title>"
            f"<style>{style}</style></head><body>{''.join(body)}</body></html>\n")


def _summary(run_dir: Path) -> dict | None:
    """The run's summary.json (bench.results.load_summary: checked), None when it has none."""
    return load_summary(run_dir) if (run_dir / "summary.json").is_file() else None


def _is_real(summary: dict | None) -> bool:
    return (summary or {}).get("metadata", {}).get("kind") == "real"


def counterpart(run_dir: Path, summary: dict | None, real_dir: str | Path | None
                ) -> tuple[Path | None, str | None]:
    """(the other bench's run folder or None, a sentence when one was expected but is missing).

    A synthetic run's counterpart is ``real_dir`` (ValueError unless it is a real-photo run); a
    real run's is the synthetic run its simreal.json names (``real_dir`` must be None)."""
    if _is_real(summary):
        if real_dir is not None:
            raise ValueError(f"--real {real_dir}: {run_dir} is itself a real-photo run (its synthetic "
                             "counterpart is the --sim run of fenestra bench --profile real)")
        p = run_dir / SIMREAL_JSON
        if not p.is_file():
            return None, None
        doc = read_json(p, "sim-to-real link")
        if not isinstance(doc, dict) or not isinstance(doc.get("sim_run"), str):
            raise DatasetError(f"sim-to-real link {p} must be a JSON object with the 'sim_run' folder")
        sim = Path(doc["sim_run"])
        if not (sim / "summary.json").is_file():
            return None, f"The synthetic run {sim} of the sim-to-real table is gone; the lead shows photos only."
        return sim, None
    if real_dir is None:
        return None, None
    real_dir = Path(real_dir)
    if not _is_real(_summary(real_dir)):
        raise ValueError(f"--real {real_dir}: not a real-photo run folder (its summary.json lacks "
                         "metadata kind = \"real\"; make one with fenestra bench --profile real)")
    return real_dir, None


def _lead_sections(lead: lead_mod.Lead, sim_df: pd.DataFrame | None, real_df: pd.DataFrame | None,
                   fig: Path | None, runs: str, sim_table: PairedTable | None = None) -> list[tuple]:
    """The lead: one figure, what it shows, and the answer in words (never folded)."""
    img = [("img", fig)] if fig is not None else []  # no figure when neither bench ranks a method
    return [("h2", LEAD_TITLE), *img, ("p", lead_mod.caption(lead) + " " + runs),
            *(("p", t) for t in lead_mod.answer(lead, sim_df, real_df, sim_table)), ("fold",)]


def build_report(run_dir: str | Path, real_dir: str | Path | None = None) -> tuple[Path, Path]:
    """Write report.html (self-contained) and report.md + figures/ into run_dir; return their paths.

    real_dir: a real-photo run folder (fenestra bench --profile real) whose ranks fill the lead
    figure's photo column of a synthetic run's report; a real run finds its synthetic counterpart
    itself (simreal.json). ValueError for a real_dir that is not a real run, or given to a real run.
    Every file is listed in the run's manifest (fenestra.outputs) before it takes its name."""
    run_dir = Path(run_dir)
    with outputs.listing(run_dir):
        return _build_report(run_dir, real_dir)


def _build_report(run_dir: Path, real_dir: str | Path | None) -> tuple[Path, Path]:
    """build_report's body."""
    df = load_verified_results(run_dir)  # refuses a table that does not match the run's manifest
    claim_report(run_dir)
    if df.empty:
        raise ValueError(f"{run_dir}: the results table is empty")
    summary = _summary(run_dir)
    other, missing = counterpart(run_dir, summary, real_dir)
    other_df = load_verified_results(other) if other is not None else None
    sim_df, real_df = (other_df, df) if _is_real(summary) else (df, other_df)
    results = summarize(df)
    table = PairedTable(df)
    lead = lead_mod.make_lead(sim_df, real_df, *((results, None) if sim_df is df else (None, results)))
    figs = make_figures(df, run_dir / "figures", lead_mod.lead_columns(lead))  # no lead figure: photos with boxes only and no renders run
    fig = figs["lead"][0] if figs["lead"] else None
    runs = " ".join(x for x in (f"Renders: {'this run' if sim_df is df else other}." if sim_df is not None else "",
                                f"Real photos: {'this run' if real_df is df else other}." if real_df is not None else "",
                                missing or "") if x)
    sections = _sections(df, results, summary, figs, table)
    at = next(i for i, sec in enumerate(sections) if sec[0] == "h2")
    sections[at:at] = _lead_sections(lead, sim_df, real_df, fig, runs, table if sim_df is df else None)
    at = next(i for i, sec in enumerate(sections) if sec[:2] == ("h2", "Strategy comparison"))
    sections[at:at] = real_sections(run_dir, results, summary)
    md, html = run_dir / "report.md", run_dir / "report.html"
    write_text(md, _to_md(sections, run_dir))
    write_text(html, to_html(sections))
    outputs.record(run_dir, [*REPORT_FILES, *(f"{FIGURES}/{f}" for f in outputs.files_in(run_dir / FIGURES))],
                   kind=RUN_KIND)  # the run's files: its next bench replaces them
    return html, md


REPORT_FILES = ("report.md", "report.html")
FIGURES = "figures"


def claim_report(run_dir: Path) -> None:
    """OwnershipError (one line, fenestra.outputs) unless ``run_dir`` may receive its report: a
    bench run (or a table sealed without one), where report.md, report.html and every file in
    figures/ are Fenestra's (a figure's name is known only once drawn, so any file there that
    Fenestra did not write is refused)."""
    outputs.check_kind(run_dir, RUN_KIND, option="report")
    figures = [f"{FIGURES}/{f}" for f in outputs.files_in(run_dir / FIGURES)] if (run_dir / FIGURES).is_dir() else []
    outputs.check_names(run_dir, [*REPORT_FILES, *figures], option="report")


__all__ = ["build_report", "paired_comparison", "comparison_rows", "narrative", "best_method",
           "CORNER_STAGES", "STAGE_LABELS"]
