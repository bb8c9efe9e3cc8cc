"""CLI commands of bench/ (registered on the `fenestra` app by fenestra/app/cli.py).

    fenestra bench --profile smoke [--out DIR] [--workers N] [--no-report] [--executor local|ray] [--real RUN_DIR]
    fenestra bench --profile real [--data DIR --format coco|yolo|labelmap|curtainwall] [--sim RUN_DIR]
    fenestra gate RUN_DIR [--gates FILE] [--profile NAME]
    fenestra check-data DIR --format coco|yolo|labelmap|curtainwall [--option KEY=JSON ...]

bench/ never imports reports/: fenestra/app/cli.py passes the report writer (reports.cli.write_report)
to :func:`register`, and ``fenestra bench`` calls it on the finished run folder.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import math
from collections.abc import Callable
from pathlib import Path

import typer

from fenestra.bench.real.adapters import ADAPTERS
from fenestra.config import choices
from rich.console import Console
from rich.table import Table
from fenestra.errors import DatasetError


def _fmt(x, d: int = 2) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.{d}f}"


def print_headline(results: dict) -> None:
    """The headline table of a summary's results, with rich."""

    from fenestra.bench.results import headline_table  # noqa: PLC0415 (fenestra.bench.results loads pandas, shapely: imported when first used)

    t = Table(title="per method (evaluable windows)")
    rows = headline_table(results)
    for col in ("method", "evaluable", "detected", "mask med px", "head med px", "snap med px", "snap p90 px",
                "reproj med px", "R@2px snap", "aspect p90", "rot med deg"):
        t.add_column(col, justify="left" if col == "method" else "right")
    for r in rows:
        t.add_row(r["method"], str(r["n_evaluable"]), _fmt(r["detected"]), _fmt(r["mask_med_px"]), _fmt(r["head_med_px"]),
                  _fmt(r["snap_med_px"]), _fmt(r["snap_p90_px"]), _fmt(r["reproj_med_px"]),
                  _fmt(r["recall_2px_snap"]), _fmt(r["aspect_p90_rel"], 3), _fmt(r["rot_med_deg"]))
    Console(width=max(150, Console().width)).print(t)


WriteReport = Callable[..., object]  # (run_dir, real_dir=None) -> writes the run's report


def bench_command(write_report: WriteReport) -> Callable[..., None]:
    """The ``fenestra bench`` command, writing its report with ``write_report(run_dir, real_dir=...)``."""

    def bench(profile: str = typer.Option("smoke", "--profile", "-p", help="profile name (fenestra/bench/profiles) or TOML path"),
              out: Path = typer.Option(None, "--out", "-o", help="run folder (default out/bench/<profile>-<hash>)"),
              workers: int = typer.Option(0, "--workers", "-j", help="worker processes (0: all cores)"),
              no_report: bool = typer.Option(False, "--no-report", help="skip the HTML/Markdown report"),
              executor: str = typer.Option("local", "--executor", "-x",
                                           help="where views are rendered and evaluated: local (process pool) or ray"),
              ray_address: str = typer.Option(None, "--ray-address",
                                              help="ray: a running cluster (auto, or HOST:PORT); default a local one"),
              shard_views: int = typer.Option(20, "--shard-views", help="ray: views per shard"),
              data: Path = typer.Option(None, "--data", help="real profiles: your labelled photo folder instead of the profile's datasets"),
              fmt: str = typer.Option("coco", "--format", help=f"with --data: {choices(ADAPTERS)}"),
              sim: Path = typer.Option(None, "--sim", help="real profiles: a synthetic run folder for the sim-to-real table"),
              real: Path = typer.Option(None, "--real", help="synthetic profiles: a real-photo run folder (fenestra bench "
                                                             "--profile real) for the report's photo column"),
              force: bool = typer.Option(False, "--force", help="replace a --out folder holding another run or other files"),
              csv: bool = typer.Option(False, "--csv", help="also write results.csv (results.parquet is the results table)"),
              seed: int = typer.Option(None, "--seed", help="synthetic profiles: replace the profile's seed (cameras, "
                                                            "looks, sensor noise; another run folder)")) -> None:
        """Render (cached), reconstruct with every strategy, measure, summarise, report."""
        from fenestra.bench.executors import get_executor  # noqa: PLC0415 (fenestra.bench.executors loads SciPy, pandas, shapely: imported when first used)
        from fenestra.bench.profiles import load_profile  # noqa: PLC0415 (a command's own: loaded when the command runs)
        from fenestra.bench.results import load_summary  # noqa: PLC0415 (fenestra.bench.results loads pandas, shapely: imported when first used)
        from fenestra.bench.runner import report_apart, run_benchmark  # noqa: PLC0415 (fenestra.bench.runner loads SciPy, pandas, shapely: imported when first used)

        if workers < 0:
            raise ValueError(f"--workers must be >= 0, got {workers}")
        if shard_views < 1:
            raise ValueError(f"--shard-views must be >= 1, got {shard_views}")
        get_executor(executor)  # an unknown name fails before anything is rendered
        opts = {"address": ray_address, "shard_views": shard_views} if executor == "ray" else {}
        inputs = tuple(p for p in (data, real, Path(profile) if Path(profile).is_file() else None)
                       if p is not None and p.exists())  # what the run reads: never in --out
        p = load_profile(profile)  # either kind: its source is renders or labelled datasets
        if p.photos:
            from fenestra.bench.real.profile import with_user_data  # noqa: PLC0415 (fenestra.bench.real.profile loads SciPy, pandas, shapely: imported when first used)

            if seed is not None:
                raise ValueError(f"--seed needs a synthetic profile (a real run has no cameras to draw), got profile {profile!r}")
            if real is not None:
                raise ValueError(f"--real needs a synthetic profile (a real run's report takes its --sim run), "
                                 f"got profile {profile!r}")
            if data is not None:
                p = with_user_data(p, data, fmt)
            info = run_benchmark(p, out_dir=out, report=None if no_report else write_report, force=force, sim_dir=sim, csv=csv,
                                 inputs=inputs)
        elif data is not None or sim is not None:
            raise ValueError(f"--data/--sim need a real profile (kind = \"real\"), got profile {profile!r}")
        else:
            if real is not None and not (real / "summary.json").is_file():
                raise FileNotFoundError(f"--real {real}: not a benchmark run folder (no summary.json)")
            if real is not None and load_summary(real)["metadata"].get("kind") != "real":
                raise ValueError(f"--real {real}: not a real-photo run (fenestra bench --profile real makes one)")
            # the report in its own process: its memory and the evaluation's never add up
            report = None if no_report else functools.partial(report_apart, functools.partial(write_report, real_dir=real))
            if seed is not None:
                if seed < 0:
                    raise ValueError(f"--seed must be >= 0, got {seed}")
                p = dataclasses.replace(p, seed=seed)
            info = run_benchmark(p, out_dir=out, workers=workers or None,
                                 report=report, executor=executor, executor_options=opts, force=force, csv=csv, inputs=inputs)
        summary = load_summary(info.run_dir)
        typer.echo(f"wall time {info.wall_time_s:.1f} s for {info.n_views} views, {info.n_rows} rows")
        typer.echo("stages (s): " + ", ".join(f"{k} {v:.1f}" for k, v in info.stage_time_s.items()))
        if info.skipped_detectors:
            typer.echo("skipped detectors: " + "; ".join(f"{k}: {v}" for k, v in info.skipped_detectors.items()))
        print_headline(summary["results"])
        if summary.get("kfree"):
            from fenestra.bench.kfree_summary import format_kfree  # noqa: PLC0415 (fenestra.bench.kfree_summary loads pandas, shapely: imported when first used)

            typer.echo("\n".join(format_kfree(summary["kfree"])))
        typer.echo(f"results: {info.run_dir / 'results.parquet'}")
        if not no_report:
            typer.echo(f"report: {info.run_dir / 'report.html'} (and report.md)")

    return bench


def gate(run_dirs: list[Path] = typer.Argument(..., help="run folders (results.parquet, summary.json) of one profile: "
                                                           "several (e.g. seeds) are gated at their pessimistic end"),
         gates: Path = typer.Option(None, "--gates", help="gates TOML (default fenestra/bench/gates.toml)"),
         profile: str = typer.Option(None, "--profile", help="check against this profile's gates"),
         suggest: bool = typer.Option(False, "--suggest", help="print gates.toml text from these runs' numbers instead"),
         margin: float = typer.Option(0.5, "--margin", help="with --suggest: relative margin on ceilings")) -> None:
    """Check runs against accuracy gates; exit 1 naming each violated metric, value and bound. With
    several runs (one profile, e.g. seeds 0, 1, 2: ``fenestra bench --seed``) every run must pass:
    the worst run decides, and --suggest bounds from the worst."""
    from fenestra.bench.gates import DEFAULT_GATES, check, load_gates, run_profile, suggest_gates  # noqa: PLC0415 (fenestra.bench.gates loads pandas, shapely: imported when first used)
    from fenestra.bench.manifest import load_verified_results, require_complete  # noqa: PLC0415 (fenestra.bench.manifest loads pandas, shapely: imported when first used)
    from fenestra.bench.results import summarize  # noqa: PLC0415 (fenestra.bench.results loads pandas, shapely: imported when first used)

    def one_profile() -> str | None:
        """The runs' profile (refusing runs of several), or --profile."""
        if profile is not None or len(run_dirs) == 1:
            return profile
        names = {run_profile(d) for d in run_dirs}
        if len(names) > 1:
            raise ValueError(f"runs of different profiles {sorted(map(str, names))}: gate them one profile at a time")
        return names.pop()

    if suggest:
        if not (math.isfinite(margin) and margin >= 0):
            raise ValueError(f"--margin must be a finite number >= 0, got {margin}")
        for d in run_dirs:
            require_complete(d)
        name = one_profile() or run_profile(run_dirs[0])
        typer.echo(suggest_gates([summarize(load_verified_results(d)) for d in run_dirs], name, margin), nl=False)
        return

    bounds = load_gates(gates or DEFAULT_GATES)  # a bad gates file is named before any run is read
    name = one_profile()
    violations = [(d, v) for d in run_dirs for v in check(d, bounds, profile=name)]
    if violations:
        for d, v in violations:
            typer.echo(f"GATE FAILED {v}" + (f" (run {d})" if len(run_dirs) > 1 else ""), err=True)
        typer.echo(f"{len(violations)} gate violation(s)", err=True)
        raise typer.Exit(1)
    typer.echo("all gates passed" + (f" on each of {len(run_dirs)} runs" if len(run_dirs) > 1 else ""))


def _options(items: list[str]) -> dict:
    """``--option KEY=JSON`` values as adapter keyword options (a value that is not JSON: a string)."""

    out = {}
    for it in items:
        key, sep, val = it.partition("=")
        if not sep or not key.isidentifier():
            raise ValueError(f"--option {it!r}: expected KEY=VALUE, e.g. classes=[0,4]")
        try:
            out[key] = json.loads(val)
        except json.JSONDecodeError:
            out[key] = val
    return out


def check_data(folder: Path = typer.Argument(..., help="a labelled photo folder"),
               fmt: str = typer.Option("coco", "--format", help=f"{choices(ADAPTERS)}"),
               option: list[str] = typer.Option([], "--option",
                                                help="adapter option KEY=JSON, e.g. classes=[0,4] (repeatable)")) -> None:
    """Read a dataset as `fenestra bench --data` would: print each photo's windows, what was
    refused and why; exit 2 with the first problem when the dataset cannot be used."""
    from fenestra.bench.real.adapters.check import check_dataset  # noqa: PLC0415 (fenestra.bench.real.adapters.check loads SciPy: imported when first used)

    c = check_dataset(folder, fmt, **_options(option))
    typer.echo(f"{c.format} dataset {c.folder}: {len(c.views)} photo(s), {c.n_windows} window(s), "
               f"{len(c.refused)} refused, {len(c.problems)} problem(s)")
    for line in c.views:
        typer.echo(f"  found: {line}")
    for line in c.refused:
        typer.echo(f"  refused: {line}")
    for line in c.problems:
        typer.echo(f"  problem: {line}")
    if c.problems:
        more = f" (and {len(c.problems) - 1} more, listed above)" if len(c.problems) > 1 else ""
        raise DatasetError(c.problems[0] + more)


def register(app: typer.Typer, write_report: WriteReport) -> None:
    """Add this stage's commands to the top-level app; ``fenestra bench`` reports with write_report."""
    app.command("bench")(bench_command(write_report))
    app.command("gate")(gate)
    app.command("check-data")(check_data)
