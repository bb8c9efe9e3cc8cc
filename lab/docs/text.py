"""Render: the doc summary -> docs/results.md, the README's answer and the defaults statements."""
from __future__ import annotations

from fenestra.conventions import DEFAULTS, PAPER
from fenestra.tolerances import TOL
from fenestra.reports.lead import FEW_WINDOWS, SIGNIFICANT_P
from fenestra.reports.kfree import KFREE_NOTES, counts
from lab.docs.figures import target_words

REGENERATE = "make bench` then `python -m lab.docs RUN --real out/bench/real"


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
           "lab/scripts/make_data.sh, fenestra/pipeline/models/README.md). The bench's procedural "
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


def kfree_section(kf: dict | None) -> list[str]:
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
           "<!-- Generated by lab/docs from docs/results/summary.json: do not edit by hand. -->", "",
           f"Regenerate: `{REGENERATE}` (writes this file, docs/results/summary.json and the README's answer); "
           "`python -m lab.docs` renders them again from the committed summary. History and older "
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
            *kfree_section((real or {}).get("kfree"))]
    return "\n".join(out).rstrip() + "\n"


