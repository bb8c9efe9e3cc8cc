"""The results docs, generated from a bench run: docs/results.md, the README's answer and the
defaults statements, all rendered from one small committed summary.

    fenestra report RUN --markdown docs/results.md [--real REAL_RUN]
        1. collect(RUN, REAL_RUN) -> the doc summary: the figures the tables show, rounded, and the
           runs' provenance; written to docs/results/summary.json (a few KB, committed);
        2. render it: docs/results.md, and the marked blocks of README.md and docs/DESIGN.md
           (``<!-- results:begin -->`` ... ``<!-- results:end -->``, ``<!-- defaults:begin -->`` ...).
    python -m fenestra.reports.markdown [--check]
        step 2 alone, from the committed summary (``--check``: exit 1 where a doc differs).

The docs are always rendered from the rounded summary (never from the run directly), so rendering
the committed summary again gives the committed docs byte for byte (tests/test_docs.py).
Which method is "the CLI default" and "the paper's" comes from ``fenestra.conventions`` at render
time; a run that lacks the CLI default's method says so.
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from fenestra.files import REPO_ROOT
from fenestra.bench.manifest import load_verified_results
from fenestra.bench.paired import paired_comparison
from fenestra.bench.real.simreal import method_medians, ranking
from fenestra.bench.results import KFREE_TARGETS, METRIC_ERRORS, summarize, summarize_method
from fenestra.conventions import DEFAULTS, OBLIQUE_INCIDENCE_DEG, PAPER, THIN_ASPECT
from fenestra.methods import NO_K_SUFFIX
from fenestra.tolerances import TOL
from fenestra.pipeline.detectors import DETECTORS
from fenestra.reports.lead import FEW_WINDOWS, PHOTO_METRICS, SIGNIFICANT_P, SIM_METRIC, ranks
from fenestra.reports.kfree import KFREE_NOTES, counts
from fenestra.reports.plots import main_pose

FORMAT = 1
SUMMARY_NAME = Path("results") / "summary.json"  # beside the markdown file: docs/results/summary.json
SIG_DIGITS = 4
# The houses each shipped learned detector was trained on (fenestra/training/scripts/make_data.sh: its
# bundled training houses; its procedural houses use other seeds than the bench's). samplehouse4 is
# held out. tests/test_docs.py checks this against make_data.sh.
TRAINED_ON: dict[str, tuple[str, ...]] = {
    "default": ("fzk-haus", "duplex", "jasmin-sun", "niedriha"),
    "quadnet": ("fzk-haus", "duplex", "jasmin-sun", "niedriha"),
    "winnet": ("fzk-haus", "duplex", "jasmin-sun", "niedriha"),
    "maskrcnn": ("fzk-haus", "duplex", "jasmin-sun", "niedriha"),
}
# What a house is to a learned detector (issue #36): "trained on" (TRAINED_ON), "same generator" (the
# bench's procedural houses: fenestra.scenes.generate made the training houses too, so a held-out
# seed is not a held-out family) or "held out" (neither the house nor its generator trained it:
# samplehouse4, office-a, the authored houses). Figures on "held out" houses are the ones quoted.
ROLES = ("held out", "same generator", "trained on")
ROLE_GROUPS = {"held out": "held-out families", "same generator": "same generator", "trained on": "trained-on houses"}
PROCEDURAL_PREFIX = "procedural"  # the bench's name of a generated house: procedural-<seed>


def house_role(detector: str, house: str) -> str:
    """One of ROLES: what ``house`` (a bench house name) is to ``detector``'s training."""
    if house in TRAINED_ON.get(detector, ()):
        return "trained on"
    return "same generator" if house.startswith(PROCEDURAL_PREFIX) else "held out"


REGENERATE = "make bench` then `fenestra report RUN --markdown docs/results.md --real out/bench/real"


@dataclass(frozen=True)
class DocPaths:
    """Where the generator writes: the markdown file, its summary, and the docs with marked blocks
    (filled when the file exists)."""

    markdown: Path
    summary: Path
    readme: Path
    design: Path

    @staticmethod
    def for_markdown(markdown: Path) -> "DocPaths":
        """docs/results.md -> docs/results/summary.json, README.md one folder up, docs/DESIGN.md beside it."""
        markdown = Path(markdown)
        return DocPaths(markdown, markdown.parent / SUMMARY_NAME, markdown.parent.parent / "README.md",
                        markdown.parent / "DESIGN.md")


# ---------------------------------------------------------------- collect: run -> summary

def _r(x) -> float | None:
    """A figure rounded to SIG_DIGITS significant digits; None for NaN/inf/None."""
    if x is None:
        return None
    x = float(x)
    if not math.isfinite(x):
        return None
    return float(f"{x:.{SIG_DIGITS}g}")


def _stat(results: dict, method: str, col: str, key: str) -> float | None:
    return _r(((results.get(method) or {}).get(col) or {}).get(key))


def _git_commit(cwd: Path) -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    return out.stdout.strip() or None


def provenance(run_dir: Path, summary: dict) -> dict:
    """Profile, config hash, commit (the run's; else the checkout's at report time, said so), date
    (when summary.json was written, UTC) and the size of the run."""
    meta = summary.get("metadata", {})
    commit, source = meta.get("commit"), "run"
    if not commit:
        commit, source = _git_commit(REPO_ROOT), "report"
    mtime = (run_dir / "summary.json").stat().st_mtime
    cfg = meta.get("config") or {}
    return {"profile": meta.get("profile"), "config_hash": meta.get("config_hash"),
            "commit": commit[:12] if commit else None, "commit_source": source,
            "date": dt.datetime.fromtimestamp(mtime, dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "seed": meta.get("seed"), "n_views": meta.get("n_views"), "n_rows": meta.get("n_rows"),
            "n_methods": len(meta.get("methods") or []) or None,
            "houses": sorted((meta.get("datasets") or {}).keys()),
            "renderer": (cfg.get("render") or {}).get("renderer"),
            # "view": each view drew its own look (walls, frames, light); "set": one look per house
            "look_per": (((cfg.get("render") or {}).get("options") or {}).get("settings") or {}).get("look_per", "set"),
            "description": cfg.get("description")}


def _is_learned(detector: str) -> bool:
    """A detector that does not read the ground truth (not an oracle)."""
    entry = DETECTORS.get(detector)
    return entry is not None and not entry.needs_instances


def _k_known(results: dict, method: str) -> bool:
    """False for a method that estimated the focal length (K withheld: focal errors measured)."""
    return _stat(results, method, "focal_err_rel", "median") is None


def _snap_ranks(df: pd.DataFrame, results: dict, metric: str) -> dict[str, list[dict]]:
    return {det: [{"snapper": r.snapper, "median": _r(r.median), "p90": _r(r.p90), "n": r.n} for r in rk]
            for det, rk in ranks(df, metric, results).items()}


def _pose_rows(df: pd.DataFrame, results: dict, detector: str, snapper: str) -> list[dict]:
    """Every pose strategy of detector x snapper: rotation and aspect-ratio median/p90, windows."""
    rows = df.loc[(df["detector"] == detector) & (df["snapper"] == snapper), ["method", "pose"]].drop_duplicates()
    out = []
    for method, pose in sorted(rows.itertuples(index=False), key=lambda t: t[1]):
        out.append({"pose": pose, "k_known": _k_known(results, method),
                    "rot_median": _stat(results, method, "rot_err_deg", "median"),
                    "rot_p90": _stat(results, method, "rot_err_deg", "p90"),
                    "aspect_median": _stat(results, method, "aspect_err_rel", "median"),
                    "aspect_p90": _stat(results, method, "aspect_err_rel", "p90"),
                    "n": int(((results.get(method) or {}).get("rot_err_deg") or {}).get("n_valid", 0))})
    return out


def _detection(df: pd.DataFrame, results: dict, summary: dict) -> dict[str, dict]:
    det_ap = summary.get("detection") or {}
    out = {}
    for det in sorted(df["detector"].unique()):
        method = sorted(m for m in results if m.startswith(det + "/"))[0]
        r = results[method]
        ap = det_ap.get(det) or {}
        out[det] = {"learned": _is_learned(det), "detection_rate": _r(r["detection_rate"]),
                    "n_evaluable": r["n_evaluable"], "n_detected": r["n_detected"],
                    "segm_AP": _r(ap.get("segm_AP")), "segm_AP50": _r(ap.get("segm_AP50")),
                    "bbox_AP": _r(ap.get("bbox_AP")), "bbox_AP50": _r(ap.get("bbox_AP50")),
                    "trained_on": list(TRAINED_ON[det]) if det in TRAINED_ON else None}
    return out


def _house_figures(rows: pd.DataFrame) -> dict:
    """Figures of one method's rows (one house, or several): evaluable windows, detection rate, the
    share with a quad (also among the thin and the oblique ones: conventions.THIN_ASPECT,
    OBLIQUE_INCIDENCE_DEG), the share with all four corners within TOL.all_corners_px (of the evaluable
    windows: a missed window counts as not), corner, rotation and aspect-ratio medians / p90."""
    s = summarize_method(rows)
    ev = rows[rows["evaluable"].astype(bool)]
    n = len(ev)
    quad = ev["corner_err_px_snap"].notna().to_numpy()
    close = (ev["corner_err_px_snap_max"].to_numpy(float) <= TOL.all_corners_px)
    aspect, incidence = ev["gt_aspect"].to_numpy(float), ev["incidence_deg"].to_numpy(float)
    thin = (aspect >= THIN_ASPECT) | (aspect <= 1.0 / THIN_ASPECT)
    lo, hi = OBLIQUE_INCIDENCE_DEG
    oblique = (incidence >= lo) & (incidence < hi)
    return {"n_evaluable": s["n_evaluable"], "detection_rate": _r(s["detection_rate"]),
            "quad_rate": _r(quad.mean()) if n else None, "all_corners_close": _r(close.mean()) if n else None,
            "n_thin": int(thin.sum()), "thin_quad_rate": _r(quad[thin].mean()) if thin.any() else None,
            "n_oblique": int(oblique.sum()), "oblique_quad_rate": _r(quad[oblique].mean()) if oblique.any() else None,
            "snap_median": _r(s["corner_err_px_snap"]["median"]),
            "rot_median": _r(s["rot_err_deg"]["median"]),
            "aspect_p90": _r(s["aspect_err_rel"]["p90"])}


def _per_house(df: pd.DataFrame, detector: str, snapper: str, pose: str) -> list[dict]:
    """Per house, then the houses of each role (ROLE_GROUPS: held-out families, same generator,
    trained on) together, the method detector/snapper/pose (:func:`_house_figures`), beside the exact
    masks' corner median (``oracle`` without snapping, the same pose, else the run's first: the
    snapped corners do not depend on the pose) where the run has them."""
    g = df[(df["detector"] == detector) & (df["snapper"] == snapper) & (df["pose"] == pose)]
    exact = df[(df["detector"] == "oracle") & (df["snapper"] == "none")]
    exact = exact[exact["pose"] == (pose if (exact["pose"] == pose).any() else exact["pose"].iloc[0] if len(exact) else pose)]
    roles = g["house"].map(lambda h: house_role(detector, h))
    groups = [(h, house_role(detector, h), False, rows) for h, rows in sorted(g.groupby("house"), key=lambda kv: kv[0])]
    groups += [(ROLE_GROUPS[role], role, True, g[roles == role]) for role in ROLES]
    out = []
    for house, role, together, rows in groups:
        if rows.empty:
            continue
        ex = exact[exact["house"].isin(set(rows["house"]))]
        ex_med = summarize_method(ex)["corner_err_px_snap"]["median"] if len(ex) else None
        out.append({"house": house, "role": role, "trained": role == "trained on", "together": together,
                    **_house_figures(rows), "exact_snap_median": _r(ex_med)})
    return out


def _recommend(snap: dict, pose: dict, detector: str) -> dict | None:
    """The detector's best snapper (lowest median snapped corner error) with its best K-known pose
    (lowest median rotation error); None when the run has no measured figure for it."""
    rk = [r for r in snap.get(detector, []) if r["median"] is not None]
    rows = [p for p in (pose.get(detector) or {}).get("rows", []) if p["k_known"] and p["rot_median"] is not None]
    if not rk or not rows:
        return None
    best = min(rows, key=lambda p: (p["rot_median"], p["pose"]))
    return {"detector": detector, "snapper": rk[0]["snapper"], **best}


def collect_synthetic(run_dir: Path) -> dict:
    """The figures of a synthetic run the docs show (rounded), with its provenance."""
    df = load_verified_results(run_dir)
    summary = json.loads((run_dir / "summary.json").read_text())
    results = with_export(summarize(df), summary)
    snap = _snap_ranks(df, results, SIM_METRIC)
    pose = {det: {"snapper": rk[0]["snapper"], "rows": _pose_rows(df, results, det, rk[0]["snapper"])}
            for det, rk in snap.items() if rk and rk[0]["median"] is not None}
    doc = {"provenance": provenance(run_dir, summary), "main_pose": main_pose(df), "snap": snap, "pose": pose,
           "detection": _detection(df, results, summary)}
    learned = [d for d, v in doc["detection"].items() if v["learned"]]
    doc["recommended"] = {d: _recommend(snap, pose, d) for d in learned}
    doc["per_house"] = {d: {"snapper": rec["snapper"], "pose": rec["pose"],
                            "rows": _per_house(df, d, rec["snapper"], rec["pose"])}
                        for d, rec in doc["recommended"].items() if rec is not None}
    doc["default_method"] = _method_figures(results, f"{DEFAULTS.detector}/{DEFAULTS.snapper}/{DEFAULTS.pose}")
    doc["default_vs_recommended"] = _default_vs_recommended(df, doc)
    return doc


def _default_vs_recommended(df: pd.DataFrame, doc: dict) -> dict | None:
    """The CLI default method against the run's recommendation for its detector, paired on the
    same windows by rotation error (bench.paired: a = the default, b = the recommendation); None
    when either is not in the run or they are the same method."""
    rec, dm = doc["recommended"].get(DEFAULTS.detector), doc["default_method"]
    if rec is None or not dm["in_run"] or (rec["snapper"], rec["pose"]) == (DEFAULTS.snapper, DEFAULTS.pose):
        return None
    other = f"{DEFAULTS.detector}/{rec['snapper']}/{rec['pose']}"
    c = paired_comparison(df, dm["method"], other, "rot_err_deg")
    return {"recommended": other, "n": c["n"], "median_diff": _r(c["median_diff"]), "a_better": _r(c["a_better"]),
            "p_value": _r(c["p_value"])}


def _method_figures(results: dict, method: str) -> dict:
    """One method's headline figures, or only its name when the run lacks it."""
    if method not in results:
        return {"method": method, "in_run": False}
    return {"method": method, "in_run": True,
            "snap_median": _stat(results, method, "corner_err_px_snap", "median"),
            "rot_median": _stat(results, method, "rot_err_deg", "median"),
            "rot_p90": _stat(results, method, "rot_err_deg", "p90"),
            "aspect_median": _stat(results, method, "aspect_err_rel", "median"),
            "aspect_p90": _stat(results, method, "aspect_err_rel", "p90"),
            "bim": bim_figures(results, method), "bim_noK": bim_figures(results, method + NO_K_SUFFIX)}


def with_export(results: dict, summary: dict) -> dict:
    """``results`` (bench.results.summarize of the verified table) with each method's ``export``
    block (export precision and its counts, bench.results.export_precision) from the run's
    summary.json: counted per detection, it is not in the table (in place; returned)."""
    for m, r in (summary.get("results") or {}).items():
        if m in results and r.get("export"):
            results[m]["export"] = r["export"]
    return results


def bim_figures(results: dict, method: str) -> dict | None:
    """What a BIM user gets from one method (bench.results' ``bim`` block, rounded): windows
    reconstructed, exported share, focal sources, assumed-scale shares and the metric errors'
    median and p90 (m), and, where the run counted them (:func:`with_export`), ``export``: the
    export precision and its counts; None when the run lacks the method or the block."""
    b = results.get(method, {}).get("bim")
    if not b:
        return None
    out = {"method": method, "n": b["n"], "exported_rate": _r(b["exported_rate"]),
           "K_source": {k: _r(v) for k, v in b["K_source"].items()},
           "assumed_rate": _r(b.get("assumed_rate")), "assumed_rate_storey": _r(b.get("assumed_rate_storey"))}
    for c in METRIC_ERRORS:
        if c in b:
            out[c] = {"median": _r(b[c]["median"]), "p90": _r(b[c]["p90"]), "n": b[c]["n_valid"]}
    e = results[method].get("export")
    if e:
        out["export"] = {"precision": _r(e["precision"]),
                         **{k: int(e[k]) for k in ("n_exported", "n_matched", "n_on_ignore", "n_on_nothing")}}
    return out


def collect_real(real_dir: Path, sim_dir: Path | None) -> dict:
    """The real run's figures: each detector's snappers ranked by the first photo metric it
    measures, whether renders choose the same snapper by that metric, and detection AP."""
    df = load_verified_results(real_dir)
    summary = json.loads((real_dir / "summary.json").read_text())
    results = with_export(summarize(df), summary)
    metric, snap = None, {}
    for m in PHOTO_METRICS:
        snap = _snap_ranks(df, results, m)
        if any(r["median"] is not None for rk in snap.values() for r in rk):
            metric = m
            break
    agreement = {}
    if metric is not None and sim_dir is not None:
        sim_df = load_verified_results(sim_dir)
        for det in snap:
            r = ranking(method_medians(sim_df, metric, det), method_medians(df, metric, det))
            if r is not None:
                agreement[det] = {"best_sim": r["best_sim"].split("/")[1], "best_real": r["best_real"].split("/")[1],
                                  "best_sim_real_rank": int(r["best_sim_real_rank"]), "n": r["n"],
                                  "spearman": _r(r["spearman"])}
    meta = summary.get("metadata", {})
    cli = f"{DEFAULTS.detector}/{DEFAULTS.snapper}/{DEFAULTS.pose}"
    # the photo counterpart of the BIM figures: the CLI's method, else the first method (the CLI's
    # first) that reconstructed a window of known size
    figures = (bim_figures(results, m) for m in (cli, cli + NO_K_SUFFIX, *sorted(results)))
    first = next((b for b in figures if (b or {}).get("width_err_m", {}).get("n")), None)
    bim = {} if first is None else {first["method"]: first}
    det_ap = {d: {k: _r(v.get(k)) for k in ("bbox_AP", "bbox_AP50", "segm_AP", "segm_AP50")} | {"n_gt": v.get("n_gt")}
              for d, v in sorted((summary.get("detection") or {}).items())}
    return {"provenance": provenance(real_dir, summary), "metric": metric, "snap": snap if metric else {},
            "agreement": agreement, "detection": det_ap, "n_windows": meta.get("n_windows"), "bim": bim,
            "kfree": collect_kfree(summary.get("kfree"))}


# (the figures with a target are in "targets" only: docs/results/summary.json stays small)
KFREE_FIGURES = ("n_photos", "output_share", "export_precision", "n_exported", "n_labelled", "windows_per_label",
                 "walls_median", "focal_spread_median", "focal_spread_n_observed", "focal_err_median", "focal_err_n_observed",
                 "focal_err_median_all", "K_sources", "detections", "focal_spread_by_transform", "targets",
                 "n_labels_matched", "n_exported_partial", "walls_stable_n_photos", "wall_tilt_max_deg",
                 "wall_tilt_n_walls", "known_storey_m", "known_storey_n_photos", "known_storey_n_exported",
                 "known_storey_n_rows", "focal_interval_coverage", "focal_interval_n")
TARGET_FIELDS = ("key", "target", "value", "met")  # a target's words come from bench.results.KFREE_TARGETS


def target_words(t: dict) -> str:
    """A K-free target's words: bench.results.KFREE_TARGETS' for its key (an older summary's own words)."""
    return next((w for k, _, _, w in KFREE_TARGETS if k == t["key"]), t.get("words") or t["key"])


def collect_kfree(block: dict | None) -> dict | None:
    """The K-free block of a real run's summary (bench.photo_eval), rounded; None when absent."""
    if not block:
        return None

    def rnd(v):
        if isinstance(v, dict):
            return {k: rnd(x) for k, x in v.items()}
        if isinstance(v, list):
            return [rnd(x) for x in v]
        return _r(v) if isinstance(v, float) else v

    def fig(d: dict, k: str):
        if k == "targets":
            return [{f: rnd(t[f]) for f in TARGET_FIELDS} for t in d.get(k) or []]
        return rnd(d.get(k))

    return {"spec": block["spec"], "wall_time_s": _r(block["wall_time_s"]), "n_runs": block["n_runs"],
            "datasets": {n: {k: fig(d, k) for k in KFREE_FIGURES} for n, d in block["datasets"].items()}}


def _is_real_run(run_dir: Path) -> bool:
    p = run_dir / "summary.json"
    if not p.is_file():
        raise ValueError(f"{run_dir}: no summary.json (not a bench run folder)")
    return json.loads(p.read_text()).get("metadata", {}).get("kind") == "real"


def collect(run_dir: Path, real_dir: Path | None = None) -> dict:
    """The doc summary of a synthetic run and, optionally, a real-photo run."""
    run_dir = Path(run_dir)
    for d, want in ((run_dir, False), (real_dir, True)):
        if d is not None and _is_real_run(Path(d)) != want:
            raise ValueError(f"{d}: {'not ' if want else ''}a real-photo run folder; give the synthetic run as RUN "
                             "and the real one with --real")
    return {"format": FORMAT, "synthetic": collect_synthetic(run_dir),
            "real": collect_real(Path(real_dir), run_dir) if real_dir is not None else None}


# ---------------------------------------------------------------- render: summary -> markdown

def _px(x) -> str:
    return "-" if x is None else f"{x:.2f} px"


def _deg(x) -> str:
    return "-" if x is None else f"{x:.2f}°"


def _pct(x, digits: int = 1) -> str:
    return "-" if x is None else f"{100 * x:.{digits}f} %"


def _num(x, digits: int = 1) -> str:
    return "-" if x is None else f"{100 * x:.{digits}f}"


def _value(x, metric: str) -> str:
    """A photo error: px to 0.01 px; a relative error in percent to 3 significant digits (as fixed point)."""
    if x is None or metric.startswith("corner_err_px"):
        return _px(x)
    return _pct(x, 2 if abs(x) < 0.1 else 1 if abs(x) < 1 else 0)


METRIC_WORDS = {"corner_err_px_snap": "snapped corner error", "aspect_err_rel": "aspect-ratio error"}


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header), *("| " + " | ".join(r) + " |" for r in rows)]


def _snapper_order(snap: dict) -> list[str]:
    """Columns of the lead table: the CLI default detector's ranking, then any other snapper by name."""
    first = [r["snapper"] for r in snap.get(DEFAULTS.detector, [])]
    rest = sorted({r["snapper"] for rk in snap.values() for r in rk} - set(first))
    return first + rest


def _snapper_label(s: str) -> str:
    tags = [t for t, name in (("paper", PAPER.snapper), ("CLI default", DEFAULTS.snapper)) if s == name]
    return f"`{s}`" + (f" ({', '.join(tags)})" if tags else "")


def _detector_label(det: str, info: dict) -> str:
    if not info["learned"]:
        return f"`{det}`" + (" (exact void)" if det == "oracle" else " (Mask-R-CNN-like)")
    return f"`{det}`" + (" (CLI default)" if det == DEFAULTS.detector else "") + " †"


def lead_table(syn: dict) -> list[str]:
    """Each detector's snappers by median snapped corner error (p90), best in bold, and the
    detection rate: the README's table and docs/results.md's first."""
    order = _snapper_order(syn["snap"])
    rows = []
    for det, rk in syn["snap"].items():
        by = {r["snapper"]: r for r in rk}
        best = rk[0]["snapper"] if rk and rk[0]["median"] is not None else None
        cells = []
        for s in order:
            r = by.get(s)
            cell = "-" if r is None or r["median"] is None else f"{_px(r['median'])} ({r['p90']:.2f})"
            cells.append(f"**{cell}**" if s == best else cell)
        info = syn["detection"][det]
        rows.append([_detector_label(det, info), _pct(info["detection_rate"], 0), *cells])
    return _table(["masks from", "detected", *(_snapper_label(s) for s in order)], rows)


def _pose_label(pose: str) -> str:
    return f"`{pose}`" + (" (CLI default)" if pose == DEFAULTS.pose else "") + (" (paper)" if pose == PAPER.pose else "")


def _default_sentence(syn: dict) -> str:
    """The CLI default method's figures (or that the run lacks it), and whether it is the recommendation."""
    d, rec = syn["default_method"], syn["recommended"].get(DEFAULTS.detector)
    same = rec is not None and (rec["snapper"], rec["pose"]) == (DEFAULTS.snapper, DEFAULTS.pose)
    verdict = (" It is this run's recommendation." if same else
               " This run recommends another snapper or pose than the CLI default." if rec is not None else "")
    if not d["in_run"]:
        return (f"The CLI's default method, `{d['method']}` (`fenestra.conventions.DEFAULTS`), is not part of "
                f"this `{syn['provenance']['profile']}` run, so it is not measured here.{verdict}")
    return (f"The CLI's default method, `{d['method']}`, has a median corner error of {_px(d['snap_median'])}, "
            f"rotation error {_deg(d['rot_median'])} (p90 {_deg(d['rot_p90'])}) and aspect-ratio error "
            f"{_pct(d['aspect_median'])} (p90 {_pct(d['aspect_p90'])}).{verdict}"
            + _why_default(syn.get("default_vs_recommended"), rec, d))


def _m(x) -> str:
    return "-" if x is None else f"{x:.2f} m"


def _bim_clause(b: dict, storey: bool = True) -> str:
    """Width / height / position error of a method's BIM windows, with the assumed scale and
    (storey) with the true storey height given."""
    def err(suffix: str) -> str:
        w, h = b.get(f"width_err_m{suffix}"), b.get(f"height_err_m{suffix}")
        pos = b.get(f"pos_err_m{suffix}")
        text = f"width off by {_m(w['median'])} (p90 {_m(w['p90'])}), height {_m(h['median'])} (p90 {_m(h['p90'])})"
        if pos and pos.get("median") is not None:
            text += f", position {_m(pos['median'])} (p90 {_m(pos['p90'])})"
        return text

    text = f"with nothing known (each wall's median window assumed 1.5 m tall) its windows have their {err('')}"
    if storey and b.get("width_err_m_storey") and b["width_err_m_storey"].get("n"):
        used = 1.0 - (b.get("assumed_rate_storey") or 0.0)
        text += (f"; with the house's true storey height given (`--known-storey`) {err('_storey')} (the storey "
                 f"height set the scale of {_pct(used, 0)} of them; the others' walls show no two window rows a storey "
                 "apart, and keep the assumed height)")
    return text


def bim_sentence(syn: dict, real: dict | None) -> str:
    """What a BIM user gets from the CLI's method: metric size and position errors (renders), the
    exported share, the export precision on the renders with its counts (where the run has them:
    doors and glazing are labelled negatives), the focal chain's sources with K withheld, and the
    real-photo counterpart."""
    d = syn["default_method"]
    b = d.get("bim") if d.get("in_run") else None
    if not b:
        return "This run has no BIM figures of the CLI's method (an older run, or the method is not in it)."
    text = (f"As a BIM user gets it, from the CLI's method on the renders (K known, {b['n']} windows): "
            f"{_bim_clause(b)}; {_pct(b['exported_rate'], 0)} of them are exported.")
    e = b.get("export")
    if e and e["n_exported"]:
        text += (f" Its export precision on the renders is {_pct(e['precision'])}: of the {e['n_exported']} "
                 f"detections it exports, {e['n_matched']} are labelled windows, {e['n_on_ignore']} lie on a "
                 f"door or glazing (labelled as negatives) and {e['n_on_nothing']} on neither.")
    nk = d.get("bim_noK")
    if nk:
        src = ", ".join(f"{k} {_pct(v, 0)}" for k, v in nk["K_source"].items() if v)
        text += f" With K withheld the focal length comes from: {src}; {_bim_clause(nk, storey=False)}."
    rb = (real or {}).get("bim") or {}
    cli = d["method"]
    m = cli if cli in rb else next(iter(rb), None)
    if m is None:
        text += " On real photos no window of known size was reconstructed, so there is no photo counterpart."
    else:
        who = "the CLI's method" if m == cli else f"`{m}` (the CLI's method reconstructed none)"
        text += (f" On real photos of known window size ({', '.join(real['provenance']['houses'])}), {who}: "
                 f"{_bim_clause(rb[m], storey=False)} ({rb[m]['width_err_m']['n']} windows).")
    return text


def _why_default(c: dict | None, rec: dict | None, d: dict) -> str:
    """Why the CLI default differs from the recommendation, from the numbers. The recommendation
    picks the snapper by corner error first; the pose is what a user gets. The default stays
    while it is not clearly worse there: when the recommendation's rotation error is lower on the
    same windows (paired, p < SIGNIFICANT_P) but the default's worst cases are smaller (rotation
    and aspect-ratio p90), the sentence states that trade-off; when the recommendation is also no
    worse in those tails, it says DEFAULTS should follow it."""
    if c is None or rec is None:
        return ""
    p = "-" if c["p_value"] is None else f"{c['p_value']:.2g}"
    paired = (f"on the same {c['n']} windows the default's rotation error is lower on {_pct(c['a_better'], 0)} of them, "
              f"median difference {_deg(c['median_diff'])}, Wilcoxon p = {p}")
    figures = (f"rotation error median {_deg(d['rot_median'])} against {_deg(rec['rot_median'])}, p90 "
               f"{_deg(d['rot_p90'])} against {_deg(rec['rot_p90'])}; aspect-ratio error median "
               f"{_pct(d['aspect_median'])} against {_pct(rec['aspect_median'])}, p90 {_pct(d['aspect_p90'])} against "
               f"{_pct(rec['aspect_p90'])}")
    worse_median = c["p_value"] is not None and c["p_value"] < SIGNIFICANT_P and (c["median_diff"] or 0) > 0
    smaller_tails = all(d[k] is not None and rec[k] is not None and d[k] < rec[k] for k in ("rot_p90", "aspect_p90"))
    if worse_median and not smaller_tails:
        return (f" The recommendation `{c['recommended']}` is better on the pose too ({figures}; {paired}): "
                "`fenestra.conventions.DEFAULTS` should follow it.")
    if worse_median:
        return (f" Why the CLI keeps its default: against `{c['recommended']}` its typical rotation error is a little "
                f"higher ({paired}), but its worst cases are smaller ({figures}); the CLI keeps the smaller tails "
                "(docs/DESIGN.md, Decisions).")
    return (f" Why the CLI keeps its default: the recommendation ranks snappers by corner error first, but what a "
            f"user gets is the pose, and there the default is not worse than `{c['recommended']}` ({figures}; {paired}).")


def _recommend_sentence(syn: dict) -> str:
    rec = syn["recommended"].get(DEFAULTS.detector)
    if rec is None:
        return f"The run has no measured figure for the CLI's default detector `{DEFAULTS.detector}`."
    best = syn["snap"][DEFAULTS.detector][0]
    return (f"With the learned detector `{DEFAULTS.detector}` (it finds "
            f"{_pct(syn['detection'][DEFAULTS.detector]['detection_rate'], 0)} of the evaluable windows), "
            f"`{rec['snapper']}` snapping puts the corners {_px(best['median'])} from the truth (median, p90 "
            f"{_px(best['p90'])}), and with the pose strategy `{rec['pose']}` it gives the lowest median rotation "
            f"error of its poses, {_deg(rec['rot_median'])} (p90 {_deg(rec['rot_p90'])}; aspect-ratio error "
            f"median {_pct(rec['aspect_median'])}, p90 {_pct(rec['aspect_p90'])}): "
            f"`--snapper {rec['snapper']} --pose {rec['pose']}`.")


def _windows(rk: list[dict]) -> int:
    """Windows behind a detector's ranking: the most any of its snappers has a value for."""
    return max((r["n"] for r in rk if r["median"] is not None), default=0)


def _real_sentence(real: dict | None) -> str:
    """Whether the renders' choice of snapper holds on the photos, per detector, in one sentence."""
    if real is None:
        return "No real-photo run is part of these figures."
    if real.get("kept"):
        pv = real["provenance"]
        return (f"(Real-photo figures kept from an earlier run, commit `{pv['commit']}`, {pv['date']}: this run had "
                "none.) " + _real_sentence({k: v for k, v in real.items() if k != "kept"}))
    if real["metric"] is None:
        return "The real-photo run measures no error its labels allow to rank snappers by."
    parts = []
    for det, rk in real["snap"].items():
        n, ag = _windows(rk), real["agreement"].get(det)
        if n == 0:
            parts.append(f"`{det}` got no value on any photographed window")
        elif ag is None:
            parts.append(f"`{det}` was not run on renders")
        elif ag["best_sim"] == ag["best_real"]:
            parts.append(f"`{det}`: both choose `{ag['best_real']}`")
        else:
            parts.append(f"`{det}`: renders choose `{ag['best_sim']}`, which ranks {ag['best_sim_real_rank']} of "
                         f"{ag['n']} on the photos (best there: `{ag['best_real']}`)")
        if 0 < n < FEW_WINDOWS:
            parts[-1] += f" ({n} windows: too few to trust)"
    return (f"On real photos ({', '.join(real['provenance']['houses'])}), by the {METRIC_WORDS[real['metric']]} "
            "of windows of known aspect ratio" * (real["metric"] == "aspect_err_rel")
            + ": " + "; ".join(parts) + ".")


def answer(doc: dict) -> str:
    """The README's generated block: the lead table and one paragraph."""
    syn = doc["synthetic"]
    pv = syn["provenance"]
    houses = len(pv["houses"])
    caption = (f"The table: median snapped corner error (p90 in brackets) under pose `{syn['main_pose']}` over the "
               f"evaluable windows of the `{pv['profile']}` bench profile ({pv['n_views']} rendered views of {houses} "
               f"house{'s' * (houses != 1)}), best per detector in bold; † a learned detector, trained on some of these "
               "houses (per house: [docs/results.md](docs/results.md)).")
    para = " ".join([caption, _recommend_sentence(syn), _default_sentence(syn), bim_sentence(syn, doc.get("real")),
                     _real_sentence(doc.get("real")),
                     f"Provenance (commit `{pv['commit']}`, config `{pv['config_hash']}`, {pv['date']}) and every "
                     "table behind this: [docs/results.md](docs/results.md)."])
    return "\n".join([*lead_table(syn), "", para])


def defaults_text() -> str:
    """The CLI defaults in words, from fenestra.conventions.DEFAULTS and PAPER (README, DESIGN.md)."""
    return (f"Defaults (`fenestra.conventions.DEFAULTS`, the one place that names them): detector "
            f"`{DEFAULTS.detector}`, snapper `{DEFAULTS.snapper}`, pose `{DEFAULTS.pose}`, quad source "
            f"`{DEFAULTS.quad_source}`. The paper's method (`PAPER`, the reference in comparisons): detector "
            f"`{PAPER.detector}`, snapper `{PAPER.snapper}`, pose `{PAPER.pose}`.")


def _provenance_lines(name: str, pv: dict) -> list[str]:
    commit = f"`{pv['commit']}`" + ("" if pv["commit_source"] == "run" else
                                    " (the checkout's at report time: the run recorded none)")
    return [f"- **{name}**: profile `{pv['profile']}` (config hash `{pv['config_hash']}`, seed {pv['seed']}), "
            f"commit {commit}, written {pv['date']}; {pv['n_views']} views, {pv['n_methods']} methods, "
            f"{pv['n_rows']} rows; houses/datasets: {', '.join(pv['houses'])}."
            + (f" Profile: {pv['description']}" if pv.get("description") else "")]


def _pose_section(syn: dict) -> list[str]:
    out = ["## Pose and aspect ratio per detector", "",
           "Each detector with its best snapper (lowest median snapped corner error), under every pose strategy "
           "of the run: median and p90 of the rotation error and of the relative aspect-ratio error over the "
           "windows with a value (n). K withheld: the focal length was estimated, not given.", ""]
    rows = []
    for det, v in syn["pose"].items():
        for p in v["rows"]:
            rows.append([f"`{det}`", f"`{v['snapper']}`", _pose_label(p["pose"]) + ("" if p["k_known"] else " (K withheld)"),
                         _deg(p["rot_median"]), _deg(p["rot_p90"]), _pct(p["aspect_median"]), _pct(p["aspect_p90"]),
                         str(p["n"])])
    out += _table(["detector", "snapper", "pose", "rotation median", "rotation p90", "aspect median",
                   "aspect p90", "n"], rows)
    return out + [""]


def _detection_section(syn: dict) -> list[str]:
    out = ["## Detection", "",
           "Share of the evaluable windows a detector's masks matched, and COCO AP of its detections "
           "(summary.json of the run; AP in percent).", ""]
    rows = [[f"`{d}`", str(v["n_evaluable"]), _pct(v["detection_rate"]), _num(v["segm_AP"]), _num(v["segm_AP50"]),
             _num(v["bbox_AP"]), _num(v["bbox_AP50"])] for d, v in syn["detection"].items()]
    return out + _table(["detector", "evaluable windows", "detected", "segm AP", "segm AP50", "bbox AP",
                         "bbox AP50"], rows) + [""]


def _per_house_section(syn: dict) -> list[str]:
    out = ["## Learned detectors per house", "",
           "The learned detectors were trained on renders of some of the bench's houses (`trained on`; "
           "fenestra/training/scripts/make_data.sh, fenestra/pipeline/models/README.md). The bench's procedural "
           "houses come from the generator of the training houses, with seeds the training did not use (`same "
           "generator`: a held-out seed, not a held-out family); only the `held out` houses (another author or "
           "family, never trained on, nor their generator) measure what the detector never saw. Each detector with "
           "its recommended snapper and pose; `quad`: evaluable windows with a quad; all corners within: "
           "evaluable windows whose four corners are all that close to the truth (a missed window counts as "
           "not); exact masks: the `oracle` detector's masks, not snapped, as a floor.", ""]
    for det, v in syn["per_house"].items():
        out += [f"### `{det}` with `{v['snapper']}` + `{v['pose']}`", ""]
        rows = [[f"**{r['house']}**" if r.get("together") else f"`{r['house']}`",
                 f"**{r['role']}**" if r.get("role") == "held out" else r.get("role", "trained on" if r["trained"] else "held out"),
                 str(r["n_evaluable"]), _pct(r["detection_rate"], 0), _pct(r.get("quad_rate"), 0),
                 _pct(r.get("all_corners_close"), 0), _px(r["snap_median"]), _px(r.get("exact_snap_median")),
                 _pct(r.get("aspect_p90")), _deg(r["rot_median"])] for r in v["rows"]]
        out += _table(["house", "to the detector", "evaluable windows", "detected", "quad",
                       f"all corners within {TOL.all_corners_px:g} px", "corner error median",
                       "exact masks: corner error median", "aspect p90", "rotation median"], rows) + [""]
    return out


def _real_section(real: dict | None) -> list[str]:
    out = ["## Real photos", ""]
    if real is None:
        return out + ["No real-photo run was given (`--real`): `make real` writes one to out/bench/real.", ""]
    if real.get("kept"):
        out += [f"Kept from an earlier real-photo run (commit `{real['provenance']['commit']}`, "
                f"{real['provenance']['date']}): the run behind the rest of this page had none (`make real`).", ""]
    n = real.get("n_windows") or {}
    out += ["Labelled windows per dataset: " + ", ".join(f"{k} {v}" for k, v in n.items()) + "." if n else "", ""]
    if real["metric"] is None:
        out += ["No window of the run has the labels a ranking error needs.", ""]
    else:
        words = METRIC_WORDS[real["metric"]]
        out += [f"Each detector's snappers ranked by median {words} (p90, windows with a value).", ""]
        rows, unmeasured = [], []
        for det, rk in real["snap"].items():
            measured = [r for r in rk if r["median"] is not None]
            if not measured:
                unmeasured.append(f"`{det}`")
                continue
            few = " (too few windows to rank)" if max(r["n"] for r in measured) < FEW_WINDOWS else ""
            rows.append([f"`{det}`{few}", *(f"{i}. `{r['snapper']}` {_value(r['median'], real['metric'])} "
                                            f"({_value(r['p90'], real['metric'])}, n {r['n']})"
                                            for i, r in enumerate(measured, 1))])
        width = max((len(r) for r in rows), default=1)
        rows = [r + ["-"] * (width - len(r)) for r in rows]
        out += _table(["detector", *(f"rank {i}" for i in range(1, width))], rows) + [""]
        if unmeasured:
            out += [f"No window has a value for {', '.join(unmeasured)} (no usable quad where the truth is known).", ""]
        out += [_real_sentence(real), ""]
    if real["detection"]:
        out += ["Detection on the photos (COCO AP in percent; '-': not labelled; `DETECTOR @ DATASET`: one dataset). "
                "The curtain-wall photos label each glass pane as a window, while the learned detectors were taught "
                "that curtain-wall glazing is not a window void (an ignore region in their training and evaluation; "
                "[experiments.md](experiments.md)); give such photos their masks (`--masks`).", ""]
        out += _table(["detector", "bbox AP", "bbox AP50", "segm AP", "segm AP50", "labelled windows"],
                      [[f"`{d}`", _num(v["bbox_AP"]), _num(v["bbox_AP50"]), _num(v["segm_AP"]), _num(v["segm_AP50"]),
                        str(v["n_gt"])] for d, v in real["detection"].items()]) + [""]
    return out


def _kfree_section(kf: dict | None) -> list[str]:
    """The K-free path's figures beside the issue's targets (bench.photo_eval); [] without them."""
    if not kf:
        return []
    spec = kf["spec"]
    out = ["## One photo, no intrinsics (`fenestra reconstruct`)", "",
           f"Every photo of {', '.join(f'`{d}`' for d in spec['datasets'])} through `fenestra reconstruct` without K "
           f"({kf['n_runs']} runs, {kf['wall_time_s']:.0f} s); {', '.join(f'`{d}`' for d in spec['transform_datasets'])} "
           f"also under {', '.join(spec['transforms'])}. An exported window matches a label at box IoU >= "
           f"{spec['match_iou']:g}; focal spread: per photo the largest relative change of f under the transforms; "
           "focal error: against the calibration, where f was observed (not the stated prior). The stated prior is a field of view of the frame, so a 10 % crop moves a prior focal length by 10 % by construction (without EXIF a crop cannot be told from a wider lens). "
           + KFREE_NOTES + (f" Run with the known storey: {', '.join(f'`{d}`' for d in spec['known_storey_datasets'])} as is with "
                            f"`--known-storey {spec['known_storey_m']:g}`." if spec.get("known_storey_datasets") else ""), ""]
    rows = [[f"`{n}`", target_words(t), f"{t['value']:.3g}", t["target"], "yes" if t["met"] else "**no**"]
            for n, d in kf["datasets"].items() for t in d["targets"]]
    out += _table(["dataset", "figure", "value", "target", "met"], rows) + [""]
    rows = [[f"`{n}`", ", ".join(d["detections"] or []), str(d["n_photos"]), ", ".join(f"{k} {v}" for k, v in d["K_sources"].items()),
             *counts(d).values(),
             ", ".join(f"{k} {v:.3f}" for k, v in d["focal_spread_by_transform"].items()) or "-",
             "-" if d["focal_err_median_all"] is None else f"{d['focal_err_median_all']:.3f}"]
            for n, d in kf["datasets"].items()]
    return out + _table(["dataset", "detections", "photos", "K sources", *counts({}),
                         "focal spread per transform (median)", "focal error, all photos (median)"], rows) + [""]


def results_md(doc: dict) -> str:
    """docs/results.md."""
    syn, real = doc["synthetic"], doc.get("real")
    out = ["# Results", "",
           "<!-- Generated by fenestra/reports/markdown.py from docs/results/summary.json: do not edit by hand. -->", "",
           f"Regenerate: `{REGENERATE}` (writes this file, docs/results/summary.json and the README's answer); "
           "`python -m fenestra.reports.markdown` renders them again from the committed summary. History and older "
           "measurements: [experiments.md](experiments.md); speed: [performance.md](performance.md).", "",
           "## Provenance", "", *_provenance_lines("Renders", syn["provenance"])]
    if real is not None:
        out += _provenance_lines("Real photos", real["provenance"])
    out += ["", "## The answer", "", *lead_table(syn), "",
            f"Median snapped corner error (p90 in brackets) under pose `{syn['main_pose']}` (snapping does not depend "
            "on the pose), over each method's evaluable windows with a value; best per detector in bold; † learned "
            "detector (trained on some of these houses: per house below).", "",
            _recommend_sentence(syn) + " " + _default_sentence(syn), "",
            "## What a BIM user gets", "", bim_sentence(syn, real), "",
            *_pose_section(syn), *_detection_section(syn), *_per_house_section(syn), *_real_section(real),
            *_kfree_section((real or {}).get("kfree"))]
    return "\n".join(out).rstrip() + "\n"


# ---------------------------------------------------------------- blocks and files

def fill_block(text: str, name: str, content: str) -> str:
    """text with the lines between ``<!-- name:begin -->`` and ``<!-- name:end -->`` replaced by content;
    ValueError naming the block if its markers are missing or repeated."""
    pattern = re.compile(rf"(<!-- {name}:begin -->\n)(.*?)(<!-- {name}:end -->)", re.S)
    found = pattern.findall(text)
    if len(found) != 1:
        raise ValueError(f"block {name!r}: expected one <!-- {name}:begin --> ... <!-- {name}:end --> pair, found {len(found)}")
    return pattern.sub(lambda m: m.group(1) + content.rstrip("\n") + "\n" + m.group(3), text)


def write_block(path: Path, name: str, content: str) -> None:
    """Replace block ``name`` of the Markdown file ``path`` by ``content`` (:func:`fill_block`) and say so."""
    path = Path(path)
    path.write_text(fill_block(path.read_text(), name, content))
    print(f"wrote block {name!r} of {path}")


def block(text: str, name: str) -> str:
    """The content of block ``name`` (without its markers)."""
    m = re.search(rf"<!-- {name}:begin -->\n(.*?)<!-- {name}:end -->", text, re.S)
    if m is None:
        raise ValueError(f"block {name!r} not found")
    return m.group(1)


def rendered(doc: dict, paths: DocPaths) -> dict[Path, str]:
    """{path: new text} of every doc the summary renders (README/DESIGN only where they exist)."""
    out = {paths.markdown: results_md(doc)}
    if paths.readme.is_file():
        text = fill_block(paths.readme.read_text(), "results", answer(doc))
        out[paths.readme] = fill_block(text, "defaults", defaults_text())
    if paths.design.is_file():
        out[paths.design] = fill_block(paths.design.read_text(), "defaults", defaults_text())
    return out


def write_summary(doc: dict, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")


def write_docs(run_dir: Path, markdown: Path, real_dir: Path | None = None) -> list[Path]:
    """collect the run(s) into markdown's summary file, then render every doc from that file.

    Without a real-photo run, the real-photo figures of the summary already there are kept (marked
    ``kept``: their own provenance says which run they are from), never dropped."""
    paths = DocPaths.for_markdown(markdown)
    doc = collect(run_dir, real_dir)
    if doc["real"] is None and paths.summary.is_file():
        before = json.loads(paths.summary.read_text()).get("real")
        if before is not None:
            doc["real"] = {**before, "kept": True}
    write_summary(doc, paths.summary)
    return [paths.summary, *render_docs(paths)]


def render_docs(paths: DocPaths) -> list[Path]:
    """Render the docs from the committed summary file; the paths written."""
    doc = json.loads(paths.summary.read_text())
    written = []
    for p, text in rendered(doc, paths).items():
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
        written.append(p)
    return written


def stale(paths: DocPaths) -> list[Path]:
    """The docs whose committed text differs from what the committed summary renders."""
    doc = json.loads(paths.summary.read_text())
    return [p for p, text in rendered(doc, paths).items() if not p.is_file() or p.read_text() != text]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Render docs/results.md and the README/DESIGN blocks from docs/results/summary.json.")
    ap.add_argument("--markdown", type=Path, default=Path("docs/results.md"))
    ap.add_argument("--check", action="store_true", help="write nothing; exit 1 if a doc differs from its rendering")
    a = ap.parse_args(argv)
    paths = DocPaths.for_markdown(a.markdown)
    if a.check:
        bad = stale(paths)
        for p in bad:
            print(f"stale: {p} (python -m fenestra.reports.markdown renders it)", file=sys.stderr)
        return 1 if bad else 0
    for p in render_docs(paths):
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
