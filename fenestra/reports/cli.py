"""CLI command of reports/ (registered on the `fenestra` app by fenestra/app/cli.py).

    fenestra report RUN_DIR [--real REAL_RUN_DIR]
    fenestra compare RUN_A RUN_B [--method LABEL] [--html PATH]   (two runs of one profile, reports.compare)

:func:`write_report` is also what fenestra/app/cli.py hands to bench.cli, so ``fenestra bench`` ends
with the same report without bench/ importing reports/.
"""
from __future__ import annotations

from pathlib import Path

import typer


def write_report(run_dir: Path, real_dir: Path | None = None) -> tuple[Path, Path]:
    """reports.build.build_report, imported when called (matplotlib stays out of CLI start-up)."""
    from fenestra.reports.build import build_report  # noqa: PLC0415 (fenestra.reports.build loads SciPy, matplotlib, pandas, shapely: imported when first used)

    return build_report(run_dir, real_dir=real_dir)


def report(run_dir: Path = typer.Argument(..., help="a run folder with results.parquet"),
           real: Path = typer.Option(None, "--real", help="a real-photo run folder (fenestra bench --profile real) "
                                                          "for the photo column of a synthetic run's report")) -> None:
    """Regenerate report.html and report.md (+ figures/) of a run from its results (the repository's
    results docs are the lab's: ``python -m lab.docs RUN``)."""
    html, md = write_report(run_dir, real_dir=real)
    typer.echo(f"report: {html}\nmarkdown: {md}")


def compare(run_a: Path = typer.Argument(..., help="the baseline run folder"),
            run_b: Path = typer.Argument(..., help="the run after the change (same profile, any commit)"),
            method: str = typer.Option(None, "--method", help="the method whose significant regression exits 1 "
                                                              "(default: the CLI's, fenestra.conventions.DEFAULTS)"),
            html: Path = typer.Option(None, "--html", help="the comparison page (default RUN_B/compare-<RUN_A's name>.html)"),
            top: int = typer.Option(10, "--top", help="how many of the windows that changed most to list")) -> None:
    """Compare run B with baseline run A window by window: per method the change of median and p90
    of corner, aspect and rotation error, the paired Wilcoxon test, the share of windows better and
    worse, the windows that changed most; exit 1 on a significant regression of the gated method
    (median worse by more than fenestra/tolerances.py's compare_* tolerance, p < 0.01)."""
    from fenestra.reports import compare as cmp  # noqa: PLC0415 (fenestra.reports.compare loads SciPy, pandas, shapely: imported when first used)

    if top < 0:
        raise ValueError(f"--top must be >= 0, got {top}")
    page = html if html is not None else Path(run_b) / f"compare-{Path(run_a).resolve().name}.html"
    cmp.check_page(page, run_a, run_b)  # before the comparison: never over a file it did not write, nor a run's
    c = cmp.compare_runs(run_a, run_b, method=method, top=top)
    typer.echo(cmp.text(c))
    page = cmp.write_html(c, page)
    typer.echo(f"page: {page}")
    if c.regressions:
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add this stage's commands to the top-level app."""
    app.command("report")(report)
    app.command("compare")(compare)
