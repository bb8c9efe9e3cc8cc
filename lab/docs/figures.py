"""Collect: a bench run (and a real-photo run) -> the doc summary, the figures the docs show,
rounded, with the runs' provenance."""
from __future__ import annotations

import datetime as dt
import json
import math
import subprocess
from pathlib import Path

import pandas as pd

from fenestra.bench.manifest import load_verified_results
from fenestra.bench.paired import paired_comparison
from fenestra.bench.real.simreal import method_medians, ranking
from fenestra.bench.results import KFREE_TARGETS, METRIC_ERRORS, summarize, summarize_method
from fenestra.conventions import DEFAULTS, OBLIQUE_INCIDENCE_DEG, THIN_ASPECT
from fenestra.methods import NO_K_SUFFIX
from fenestra.tolerances import TOL
from fenestra.pipeline.detectors import DETECTORS
from fenestra.reports.lead import PHOTO_METRICS, SIM_METRIC, ranks
from fenestra.reports.plots import main_pose
from lab.docs.roles import ROLE_GROUPS, ROLES, TRAINED_ON, house_role

FORMAT = 1
SIG_DIGITS = 4
CHECKOUT = Path(__file__).resolve().parents[2]  # the repository this lab belongs to


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
        commit, source = _git_commit(CHECKOUT), "report"
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


def house_figures(rows: pd.DataFrame) -> dict:
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
    trained on) together, the method detector/snapper/pose (:func:`house_figures`), beside the exact
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
                    **house_figures(rows), "exact_snap_median": _r(ex_med)})
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


