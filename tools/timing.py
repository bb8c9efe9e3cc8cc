"""Where the benchmark's time goes, as a fresh clone measures it (prints figures; not a test).

    .venv/bin/python tools/timing.py [--profile default] [--executor local] [--json out/timing.json] [--ray]

Runs ``fenestra bench`` twice in a fresh, empty working folder (so no cached render, scene or
result of this checkout is reused, and the caches outside the checkout, :func:`fresh_caches`, start
empty too): first cold (procedural houses generated, scenes tessellated, shaders compiled, every
view rendered), then again with the renders and caches it just filled. Then each pose family's CPU cost per view (per-window
solvers, per-wall strategies, with K withheld) on a sample of those views. Then the render throughput of ``fenestra render`` at
the margin: (time for 60 views - time for 10 views) / 50, so start-up does not count. Prints one
JSON document: wall times, each stage's CPU seconds and share, matching's share of the CPU time,
per-view and per-window stage milliseconds, the machine's load average before and after, versions.
With ``--ray``, the cached-render run again on a local Ray cluster (a third run, its own folder).
Each run also records its artefacts' sizes and its peak memory (summary.json ``peak_rss_mb``).

``--fresh-clone DIR`` also measures what a new user meets: DIR is a ``git clone`` of this
checkout's HEAD on which ``make setup`` ran (the tool refuses another commit or a dirty clone);
``/usr/bin/time -v make bench`` runs there (it must have no out/ yet) with the caches outside a
checkout fresh in a temporary folder,
and the block compares its wall time with the cold run's (agreement within FRESH_CLONE_AGREEMENT).

The floor (:func:`floor`): each learned detector's CPU seconds per view on the cold run's renders
(:func:`detector_costs`) and the render's at the margin, times the views, against the CPU seconds
of the cold run's stages (its renders' included): the ratio of the bench to what it cannot skip.
``--from-run RUN --floor [--profile PROFILE]`` measures it for one finished run instead.

``--markdown docs/performance.md`` writes the figures as a Markdown block between the markers
``<!-- timing:begin -->`` and ``<!-- timing:end -->`` of that file (the docs' speed figures come
from this command, never typed), and the floor between ``<!-- floor:begin -->`` and ``<!-- floor:end -->``
(with ``--from-run RUN --floor``, that block only). ``--from-json out/timing.json`` takes the figures of an earlier
measurement instead of measuring; ``--from-run RUN`` those of one finished bench run folder
(its summary.json; ``--time-log`` the ``/usr/bin/time -v`` output of that run, for its peak RSS
over every process).
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


def fresh_caches(cwd: Path) -> dict[str, str]:
    """Environment that points every cache a run fills outside its checkout into ``cwd/cache``
    (issue 34): the tessellated scenes (``$FENESTRA_CACHE``, else ~/.cache/fenestra/scenes), Mesa's
    compiled shaders (~/.cache/mesa_shader_cache), matplotlib's font cache (~/.cache/matplotlib or
    ~/.config/matplotlib), anything else under $XDG_CACHE_HOME. Without it a machine that ran the
    bench before serves the "cold" run from those caches, which a fresh machine does not have."""
    c = cwd / "cache"
    return {"XDG_CACHE_HOME": str(c), "FENESTRA_CACHE": str(c / "fenestra" / "scenes"),
            "MESA_SHADER_CACHE_DIR": str(c / "mesa_shader_cache"), "MPLCONFIGDIR": str(c / "matplotlib")}


def _fenestra(args: list[str], cwd: Path) -> float:
    """Run ``python -m fenestra ARGS`` (the ``fenestra`` command of this checkout) in cwd, with the
    caches outside a checkout fresh in cwd (:func:`fresh_caches`); its wall seconds (raises on failure)."""
    t0 = time.perf_counter()
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    env = {**os.environ, "PYTHONPATH": path, "MPLBACKEND": "Agg",
           "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl"), **fresh_caches(cwd)}
    r = subprocess.run([sys.executable, "-m", "fenestra", *args], cwd=cwd, env=env, capture_output=True, text=True)
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


def artefact_mb(run: Path) -> dict[str, float]:
    """Size (MB) of each file a run folder holds (figures/ as one entry), and their ``total``."""
    sizes = {p.name: sum(f.stat().st_size for f in ([p] if p.is_file() else p.rglob("*")) if f.is_file()) / 1e6
             for p in sorted(Path(run).iterdir())}
    return {**sizes, "total": sum(sizes.values())}


def run_figures(run: Path, wall_s: float | None = None) -> dict:
    """The figures of one finished bench run folder: wall seconds (``wall_s``, else the run's
    own), the stage figures of its summary, its artefacts' sizes and its peak memory."""
    summary = json.loads((Path(run) / "summary.json").read_text())
    meta = summary["metadata"]
    return {"wall_s": meta["wall_time_s"] if wall_s is None else wall_s, "bench_wall_s": meta["wall_time_s"],
            "n_views": meta["n_views"], "n_rows": meta["n_rows"], "n_methods": len(meta.get("methods", [])),
            "commit": meta.get("commit"), "stage_time_s": meta["stage_time_s"], **stage_split(summary),
            "stage_ms_per_view": meta.get("stage_ms_per_view"),
            "stage_ms_per_window": meta.get("stage_ms_per_window"), "artefact_mb": artefact_mb(run),
            "peak_rss_mb": meta.get("peak_rss_mb"), "load_average": meta.get("load_average")}


def bench_run(profile: str, executor: str, cwd: Path, label: str) -> dict:
    """One ``fenestra bench`` run in cwd: wall seconds and the figures of its run folder."""
    run = cwd / "out" / "bench" / label
    wall = _fenestra(["bench", "--profile", profile, "--out", str(run), "--executor", executor], cwd)
    return run_figures(run, wall)


def time_log_rss_mb(text: str) -> float | None:
    """Peak RSS (MB) from ``/usr/bin/time -v`` output ("Maximum resident set size (kbytes): N"),
    or None."""
    import re  # noqa: PLC0415

    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    return None if m is None else int(m.group(1)) / 1024.0


FRESH_CLONE_AGREEMENT = 0.15  # issue 34: a fresh clone's `make bench` and `make timing`'s cold run agree within 15 %


def _git(clone: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(clone), *args], capture_output=True, text=True, check=True).stdout.strip()


def check_clone(clone: Path) -> str:
    """The clone's commit; SystemExit when it is not a clean clone of this checkout's HEAD with a
    set-up virtual environment (``make setup``)."""
    head, theirs = _git(ROOT, "rev-parse", "HEAD"), _git(clone, "rev-parse", "HEAD")
    if theirs != head:
        raise SystemExit(f"error: --fresh-clone {clone} is at {theirs[:7]}, this checkout at {head[:7]}: "
                         f"`git -C {clone} fetch {ROOT} && git -C {clone} checkout {head[:7]}`")
    if _git(clone, "status", "--porcelain", "--untracked-files=no"):
        raise SystemExit(f"error: --fresh-clone {clone} has local changes: a fresh clone has none")
    if not (clone / ".venv" / "bin" / "python").is_file():
        raise SystemExit(f"error: --fresh-clone {clone} has no .venv: run `make -C {clone} setup` first")
    if (clone / "out").exists():
        raise SystemExit(f"error: --fresh-clone {clone} has an out/ folder (renders, runs): a fresh clone has none; "
                         "clone again (nothing there is deleted)")
    return head


def fresh_clone_bench(clone: Path) -> dict:
    """``/usr/bin/time -v make bench`` in a fresh clone (see the module docstring): its wall
    seconds as the user's shell sees them, peak RSS of any process (time -v), and the figures of
    the run folder it wrote (out/bench/default*). The clone must have no out/ yet
    (:func:`check_clone`); the caches and the time log go to a temporary folder, so nothing of the
    clone is deleted or overwritten."""
    commit = check_clone(clone)
    with tempfile.TemporaryDirectory(prefix="fenestra-fresh-clone-") as tmp:
        env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
        env.update({"MPLBACKEND": "Agg", "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl"),
                    **fresh_caches(Path(tmp))})
        log = Path(tmp) / "time-v.log"
        t0 = time.perf_counter()
        r = subprocess.run(["/usr/bin/time", "-v", "-o", str(log), "make", "bench"], cwd=clone, env=env,
                           capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            raise RuntimeError(f"make bench in {clone} failed ({r.returncode}): {r.stderr[-2000:]}")
        log_text = log.read_text()
    run = max((clone / "out" / "bench").glob("default*"), key=lambda p: p.stat().st_mtime)
    fig = run_figures(run, wall)
    rss = time_log_rss_mb(log_text)
    if rss is not None:
        fig["peak_rss_mb"] = {"any_process (time -v)": rss}
    return {**fig, "commit": commit, "make_bench_wall_s": wall}


def agreement(doc: dict) -> dict | None:
    """The fresh clone's `make bench` wall time over the cold run's, and whether they agree
    within FRESH_CLONE_AGREEMENT (None without both)."""
    a, b = doc.get("fresh_clone"), doc.get("cold")
    if not a or not b:
        return None
    ratio = a["wall_s"] / b["wall_s"]
    return {"ratio": ratio, "within": bool(abs(ratio - 1) <= FRESH_CLONE_AGREEMENT), "limit": FRESH_CLONE_AGREEMENT}


BEGIN, END = "<!-- timing:begin -->", "<!-- timing:end -->"
RUN_LABELS = {"fresh_clone": "`git clone`, `make setup`, then `/usr/bin/time make bench`",
              "cold": "`make timing`: fresh folder and caches, renders included", "cached_renders": "cached renders",
              "ray_cached_renders": "cached renders, `--executor ray` (local cluster)", "run": "one run"}


def _s(x) -> str:
    return "-" if x is None else f"{x:.0f} s" if x >= 10 else f"{x:.1f} s"


def markdown(doc: dict, command: str) -> str:
    """The figures of a timing document (:func:`main`'s) as a Markdown block: one row per bench
    run (wall time, stages, peak memory, artefacts), then each pose family's CPU cost per view
    and the render throughput, where measured; ``command`` is the one that made them."""
    lines = [BEGIN, f"Generated by `{command}`, profile `{doc['profile']}`, {doc.get('cpus', '?')} CPUs; "
             f"load average before {_load(doc.get('load_before'))}, after {_load(doc.get('load_after'))}"
             + (" (the machine was shared: compare ratios, not absolute times)." if _busy(doc) else "."), "",
             "| run | commit | views | methods | rows | wall | render | evaluation | tables | report | "
             "peak RSS | artefacts |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, label in RUN_LABELS.items():
        r = doc.get(key)
        if not r:
            continue
        st = r["stage_time_s"]
        rss = r.get("peak_rss_mb") or {}
        peak = max([v for v in rss.values() if v] or [0.0])
        art = r.get("artefact_mb") or {}
        lines.append(f"| {label} | {(r.get('commit') or '?')[:7]} | {r['n_views']} | {r.get('n_methods', '-')} | "
                     f"{r['n_rows']} | **{_s(r['wall_s'])}** | {_s(st.get('render'))} | {_s(st.get('evaluate_wall'))} | "
                     f"{_s(st.get('summarize'))} | {_s(st.get('report'))} | "
                     f"{f'{peak / 1024:.2f} GB' if peak else '-'} | {art.get('total', 0):.1f} MB |")
    agree = agreement(doc)
    if agree:
        lines += ["", f"A fresh clone's `make bench` against `make timing`'s cold run: {agree['ratio']:.2f} x the wall "
                      f"time ({'within' if agree['within'] else '**outside**'} the +-{100 * agree['limit']:.0f} % "
                      "the two must agree by)."]
    for key, label in RUN_LABELS.items():
        r = doc.get(key)
        if r and r.get("cpu_s"):
            lines += ["", f"CPU seconds by stage ({label}; summed over the worker processes): "
                      + ", ".join(f"{k} {v:.0f} s ({100 * r['share'][k]:.0f} %)"
                                  for k, v in sorted(r["cpu_s"].items(), key=lambda kv: -kv[1])) + "."]
            art = {k: v for k, v in (r.get("artefact_mb") or {}).items() if k != "total"}
            if art:
                lines.append("Artefacts: " + ", ".join(f"`{k}` {v:.1f} MB" for k, v in art.items()) + ".")
            break
    fam = doc.get("pose_family_cost")
    if fam:
        lines += ["", "| pose family | methods | CPU s / view |", "|---|---|---|"]
        lines += [f"| {k} | {v['methods']} | {v['cpu_s_per_view']:.2f} |" for k, v in fam.items()]
    r = doc.get("render")
    if r:
        cpu = f", {r['cpu_s_per_view']:.3f} CPU-s per view" if "cpu_s_per_view" in r else ""
        lines += ["", f"`fenestra render --scene {r['scene']}` at the margin ({' minus '.join(reversed(list(r['wall_s'])))} "
                  f"views): **{r['views_per_s']:.1f} views/s**{cpu}."]
    return "\n".join([*lines, END])


def _load(x) -> str:
    return "-" if not x else "/".join(f"{v:.1f}" for v in x)


def _busy(doc: dict) -> bool:
    cpus = doc.get("cpus") or 1
    return any(x and x[0] > 0.75 * cpus for x in (doc.get("load_before"), doc.get("load_after")))


FLOOR_BEGIN, FLOOR_END = "<!-- floor:begin -->", "<!-- floor:end -->"


def floor_markdown(doc: dict, command: str) -> str | None:
    """The floor of a timing document (:func:`floor`) and the run's ratio to it, as a Markdown
    block between the floor markers; None without the figures."""
    fl = floor(doc, doc.get("floor_run", "cold"))
    if not fl:
        return None
    det = doc["detector_cost"]["cpu_s_per_view"]
    run = doc[fl["run"]]
    stages = ", ".join(f"{k} {v:.0f}" for k, v in sorted(fl["bench_stages_cpu_s"].items(), key=lambda kv: -kv[1]))
    return "\n".join([
        FLOOR_BEGIN, f"Generated by `{command}`, profile `{doc['profile']}` ({fl['views']} views, "
        f"{run.get('n_methods', '?')} methods, commit {(run.get('commit') or '?')[:7]}), {doc.get('cpus', '?')} CPUs; load "
        f"average before {_load(doc.get('load_before'))}, after {_load(doc.get('load_after'))}.", "",
        "| | CPU-s |", "|---|---|",
        *[f"| detector `{k}`, per view ({doc['detector_cost']['views']} views) | {v:.3f} |" for k, v in det.items()],
        f"| render at the margin, per view (`fenestra render --scene {doc['render']['scene']}`) | "
        f"{doc['render']['cpu_s_per_view']:.3f} |",
        f"| **floor**: detect {fl['floor_cpu_s']['detect']:.0f} + render {fl['floor_cpu_s']['render']:.0f} | "
        f"**{fl['floor_total_cpu_s']:.0f}** |",
        f"| the run's stages ({stages}) | {fl['bench_cpu_s']:.0f} |",
        f"| **ratio** of the run to its floor | **{fl['ratio']:.2f}** |", FLOOR_END])


def write_markdown(path: Path, block: str, begin: str = BEGIN, end: str = END) -> Path:
    """Put ``block`` between the markers ``begin`` and ``end`` (the timing block's by default) of
    the Markdown file ``path`` (appended when it has none)."""
    text = path.read_text() if path.is_file() else ""
    if begin in text and end in text:
        text = text[:text.index(begin)] + block + text[text.index(end) + len(end):]
    else:
        text = text.rstrip("\n") + ("\n\n" if text else "") + block + "\n"
    path.write_text(text)
    return path


def pose_families(methods) -> dict[str, list]:
    """Methods (fenestra.methods.Method) by pose family, chosen by capability: every per-window
    solver together, then each per-wall strategy with K given, then with K withheld."""
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415

    per_window = f"per-window ({', '.join(POSES.where(per_wall=False))})"
    out: dict[str, list] = {}
    for m in sorted(methods, key=lambda m: (POSES[m.pose].per_wall, m.withhold_K)):
        out.setdefault(m.pose_label if POSES[m.pose].per_wall else per_window, []).append(m)
    return out


def pose_costs(renders: Path, views_per_house: int = 6, profile: str = "default") -> dict:
    """CPU seconds per view of evaluate_task for each pose family (every detector x snapper of
    ``profile``), on the first views of each rendered house under ``renders``, in this process."""
    from fenestra.bench.evaluate import evaluate_task  # noqa: PLC0415
    from fenestra.bench.executors import init_worker, view_tasks  # noqa: PLC0415
    from fenestra.bench.profiles import load_profile, selected  # noqa: PLC0415
    from fenestra.bench.runner import make_plan, plan_methods  # noqa: PLC0415

    init_worker()
    p = load_profile(profile)
    # every detector x snapper the profile names (a designed profile's grids: their union), every pose
    allm, _ = plan_methods(dataclasses.replace(p, methods=dataclasses.replace(
        p.methods, detectors=tuple(selected(p.methods, "detectors")), snappers=tuple(selected(p.methods, "snappers")),
        pose_solvers=("all",), withhold_K=(False, True), grids=())))
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


def _children_cpu_s() -> float:
    """User + system CPU seconds of this process's finished children (resource.getrusage)."""
    import resource  # noqa: PLC0415

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def render_margin(cwd: Path, scene: str = "fzk-haus", few: int = 10, many: int = 60) -> dict:
    """Views per second of ``fenestra render`` at the margin (many - few views, fresh folders),
    after one uncounted warm-up render (the first render of a machine fills the driver's shader and
    the scene caches, which would otherwise be charged to the few-view run), and its CPU seconds
    per view at the margin (the render process's, its GL driver's threads included). NaN if the
    margin is not positive (a measurement drowned in noise, never an infinite rate)."""
    _fenestra(["render", "--scene", scene, "--views", "2", "--out", str(cwd / "render-warmup")], cwd)
    t, cpu = {}, {}
    for n in (few, many):
        c0 = _children_cpu_s()
        t[n] = _fenestra(["render", "--scene", scene, "--views", str(n), "--out", str(cwd / f"render-{n}")], cwd)
        cpu[n] = _children_cpu_s() - c0
    per_view = (t[many] - t[few]) / (many - few)
    return {"scene": scene, "wall_s": {str(k): v for k, v in t.items()}, "s_per_view": per_view,
            "views_per_s": 1.0 / per_view if per_view > 0 else float("nan"),
            "cpu_s": {str(k): v for k, v in cpu.items()}, "cpu_s_per_view": (cpu[many] - cpu[few]) / (many - few)}


def detector_costs(datasets: list[Path], views_per_house: int = 4, profile: str = "default") -> dict:
    """CPU seconds per view of each learned detector of ``profile`` (what the bench's session runs
    once per view: pipeline.detectors.detect at the CLI's resolution, down to the candidates' score,
    one torch thread), on the first views of each rendered house (``datasets``: their folders), in
    this process, after one uncounted warm-up call per detector (its weights load)."""
    from fenestra.bench.evaluate import view_session  # noqa: PLC0415
    from fenestra.bench.executors import init_worker, view_tasks  # noqa: PLC0415
    from fenestra.bench.profiles import load_profile  # noqa: PLC0415
    from fenestra.bench.runner import make_plan, plan_methods  # noqa: PLC0415
    from fenestra.pipeline.detectors import detector_entry  # noqa: PLC0415

    init_worker()
    p = load_profile(profile)
    methods, _ = plan_methods(p)
    plan = make_plan(p, methods, None, Path("unused"))
    learned = [d for d in dict.fromkeys(m.detector for m in methods) if not detector_entry(d).needs_instances]
    views = [t.source.load() for d in datasets for t in view_tasks(plan, d.name, d)[:views_per_house]]
    out = {}
    for det in learned:
        view_session(views[0], plan.options, (det,)).candidates(det)  # warm-up: weights
        t0 = time.process_time()
        for v in views:
            view_session(v, plan.options, (det,)).candidates(det)
        out[det] = (time.process_time() - t0) / len(views)
    return {"views": len(views), "cpu_s_per_view": out}


def floor(doc: dict, run_key: str = "cold") -> dict | None:
    """The bench's floor in CPU seconds: every learned detector's forward pass on every view
    (:func:`detector_costs`) plus rendering every view at the margin (:func:`render_margin`'s CPU
    seconds per view), against the CPU seconds the stages of run ``run_key`` took (``cpu.*`` of its
    summary: the cold run's, whose views were rendered, as a fresh clone's are); None without the
    figures."""
    det, ren, run = doc.get("detector_cost"), doc.get("render"), doc.get(run_key)
    if not det or not ren or not run or "cpu_s_per_view" not in ren:
        return None
    n = run["n_views"]
    parts = {"detect": n * sum(det["cpu_s_per_view"].values()), "render": n * ren["cpu_s_per_view"]}
    bench = dict(run["cpu_s"])
    total = sum(parts.values())
    return {"views": n, "floor_cpu_s": parts, "floor_total_cpu_s": total, "bench_stages_cpu_s": bench,
            "bench_cpu_s": sum(bench.values()), "ratio": sum(bench.values()) / total if total > 0 else float("nan"),
            "run": run_key}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="default")
    ap.add_argument("--executor", default="local")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    ap.add_argument("--skip-render", action="store_true", help="skip the render-throughput part")
    ap.add_argument("--ray", action="store_true",
                    help="also run the cached-render bench on a local Ray cluster (as many CPUs as cores) "
                         "and report its wall time against the local executor's")
    ap.add_argument("--markdown", type=Path, default=None,
                    help="write the figures as a Markdown block between the timing markers of this file")
    ap.add_argument("--from-json", type=Path, default=None, help="take the figures of this earlier --json output")
    ap.add_argument("--from-run", type=Path, default=None, help="take the figures of this finished bench run folder")
    ap.add_argument("--time-log", type=Path, default=None, help="with --from-run: that run's /usr/bin/time -v output")
    ap.add_argument("--floor", action="store_true",
                    help="with --from-run: measure the floor instead (the detectors on that run's renders, "
                         "rendering at the margin) and the run's ratio to it; --markdown then writes the floor block only")
    ap.add_argument("--fresh-clone", type=Path, default=None,
                    help="also run `/usr/bin/time -v make bench` in this clean `git clone` of HEAD (after `make setup`)")
    a = ap.parse_args(argv)
    if a.fresh_clone is not None:
        check_clone(a.fresh_clone.resolve())  # refuse before measuring for minutes
    if a.from_json is not None:
        out = json.loads(a.from_json.read_text())
    elif a.from_run is not None:
        out = from_run(a.from_run, a.time_log)
        if a.floor:
            out.update(run_floor(a.from_run, a.profile if a.profile != "default" else None))
    else:
        out = measure(a)
    if a.fresh_clone is not None:
        out["fresh_clone"] = fresh_clone_bench(a.fresh_clone.resolve())
        out["fresh_clone_agreement"] = agreement(out)
        out["load_after"] = os.getloadavg()
    text = json.dumps(out, indent=1)
    print(text)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(text)
    if a.markdown:
        command = "python tools/timing.py " + " ".join(str(x) for x in (argv if argv is not None else sys.argv[1:]))
        if not (a.from_run is not None and a.floor):  # a run's floor alone leaves the timing block as it is
            write_markdown(a.markdown, markdown(out, command))
        block = floor_markdown(out, command)
        if block:
            write_markdown(a.markdown, block, FLOOR_BEGIN, FLOOR_END)
    return out


def run_floor(run: Path, profile: str | None = None) -> dict:
    """The floor's figures for one finished run folder (:func:`floor`): its learned detectors on
    its renders (summary.json ``datasets``) and ``fenestra render`` at the margin, in a temporary
    folder. profile: the run's profile (name or TOML path; default: the name its summary gives)."""
    meta = json.loads((Path(run) / "summary.json").read_text())["metadata"]
    datasets = [Path(d) for d in meta["datasets"].values()]
    with tempfile.TemporaryDirectory(prefix="fenestra-floor-") as tmp:
        ren = render_margin(Path(tmp))
    return {"detector_cost": detector_costs(datasets, profile=profile or meta["profile"]), "render": ren,
            "floor_run": "run"}


def from_run(run: Path, time_log: Path | None = None) -> dict:
    """A timing document of one finished run folder (its profile, the run's figures as ``run``);
    time_log: its /usr/bin/time -v output, whose peak RSS (every process) replaces the run's own."""
    fig = run_figures(run)
    if time_log is not None and (rss := time_log_rss_mb(time_log.read_text())) is not None:
        fig["peak_rss_mb"] = {"any_process (time -v)": rss}
    summary = json.loads((Path(run) / "summary.json").read_text())
    load = fig.get("load_average") or {}
    return {"profile": summary["metadata"].get("profile"), "cpus": os.cpu_count(),
            "load_before": load.get("before"), "load_after": load.get("after"), "run": fig}


def measure(a: argparse.Namespace) -> dict:
    """Measure as the module docstring says (two or three bench runs, pose families, render)."""
    from fenestra.bench.results import versions  # noqa: PLC0415

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
        renders = cwd / "out" / "renders"
        out["detector_cost"] = detector_costs(sorted(d for d in renders.iterdir() if (d / "views").is_dir()),
                                              profile=a.profile)
        if not a.skip_render:
            out["render"] = render_margin(cwd)
    out["load_after"] = os.getloadavg()
    return out


if __name__ == "__main__":
    main()
