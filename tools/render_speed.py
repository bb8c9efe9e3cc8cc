"""Render-speed benchmark (prints figures; not a test).

    PYOPENGL_PLATFORM=egl .venv/bin/python tools/render_speed.py [--scene fzk-haus] [--views 30] [--mitsuba-views 3]
        [--antialias fxaa|msaa4|none]

Warm-up views first, then the median seconds per view of ``renderer.render(camera)`` (RGB +
instances + depth + ground truth; file writing excluded), printed as JSON with versions.
"""
from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np


def bench(name: str, scene, views, settings, warmup: int = 2) -> dict:
    from fenestra.renders.backends import make_renderer

    r = make_renderer(name, scene, settings)
    try:
        for v in views[:warmup]:
            r.render(v.camera)
        ts = []
        for v in views[warmup:]:
            t0 = time.perf_counter()
            r.render(v.camera)
            ts.append(time.perf_counter() - t0)
    finally:
        r.close()
    med = float(np.median(ts))
    return {"renderer": name, "views": len(ts), "median_s_per_view": med, "p90_s": float(np.percentile(ts, 90)),
            "views_per_s": 1.0 / med}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="fzk-haus")
    ap.add_argument("--views", type=int, default=30)
    ap.add_argument("--mitsuba-views", type=int, default=3)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--antialias", default="fxaa", choices=("fxaa", "msaa4", "none"), help="raster antialiasing")
    a = ap.parse_args()
    import mitsuba
    import pyrender  # noqa: F401

    from fenestra.renders.base import RenderSettings
    from fenestra.renders.sampler import SamplerConfig, sample_views
    from fenestra.scenes import load_scene

    scene = load_scene(a.scene)
    cfg = SamplerConfig(width=a.width, height=a.height)
    views = sample_views(scene, cfg, a.views + 2, seed=0).views
    out = {"scene": a.scene, "size": [a.width, a.height], "python": platform.python_version(),
           "mitsuba": mitsuba.__version__, "antialias": a.antialias,
           "results": [bench("pyrender", scene, views, RenderSettings(seed=0, antialias=a.antialias))]}
    if a.mitsuba_views > 0:
        out["results"].append(bench("mitsuba", scene, views[: a.mitsuba_views + 1], RenderSettings(seed=0, spp=a.spp),
                                    warmup=1))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
