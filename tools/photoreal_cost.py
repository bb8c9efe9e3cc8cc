"""Photoreal (mitsuba) cost and quality: the figures behind the ``photoreal`` profile's settings.

    PYOPENGL_PLATFORM=egl .venv/bin/python tools/photoreal_cost.py speed [--views 6]
    PYOPENGL_PLATFORM=egl .venv/bin/python tools/photoreal_cost.py quality [--reference-spp 256]
    PYOPENGL_PLATFORM=egl .venv/bin/python tools/photoreal_cost.py bench [--workers 2] [--reuse]

``speed``: median wall and CPU seconds per view of ``renderer.render(camera)`` (path tracing + denoising +
ground truth; start-up and one warm-up view per setting excluded) for the settings used before
issue 17 (``OLD``) and the profile's, the two alternating view by view so that both see the same
load; prints the load average beside them and the median per-view ratio old/new.
``quality``: sRGB RMSE (0-255) against a high-spp reference of the same views, for a grid of
spp x denoiser (the measured trade-off). ``bench``: the photoreal bench with ``OLD`` and with the
profile's settings on the same views; prints detection AP / rate and median corner error per
detector x snapper as a Markdown table.

(A bench script, not a renders/ one: it runs the bench, which renders/ must not import.)
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time

import numpy as np

from fenestra.conventions import PAPER
from fenestra.methods import read_methods
from fenestra.renders.base import DENOISERS, RenderSettings

OLD = RenderSettings(spp=16, denoise="none")  # the photoreal profile before issue 17 (RenderSettings defaults then)
PROFILE = "photoreal"


def load_avg() -> list[float]:
    """1/5/15-minute load averages (the machine is shared: timings scale with them)."""
    return [round(x, 2) for x in os.getloadavg()]


def profile_settings(profile=None) -> RenderSettings:
    """The RenderSettings a profile (default: photoreal) renders with (seed: set per dataset)."""
    from fenestra.bench.profiles import load_profile
    from fenestra.bench.render_adapter import dataset_config

    p = load_profile(PROFILE) if profile is None else profile
    return dataset_config(p, p.source.scenes.houses[0], "out/renders").settings


def sample(scene_name: str, n: int, width: int, height: int, seed: int = 0):
    from fenestra.renders.sampler import SamplerConfig, sample_views
    from fenestra.scenes import load_scene

    scene = load_scene(scene_name)
    return scene, [v.camera for v in sample_views(scene, SamplerConfig(width=width, height=height), n, seed=seed).views]


def speed(scene_name: str, n_views: int, width: int, height: int) -> dict:
    """Old vs profile settings, alternating per view after one warm-up view each."""
    from fenestra.renders.photoreal import PhotorealRenderer

    scene, cams = sample(scene_name, n_views + 1, width, height)
    settings = {"old": OLD, "new": profile_settings()}
    renderers = {k: PhotorealRenderer(scene, s) for k, s in settings.items()}
    ts: dict[str, list[float]] = {k: [] for k in settings}
    cpu: dict[str, list[float]] = {k: [] for k in settings}
    load = [load_avg()]
    try:
        for i, cam in enumerate(cams):
            for k, r in renderers.items():
                t0, c0 = time.perf_counter(), time.process_time()
                r.render(cam)
                if i > 0:  # view 0 warms up (JIT compilation, denoiser set-up)
                    ts[k].append(time.perf_counter() - t0)
                    cpu[k].append(time.process_time() - c0)
        load.append(load_avg())
    finally:
        for r in renderers.values():
            r.close()
    ratio = np.array(ts["old"]) / np.array(ts["new"])
    return {"scene": scene_name, "size": [width, height], "views": n_views, "cpu_count": os.cpu_count(),
            "load_avg_before_after": load,
            "settings": {k: dataclasses.asdict(s) for k, s in settings.items()},
            "median_s_per_view": {k: float(np.median(v)) for k, v in ts.items()},
            # CPU seconds of all the process's threads: less sensitive to other processes' load;
            # / cpu_count = the wall time if the renderer had the cores to itself and used them fully
            "median_cpu_s_per_view": {k: float(np.median(v)) for k, v in cpu.items()},
            "s_per_view": {k: [round(x, 2) for x in v] for k, v in ts.items()},
            "median_ratio_old_over_new": float(np.median(ratio))}


def quality(scene_name: str, n_views: int, width: int, height: int, reference_spp: int,
            spps: list[int]) -> dict:
    """sRGB RMSE (0-255) of each spp x denoiser against reference_spp renders (independent sampler
    seed, not denoised) through the gaussian pixel filter (undenoised renders) and the box one (denoised)."""
    from fenestra.renders.photoreal import PhotorealRenderer, linear_to_srgb

    scene, cams = sample(scene_name, n_views, width, height, seed=1)
    srgb = lambda r, c, **kw: linear_to_srgb(r.render_linear(c.canvas(), **kw)) * 255  # noqa: E731
    refs = {}
    for den, filt in (("none", "gaussian"), ("oidn", "box")):
        with PhotorealRenderer(scene, dataclasses.replace(OLD, denoise=den)) as r:
            refs[filt] = [srgb(r, c, spp=reference_spp, seed=12345, denoise=False) for c in cams]
    rows = []
    for den in DENOISERS:
        for spp in spps:
            with PhotorealRenderer(scene, dataclasses.replace(OLD, spp=spp, denoise=den)) as r:
                srgb(r, cams[0])  # warm-up
                errs: dict[str, list[float]] = {f: [] for f in refs}
                ts = []
                for i, c in enumerate(cams):
                    t0 = time.perf_counter()
                    img = srgb(r, c)
                    ts.append(time.perf_counter() - t0)
                    for f, ref in refs.items():
                        errs[f].append(float(np.sqrt(np.mean((img - ref[i]) ** 2))))
            rows.append({"spp": spp, "denoise": den, "pixel_filter": "gaussian" if den == "none" else "box",
                         **{f"rmse_vs_{f}_ref": round(float(np.mean(e)), 2) for f, e in errs.items()},
                         "median_s": round(float(np.median(ts)), 2)})
    return {"scene": scene_name, "size": [width, height], "views": n_views, "reference_spp": reference_spp,
            "load_avg": load_avg(), "rows": rows}


def paired_snap_errors(old_dir, new_dir) -> dict[str, tuple[float, float, int]]:
    """{method: (fraction of windows with a lower snapped corner error in new, Wilcoxon p, n)} over
    the windows evaluable and detected in both runs (same views: same cameras and ground truth)."""
    import pandas as pd
    from scipy.stats import wilcoxon

    key = ["method", "house", "view", "window_id"]
    cols = key + ["corner_err_px_snap"]
    df = [pd.read_parquet(d / "results.parquet") for d in (old_dir, new_dir)]
    df = [d.loc[d["evaluable"].astype(bool), cols].dropna() for d in df]
    both = df[0].merge(df[1], on=key, suffixes=("_old", "_new"))
    out = {}
    for m, g in both.groupby("method"):
        a, b = g["corner_err_px_snap_old"].to_numpy(), g["corner_err_px_snap_new"].to_numpy()
        p = float(wilcoxon(a, b).pvalue) if np.any(a != b) else 1.0
        out[m] = (float(np.mean(b < a)), p, len(g))
    return out


def bench(workers: int, reuse: bool = False) -> str:
    """The photoreal bench with OLD and with the profile's settings; a Markdown comparison table.
    reuse: read a run's summary.json if its run folder (named by the profile's config hash) has one."""
    from fenestra.bench.profiles import load_profile
    from fenestra.bench.runner import default_run_dir, run_benchmark

    new = load_profile(PROFILE)
    opts = dict(new.source.render.options)
    old_settings = {k: v for k, v in dataclasses.asdict(OLD).items() if k in ("spp", "denoise")}
    old_render = dataclasses.replace(
        new.source.render, options=tuple(sorted({**opts, "settings": {**opts.get("settings", {}), **old_settings}}.items())))
    old = dataclasses.replace(new, source=dataclasses.replace(new.source, render=old_render))
    dirs, s = {}, {}
    for label, prof in (("old", old), ("new", new)):
        dirs[label] = default_run_dir(prof)
        if not (reuse and (dirs[label] / "summary.json").is_file()):
            dirs[label] = run_benchmark(prof, workers=workers, report=False).run_dir
        s[label] = json.loads((dirs[label] / "summary.json").read_text())
    st = {"old": profile_settings(old), "new": profile_settings(new)}
    lines = ["; ".join(f"{k}: spp {st[k].spp}, denoise {st[k].denoise} ({dirs[k]})" for k in st)
             + f"; views {s['new']['metadata']['n_views']}, load avg {load_avg()}",
             "", "| detector | segm AP old → new | snapper | detected old → new "
             "| median corner error px old → new | paired: new lower on | Wilcoxon p |", "|---|---|---|---|---|---|---|"]
    pairs = paired_snap_errors(dirs["old"], dirs["new"])
    methods = read_methods(s["new"]["results"])
    for m in sorted(methods):
        det, snap = methods[m].detector, methods[m].snapper
        if methods[m].pose_label != PAPER.pose:
            continue
        ro, rn = s["old"]["results"][m], s["new"]["results"][m]
        ap = lambda k: 100 * s[k]["detection"][det]["segm_AP"] if det in s[k]["detection"] else None  # noqa: E731
        fmt = lambda x, f: "n/a" if x is None else format(x, f)  # noqa: E731
        lines.append(f"| {det} | {fmt(ap('old'), '.1f')} → {fmt(ap('new'), '.1f')} | {snap} | "
                     f"{ro['detection_rate']:.0%} → {rn['detection_rate']:.0%} | "
                     f"{fmt(ro['corner_err_px_snap']['median'], '.2f')} → "
                     f"{fmt(rn['corner_err_px_snap']['median'], '.2f')} | "
                     f"{pairs[m][0]:.0%} of {pairs[m][2]} | {pairs[m][1]:.2g} |")
    lines.append("")
    lines.append(f"render stage s ({s['new']['metadata']['n_views']} views, summary.json): " + ", ".join(
        f"{k} {s[k]['metadata']['stage_time_s']['render']:.0f}" for k in s))
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("speed", "quality", "bench"))
    ap.add_argument("--scene", default="fzk-haus")
    ap.add_argument("--views", type=int, default=6)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--reference-spp", type=int, default=256)
    ap.add_argument("--spp", type=int, nargs="+", default=[2, 4, 8, 16])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--reuse", action="store_true", help="bench: reuse finished runs (summary.json) of the same config")
    a = ap.parse_args()
    if a.what == "speed":
        print(json.dumps(speed(a.scene, a.views, a.width, a.height), indent=1))
    elif a.what == "quality":
        print(json.dumps(quality(a.scene, a.views, a.width, a.height, a.reference_spp, a.spp), indent=1))
    else:
        print(bench(a.workers, a.reuse))


if __name__ == "__main__":
    main()
