"""Calibrate the vanishing-point focal length's interval and its acceptance rule on renders with known K.

    PYOPENGL_PLATFORM=egl nice .venv/bin/python tools/focal_calibration.py \
        [--seeds 100-105] [--views 24] [--hfov 30 95] [--out out/focal-calibration/calibration.csv]
    .venv/bin/python tools/focal_calibration.py --summary out/focal-calibration/calibration.csv
    .venv/bin/python tools/focal_calibration.py --kfree out/bench/real/kfree.parquet   # real photos' focal table

Renders (or reuses, under out/renders) ``--views`` views of each procedural house of ``--seeds``
(fenestra.renders.dataset.render_dataset; dataset seed ``--dataset-seed``), with a horizontal
field of view drawn from ``--hfov`` (default 30-95 deg: phone tele to ultra-wide, wider than the
focal prior's 40-90 deg). These houses and cameras are not the bench's: the default / clinok
profiles render procedural seeds 0-2 and the bundled houses with dataset seed 0 and a 50-70 deg
field of view, and those renders are the held-out set the calibrated rule is measured on.

Per view it runs what ``PhotoSession.resolve`` runs for the CLI's method
(fenestra.conventions.DEFAULTS) with K withheld, without the acceptance gate: the detector, the
snapped quads of the per-window fit with no K (PhotoSession.kfree_quads), then
fenestra.pipeline.intrinsics.vanishing_fit (the walls' vanishing points refined over the windows'
corners and the façade's line segments) with no early give-up. One row per view: house, view,
f_true, the field of view, n quads, f and sd (NaN with ``reason`` where the fit gives none), the
prior's focal length, and seconds. Written as CSV (``--out``; a .parquet name writes Parquet).

The summary (printed after a run, or alone with ``--summary FILE``): the empirical quantiles of
z = |f - f_true| / sd over the views with a fit (the ``--level`` quantile is the interval
multiplier whose stated interval covers the truth that often), its coverage by sd bin, and for
each acceptance rule (the one before, a x3 inflation with a +-15 % gate; the calibrated interval
narrower than the prior's, fenestra.pipeline.intrinsics.vanishing_estimate; and that with the
stability check, intrinsics.vanishing_stability: the halves of the windows fitted alone agree) how
many views take the vanishing points and the focal errors of what they take. Each row also records
the stability check's verdict (``stable``; empty without a fit), the halves' answers (``halves``;
empty when a half has fewer than VP_SPLIT_MIN_QUADS windows: not tested) and its CPU seconds, and
the steadiness check's (intrinsics.vanishing_steadiness, on the views whose calibrated interval is
narrower than the prior's): ``steady``, the repeats' answers in words (``moved``) and
``steady_seconds``. ``--doc FILE --block NAME`` also writes the summary into that Markdown block.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

# the rule before this calibration (fenestra/pipeline/intrinsics.py at 62f8679), kept for the comparison
OLD_Z90, OLD_INFLATION, OLD_GATE = 1.6449, 3.0, 0.15


def parse_seeds(text: str) -> list[int]:
    """"100-105" or "100,103,110" -> seeds."""
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def calibration_rows(seeds: list[int], views: int, hfov: tuple[float, float], dataset_seed: int,
                     renders_dir: str, progress: bool = True, min_quads: int | None = None) -> list[dict]:
    """One row per rendered view (see the module docstring); min_quads: the stability check's
    windows per half (None: intrinsics.VP_SPLIT_MIN_QUADS)."""
    import numpy as np  # noqa: PLC0415

    from fenestra.bench.render_adapter import house_path  # noqa: PLC0415
    from fenestra.conventions import DEFAULTS  # noqa: PLC0415
    from fenestra.pipeline.intrinsics import (VP_SPLIT_MIN_QUADS, fov_from_focal, prior_focal,  # noqa: PLC0415
                                              vanishing_estimate, vanishing_fit, vanishing_stability,
                                              vanishing_steadiness)
    from fenestra.pipeline.poses import POSES  # noqa: PLC0415
    from fenestra.pipeline.session import PhotoSession  # noqa: PLC0415
    from fenestra.pipeline.types import Unavailable  # noqa: PLC0415
    from fenestra.rendered_view import read_view  # noqa: PLC0415
    from fenestra.renders.dataset import DatasetConfig, render_dataset  # noqa: PLC0415
    from fenestra.renders.sampler import SamplerConfig  # noqa: PLC0415

    rows = []
    wall = POSES[DEFAULTS.pose].wall
    for seed in seeds:
        cfg = DatasetConfig(scene=house_path(f"procedural:{seed}"), n_views=views, seed=dataset_seed,
                            renderer="pyrender", sampler=SamplerConfig(hfov_deg=hfov), out_root=renders_dir)
        root = render_dataset(cfg, progress=False)
        for i in range(views):
            view = read_view(root / "views" / f"{i:06d}")
            t0 = time.process_time()
            session = PhotoSession(view.image)
            quads = session.kfree_quads(DEFAULTS)
            fit = vanishing_fit(quads, session.size, wall, session.segments)
            f_true = float(view.meta["K"][0][0])
            f, sd, reason = (np.nan, np.nan, fit.reason) if isinstance(fit, Unavailable) else (fit[0], fit[1], "")
            seconds = time.process_time() - t0
            t1 = time.process_time()
            stable, halves = vanishing_stability(quads, session.size, fit, wall, session.segments,
                                                 VP_SPLIT_MIN_QUADS if min_quads is None else min_quads) \
                if not isinstance(fit, Unavailable) else (None, "")
            check_s = time.process_time() - t1
            est = None if isinstance(fit, Unavailable) else vanishing_estimate(fit[0], fit[1], session.size)
            t2 = time.process_time()
            tried = vanishing_steadiness(quads, session.size, est, wall, session.segments) \
                if est is not None and not isinstance(est, Unavailable) else None
            steady = None if tried is None else not isinstance(tried, Unavailable)
            moved = "" if tried is None else tried.reason if isinstance(tried, Unavailable) else tried.detail
            steady_s = time.process_time() - t2
            rows.append({"house": f"procedural:{seed}", "view": i, "mode": view.meta.get("mode"),
                         "f_true": f_true, "fov_true_deg": fov_from_focal(f_true, session.size),
                         "n_quads": int(len(quads)), "f": float(f), "sd": float(sd), "reason": reason,
                         "f_prior": prior_focal(session.size).focal_px, "width": session.size[0],
                         "height": session.size[1], "seconds": seconds, "stable": stable, "halves": halves,
                         "check_seconds": check_s, "steady": steady, "moved": moved, "steady_seconds": steady_s})
            if progress:
                r = rows[-1]
                print(f"  {r['house']} view {i:2d}: fov {r['fov_true_deg']:5.1f} deg, {r['n_quads']:2d} quads, "
                      + (f"f {f:6.0f} +- {sd:5.1f} (true {f_true:.0f}, z {abs(f - f_true) / sd:5.2f})"
                         if reason == "" else f"none: {reason[:70]}") + f"  [{r['seconds']:.1f} s]",
                      flush=True)
    return rows


def summarize(df, level: float = 0.90) -> str:
    """The calibration summary (see the module docstring) of a calibration table."""
    import numpy as np  # noqa: PLC0415

    from fenestra.pipeline import intrinsics as I  # noqa: PLC0415
    from fenestra.pipeline.types import Unavailable  # noqa: PLC0415

    lines = []
    fit = df[np.isfinite(df["f"]) & np.isfinite(df["sd"])].copy()
    fit["z"] = (fit["f"] - fit["f_true"]).abs() / fit["sd"]
    fit["rel_sd"] = fit["sd"] / fit["f"]
    fit["err"] = (fit["f"] - fit["f_true"]).abs() / fit["f_true"]
    df = df.assign(prior_err=(df["f_prior"] - df["f_true"]).abs() / df["f_true"])
    lines.append(f"{len(df)} views, {df['house'].nunique()} houses, true field of view "
                 f"{df['fov_true_deg'].min():.0f}-{df['fov_true_deg'].max():.0f} deg; a fit on {len(fit)} "
                 f"({100 * len(fit) / max(len(df), 1):.0f} %), none on {len(df) - len(fit)}")
    if len(fit) == 0:
        return "\n".join(lines)
    qs = [0.5, 0.68, 0.8, 0.9, 0.95]
    lines.append("z = |f - f_true| / sd quantiles: " + ", ".join(f"q{int(100 * q)} {np.quantile(fit['z'], q):.2f}"
                                                                    for q in qs))
    k = float(np.quantile(fit["z"], level))
    old_k = OLD_Z90 * OLD_INFLATION
    lines.append(f"calibrated multiplier (q{int(100 * level)} of z): {k:.2f} (in use: VP_SD_MULTIPLIER = "
                 f"{I.VP_SD_MULTIPLIER:g}; before: {OLD_Z90:.3f} x {OLD_INFLATION:g} = {old_k:.2f}); "
                 f"coverage of f +- {OLD_Z90:.3f} sd: {100 * np.mean(fit['z'] <= OLD_Z90):.0f} %, of the old "
                 f"x{OLD_INFLATION:g}: {100 * np.mean(fit['z'] <= old_k):.0f} %, of VP_SD_MULTIPLIER: "
                 f"{100 * np.mean(fit['z'] <= I.VP_SD_MULTIPLIER):.0f} %")
    boot = np.quantile(np.random.default_rng(0).choice(fit["z"].to_numpy(), (2000, len(fit))), level, axis=1)
    lines.append(f"its bootstrap 90 % range (2000 resamples of the views): {np.quantile(boot, 0.05):.2f}-"
                 f"{np.quantile(boot, 0.95):.2f}")
    edges = np.quantile(fit["rel_sd"], [0, 1 / 3, 2 / 3, 1])
    for lo, hi in zip(edges[:-1], edges[1:]):
        b = fit[(fit["rel_sd"] >= lo) & (fit["rel_sd"] <= hi)]
        lines.append(f"  rel sd {100 * lo:5.2f}-{100 * hi:5.2f} %: {len(b):3d} views, q{int(100 * level)} of z "
                     f"{np.quantile(b['z'], level):.2f}, coverage of the calibrated {k:.2f} sd "
                     f"{100 * np.mean(b['z'] <= k):.0f} %, focal error median {100 * b['err'].median():.1f} %")
    lines.append(f"the prior's focal error on all views: median {100 * df['prior_err'].median():.1f} %, "
                 f"p90 {100 * df['prior_err'].quantile(0.9):.1f} %")
    rules = {f"before: x{OLD_INFLATION:g} inflation, +-{100 * OLD_GATE:g} % gate":
             lambda r: OLD_Z90 * OLD_INFLATION * r["sd"] <= OLD_GATE * r["f"],
             f"in use: {I.VP_SD_MULTIPLIER:g} sd interval narrower than the prior's (intrinsics.vanishing_estimate)":
             lambda r: not isinstance(I.vanishing_estimate(r["f"], r["sd"], (int(r["width"]), int(r["height"]))), Unavailable)}
    if "stable" in fit:  # tables from before the stability check (issue 35) lack it
        used = list(rules.values())[-1]
        rules["with the stability check (the halves of the windows agree; intrinsics.vanishing_stability)"] = \
            lambda r: used(r) and str(r["stable"]) == "True"
        taken = fit[fit.apply(used, axis=1)]
        tested = taken[taken["halves"].fillna("").astype(str) != ""]
        unstable = taken[taken["stable"].astype(str) == "False"]
        lines.append(f"stability check on the {len(taken)} views the rule in use takes: tested on {len(tested)} "
                     f"(each half has enough windows), unstable {len(unstable)} (their focal error: "
                     f"{', '.join(f'{100 * e:.1f} %' for e in sorted(unstable['err'])) or '-'}, the prior's: "
                     f"{', '.join(f'{100 * e:.1f} %' for e in sorted(df.loc[unstable.index, 'prior_err'])) or '-'};"
                     f" inside f +- {I.VP_SD_MULTIPLIER:g} sd: {int((unstable['z'] <= I.VP_SD_MULTIPLIER).sum())});"
                     f" its CPU s per tested view median "
                     f"{tested['check_seconds'].median() if len(tested) else float('nan'):.2f}, max "
                     f"{tested['check_seconds'].max() if len(tested) else float('nan'):.2f}")
    if "steady" in fit:  # tables from before the steadiness check lack it
        stable_rule = list(rules.values())[-1]
        rules["with the steadiness check too (half size inside the interval, corners moved by about 1 px: "
              "an answer; intrinsics.vanishing_steadiness)"] = lambda r: stable_rule(r) and str(r["steady"]) == "True"
        tried = fit[fit["steady"].astype(str).isin(("True", "False"))]
        unsteady = tried[tried["steady"].astype(str) == "False"]
        lines.append(f"steadiness check on the {len(tried)} views the calibrated interval takes: unsteady "
                     f"{len(unsteady)} (their focal error median {100 * unsteady['err'].median():.1f} %, the prior's "
                     f"{100 * df.loc[unsteady.index, 'prior_err'].median():.1f} %; inside f +- "
                     f"{I.VP_SD_MULTIPLIER:g} sd: {int((unsteady['z'] <= I.VP_SD_MULTIPLIER).sum())}); its CPU s "
                     f"per view median {tried['steady_seconds'].median() if len(tried) else float('nan'):.2f}")
    for name, rule in rules.items():
        take = fit[fit.apply(rule, axis=1)] if len(fit) else fit
        chosen = np.concatenate([take["err"].to_numpy(),
                                 df.loc[~df.index.isin(take.index), "prior_err"].to_numpy()])
        cover = np.mean(take["z"] <= k) if len(take) else np.nan
        cover_in_use = np.mean(take["z"] <= I.VP_SD_MULTIPLIER) if len(take) else np.nan
        lines.append(f"{name}: vanishing points on {len(take)} of {len(df)} views ({100 * len(take) / len(df):.0f} %),"
                     f" their focal error median {100 * take['err'].median():.1f} % p90 "
                     f"{100 * take['err'].quantile(0.9):.1f} % (coverage of f +- {k:.2f} sd {100 * cover:.0f} %,"
                     f" of the interval in use, f +- {I.VP_SD_MULTIPLIER:g} sd, {100 * cover_in_use:.0f} %);"
                     f" the prior on those views: median {100 * df.loc[take.index, 'prior_err'].median():.1f} %;"
                     f" chosen focal error over all views median {100 * np.median(chosen):.1f} % "
                     f"p90 {100 * np.quantile(chosen, 0.9):.1f} %")
    return "\n".join(lines)


def kfree_focal_table(df) -> str:
    """The focal figures of a kfree.parquet table (fenestra.bench.photo_eval, rows of one dataset's
    photos as is and under image transforms): the as-is K sources, the spreads of
    kfree_summary.dataset_summary, the transform runs whose 90 % interval is disjoint from the as-is
    run's (a confident contradiction), and per photo its spread (the largest |f / f_as_is - 1| of its
    transform runs) and each run's focal length [interval] px and source (VP: vanishing points)."""
    import numpy as np  # noqa: PLC0415

    from fenestra.bench.kfree_summary import dataset_summary  # noqa: PLC0415

    df = df[df["transform"].isin(("as_is", "gray", "jpeg", "mirror", "crop"))]
    d = dataset_summary(df)
    base = df[df["transform"] == "as_is"].set_index("photo")
    t = df[df["transform"] != "as_is"]
    contra = [(p, tr) for p, tr, lo, hi in zip(t["photo"], t["transform"], t["focal_lo_px"], t["focal_hi_px"])
              if hi < base.focal_lo_px[p] or lo > base.focal_hi_px[p]]
    vp = df[df["K_source"] == "vanishing points"]
    spread = d["focal_spread_observed_median"]
    observed = "None" if spread is None else f"{spread:.3f}"
    lines = [f"as is: {d['K_sources']}; vanishing points on {len(vp)} of {len(df)} runs; focal_spread_observed_median "
             f"{observed} (focal_spread_n_observed {d['focal_spread_n_observed']}), "
             f"focal_spread_median (all photos) {d['focal_spread_median']:.3f}; transform runs whose interval is "
             f"disjoint from the as-is run's: {len(contra)} of {len(t)} ({', '.join(f'{p} {tr}' for p, tr in contra)})"]
    short = {"vanishing points": "VP"}
    for photo, g in df.groupby("photo", sort=True):
        g = g.set_index("transform")
        spread = max((abs(g.focal_px[tr] / g.focal_px["as_is"] - 1) for tr in g.index if tr != "as_is"), default=np.nan)
        lines.append(f"  {photo:8s} spread {spread:5.3f}: " + "  ".join(
            f"{tr} {g.focal_px[tr]:.0f} [{g.focal_lo_px[tr]:.0f}-{g.focal_hi_px[tr]:.0f}] "
            f"{short.get(g.K_source[tr], g.K_source[tr])}" for tr in ("as_is", "gray", "jpeg", "mirror", "crop")
            if tr in g.index and np.isfinite(g.focal_px[tr])))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n\n".join(__doc__.split("\n\n")[1:]))
    ap.add_argument("--seeds", default="100-105", help="procedural house seeds, e.g. 100-105 or 100,104 "
                                                       "(default 100-105; the bench uses 0-2)")
    ap.add_argument("--views", type=int, default=24, help="views per house (default 24)")
    ap.add_argument("--hfov", type=float, nargs=2, default=(30.0, 95.0), metavar=("LO", "HI"),
                    help="horizontal field of view range, deg (default 30 95)")
    ap.add_argument("--dataset-seed", type=int, default=1, help="the datasets' camera seed (default 1; the bench: 0)")
    ap.add_argument("--renders-dir", default="out/renders", help="where the views are rendered (default out/renders)")
    ap.add_argument("--out", default="out/focal-calibration/calibration.csv",
                    help="the table written (.csv or .parquet; default out/focal-calibration/calibration.csv)")
    ap.add_argument("--level", type=float, default=0.90, help="the interval's coverage to calibrate (default 0.90)")
    ap.add_argument("--summary", metavar="FILE", help="only summarize an existing table")
    ap.add_argument("--min-quads", type=int, default=None,
                    help="the stability check's windows per half (default: intrinsics.VP_SPLIT_MIN_QUADS)")
    ap.add_argument("--doc", type=Path, default=None, help="also write the summary into this Markdown file's block")
    ap.add_argument("--block", default="focal-calibration",
                    help="the block's name (<!-- NAME:begin --> ... <!-- NAME:end -->; default focal-calibration)")
    ap.add_argument("--kfree", metavar="PARQUET", nargs="+",
                    help="only print the focal figures of kfree.parquet tables (one dataset's photos as is and "
                         "under transforms; e.g. out/bench/real/kfree.parquet, spb_facades rows): the stability "
                         "of the focal chain on real photos (issue 35)")
    a = ap.parse_args(argv)
    import pandas as pd  # noqa: PLC0415

    if a.kfree:
        for name in a.kfree:
            df = pd.read_parquet(name)
            for dataset, g in df[df["transform"] == "gray"].groupby("dataset"):  # datasets run under transforms
                print(f"{name} ({dataset}):\n{kfree_focal_table(df[df['dataset'] == dataset])}")
        return 0
    if a.summary:
        path = Path(a.summary)
        df = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path, keep_default_na=False,
                                                                                 na_values=["", "nan", "NaN"])
    else:
        df = pd.DataFrame(calibration_rows(parse_seeds(a.seeds), a.views, tuple(a.hfov), a.dataset_seed,
                                           a.renders_dir, min_quads=a.min_quads))
        out = Path(a.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        df.to_parquet(out) if out.suffix == ".parquet" else df.to_csv(out, index=False)
        print(f"wrote {out} ({len(df)} views)")
    text = summarize(df, a.level)
    print(text)
    if a.doc is not None:
        from fenestra.reports.markdown import write_block  # noqa: PLC0415

        command = " ".join(["python tools/focal_calibration.py", *(sys.argv[1:] if argv is None else argv)])
        write_block(a.doc, a.block, f"`{command}`\n\n" + "\n".join(f"- {line.strip()}" for line in text.splitlines()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
