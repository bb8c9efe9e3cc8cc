"""Report sections of a real-photo run (fenestra/bench/real): its own metrics and the sim-to-real table.

Sections use reports.build's tuple format (("h2", text), ("p", text), ("table", header, rows)).
"""
from __future__ import annotations

import json
from pathlib import Path

from fenestra.bench.real.simreal import SIMREAL_JSON
from fenestra.reports.kfree import kfree_sections


def _med(r: dict, col: str):
    return (r.get(col) or {}).get("median")


def real_metrics_rows(results: dict) -> tuple[list[str], list[list]]:
    """Per method: the metrics a real run measures where the labels allow (- = absent truth)."""
    header = ["method", "evaluable", "detected", "failed", "aspect med", "aspect p90", "aspect n",
              "rel size med", "rel size n", "reproj consistency med px", "snap med px (labelled quads)"]
    rows = []
    for m, r in results.items():
        a = r["aspect_err_rel"]
        rows.append([m, r["n_evaluable"], r["detection_rate"], r["failure_rate"], a["median"], a["p90"],
                     a["n_valid"], _med(r, "rel_size_err"), (r.get("rel_size_err") or {}).get("n_valid"),
                     _med(r, "reproj_consistency_px"), r["corner_err_px_snap"]["median"]])
    return header, rows


def simreal_sections(doc: dict) -> list[tuple]:
    """The sim-to-real sections from a simreal.json document."""
    s: list[tuple] = [("h2", "Sim-to-real: do render rankings hold on photos?"),
                      ("p", f"Synthetic run {doc.get('sim_run')}; per detector and metric, methods ranked by "
                            "median error on each bench (rank 1 = best), Spearman / Kendall rank correlation, "
                            "real - synthetic per method.")]
    s += [("p", t) for t in doc["answer"]]
    for r in doc["rankings"]:
        s.append(("h3", f"{r['detector']}: {r['metric']} (Spearman {_f(r['spearman'])}, p {_f(r['spearman_p'])}; "
                        f"Kendall {_f(r['kendall'])}, p {_f(r['kendall_p'])})"))
        s.append(("table", ["method", "synthetic median", "synthetic rank", "real median", "real rank",
                            "real - synthetic"],
                  [[m["method"], m["sim"], m["sim_rank"], m["real"], m["real_rank"], m["real_minus_sim"]]
                   for m in r["methods"]]))
    if doc.get("gap"):
        s.append(("h3", "Sim-to-real gap per detector: real / synthetic pooled median error"))
        metrics = sorted({k for v in doc["gap"].values() for k in v})
        s.append(("table", ["detector", *metrics], [[d, *(v.get(k) for k in metrics)] for d, v in doc["gap"].items()]))
    return s


def _f(x) -> str:
    return "-" if x is None else f"{x:.2f}"


def real_sections(run_dir: Path, results: dict, summary: dict | None) -> list[tuple]:
    """Sections for a real run (summary metadata kind == "real"); [] for a synthetic run."""
    meta = (summary or {}).get("metadata", {})
    if meta.get("kind") != "real":
        return []
    s: list[tuple] = [("h2", "Real photos: what the labels allow"),
                      ("p", "Labelled windows: " + ", ".join(f"{k} {v}" for k, v in (meta.get("n_windows") or {}).items())
                            + (f"; skipped: {meta['skipped_datasets']}" if meta.get("skipped_datasets") else "")
                            + ". Absent truth is shown as '-' (never 0): corner errors need labelled quads, "
                              "aspect error a known aspect ratio, relative size a photo of coplanar panes of known "
                              "size; reprojection consistency (snapped quad vs the rectangle reprojected from the "
                              "pose) needs no truth but a known K."),
                      ("table", *real_metrics_rows(results))]
    det = (summary or {}).get("detection") or {}
    if det:
        s += [("h3", "Detection per detector and dataset (COCO; R50 = recall at IoU 0.5; '-': no masks labelled)"),
              ("table", ["detector", "bbox AP", "bbox AP50", "bbox R50", "segm AP", "segm AP50", "segm R50", "GT"],
               [[d, v.get("bbox_AP"), v.get("bbox_AP50"), v.get("bbox_R50"), v.get("segm_AP"), v.get("segm_AP50"),
                 v.get("segm_R50"), v.get("n_gt")] for d, v in det.items()])]
    s += kfree_sections(run_dir, (summary or {}).get("kfree"))
    p = Path(run_dir) / SIMREAL_JSON
    if p.is_file():
        s += simreal_sections(json.loads(p.read_text()))
    return s
