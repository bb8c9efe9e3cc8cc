"""Where the benchmark's time goes, as a fresh clone measures it (prints figures; not a test).

    .venv/bin/python -m bench.timing [--profile default] [--executor local] [--json out/timing.json] [--ray]

Runs ``fenestra bench`` twice in a fresh, empty working folder (so no cached render, scene or
result of this checkout is reused): first cold (procedural houses generated, every view rendered),
then again with the renders it just cached. Then each pose family's CPU cost per view (per-window
solvers, per-wall strategies, with K withheld) on a sample of those views. Then the render throughput of ``fenestra render`` at
the margin: (time for 60 views - time for 10 views) / 50, so start-up does not count. Prints one
JSON document: wall times, each stage's CPU seconds and share, matching's share of the CPU time,
per-view and per-window stage milliseconds, the machine's load average before and after, versions.
With ``--ray``, the cached-render run again on a local Ray cluster (a third run, its own folder).
The README's timing figures come from this command.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent  # the checkout whose `app` (command line) runs


def _fenestra(args: list[str], cwd: Path) -> float:
    """Run ``python -m app ARGS`` (the ``fenestra`` command of this checkout) in cwd; its wall
    seconds (raises on failure)."""
    t0 = time.perf_counter()
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    env = {**os.environ, "PYTHONPATH": path, "MPLBACKEND": "Agg",
           "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl")}
    r = subprocess.run([sys.executable, "-m", "app", *args], cwd=cwd, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"fenestra {' '.join(args)} failed ({r.returncode}): {r.stderr[-2000:]}")
    return time.perf_counter() - t0


def stage_split(summary: dict) -> dict:
    """CPU seconds per evaluation stage and each one's share of their total (from summary.json)."""
    st = summary["metadata"]["stage_time_s"]
    cpu = {k[4:]: v for k, v in st.items() if k.startswith("cpu.") and "." not in k[4:]}
    total = sum(cpu.values())
    return {"cpu_s": cpu, "cpu_total_s": total,
            "share": {k: v / total for k, v in cpu.items()} if total > 0 else {}}


def bench_run(profile: str, executor: str, cwd: Path, label: str) -> dict:
    """One ``fenestra bench`` run in cwd: wall seconds and the stage figures of its summary."""
    run = cwd / "out" / "bench" / label
    wall = _fenestra(["bench", "--profile", profile, "--out", str(run), "--executor", executor], cwd)
    summary = json.loads((run / "summary.json").read_text())
    meta = summary["metadata"]
    return {"wall_s": wall, "bench_wall_s": meta["wall_time_s"], "n_views": meta["n_views"],
            "n_rows": meta["n_rows"], "stage_time_s": meta["stage_time_s"], **stage_split(summary),
            "stage_ms_per_view": meta.get("stage_ms_per_view"),
            "stage_ms_per_window": meta.get("stage_ms_per_window")}


def pose_families(methods) -> dict[str, list]:
    """Methods (fenestra.methods.Method) by pose family, chosen by capability: every per-window
    solver together, then each per-wall strategy with K given, then with K withheld."""
    from pipeline.reconstruct import POSES  # noqa: PLC0415

    per_window = f"per-window ({', '.join(POSES.where(per_wall=False))})"
    out: dict[str, list] = {}
    for m in sorted(methods, key=lambda m: (POSES[m.pose].per_wall, m.withhold_K)):
        out.setdefault(m.pose_label if POSES[m.pose].per_wall else per_window, []).append(m)
    return out


def pose_costs(renders: Path, views_per_house: int = 6, profile: str = "default") -> dict:
    """CPU seconds per view of evaluate_task for each pose family (every detector x snapper of
    ``profile``), on the first views of each rendered house under ``renders``, in this process."""
    from bench.evaluate import evaluate_task  # noqa: PLC0415
    from bench.executors import init_worker, view_tasks  # noqa: PLC0415
    from bench.profiles import load_profile  # noqa: PLC0415
    from bench.runner import make_plan, plan_methods  # noqa: PLC0415

    init_worker()
    p = load_profile(profile)
    allm, _ = plan_methods(dataclasses.replace(p, methods=dataclasses.replace(
        p.methods, pose_solvers=("all",), withhold_K=(False, True))))
    houses = sorted(d for d in renders.iterdir() if (d / "views").is_dir())
    out = {}
    for family, members in pose_families(allm).items():
        methods = tuple(members)
        plan = make_plan(p, methods, renders, renders / "unused")
        tasks = [t for d in houses for t in view_tasks(plan, d.name, d)[:views_per_house]]
        evaluate_task(tasks[0])  # warm-up: detector weights
        stages: dict[str, float] = {}
        t0 = time.process_time()
        for t in tasks:
            for k, v in evaluate_task(t).stage_s.items():
                stages[k] = stages.get(k, 0.0) + v
        out[family] = {"methods": len(methods), "views": len(tasks),
                       "cpu_s_per_view": (time.process_time() - t0) / len(tasks),
                       "stage_cpu_s_per_view": {k: v / len(tasks) for k, v in stages.items() if "." not in k}}
    return out


def render_margin(cwd: Path, scene: str = "fzk-haus", few: int = 10, many: int = 60) -> dict:
    """Views per second of ``fenestra render`` at the margin (many - few views, fresh folders)."""
    t = {n: _fenestra(["render", "--scene", scene, "--views", str(n), "--out", str(cwd / f"render-{n}")], cwd)
         for n in (few, many)}
    per_view = (t[many] - t[few]) / (many - few)
    return {"scene": scene, "wall_s": {str(k): v for k, v in t.items()}, "s_per_view": per_view,
            "views_per_s": 1.0 / per_view if per_view > 0 else float("inf")}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="default")
    ap.add_argument("--executor", default="local")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    ap.add_argument("--skip-render", action="store_true", help="skip the render-throughput part")
    ap.add_argument("--ray", action="store_true",
                    help="also run the cached-render bench on a local Ray cluster (as many CPUs as cores) "
                         "and report its wall time against the local executor's")
    a = ap.parse_args(argv)
    from bench.results import versions  # noqa: PLC0415

    out = {"profile": a.profile, "executor": a.executor, "cpus": os.cpu_count(),
           "load_before": os.getloadavg(), "machine": platform.platform(), "versions": versions()}
    with tempfile.TemporaryDirectory(prefix="fenestra-timing-") as tmp:
        cwd = Path(tmp)
        out["cold"] = bench_run(a.profile, a.executor, cwd, "cold")
        out["cached_renders"] = bench_run(a.profile, a.executor, cwd, "cached")
        if a.ray:
            out["ray_cached_renders"] = bench_run(a.profile, "ray", cwd, "ray")
            out["ray_over_local_wall"] = out["ray_cached_renders"]["wall_s"] / out["cached_renders"]["wall_s"]
        out["pose_family_cost"] = pose_costs(cwd / "out" / "renders", profile=a.profile)
        if not a.skip_render:
            out["render"] = render_margin(cwd)
    out["load_after"] = os.getloadavg()
    text = json.dumps(out, indent=1)
    print(text)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(text)
    return out


if __name__ == "__main__":
    main()
