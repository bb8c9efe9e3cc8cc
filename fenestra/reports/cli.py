"""CLI command of reports/ (registered on the `fenestra` app by fenestra/app/cli.py).

    fenestra report RUN_DIR [--real REAL_RUN_DIR]
    fenestra report RUN_DIR --markdown docs/results.md [--real REAL_RUN_DIR]   (the results docs, reports.markdown)

:func:`write_report` is also what fenestra/app/cli.py hands to bench.cli, so ``fenestra bench`` ends
with the same report without bench/ importing reports/.
"""
from __future__ import annotations

from pathlib import Path

import typer


def write_report(run_dir: Path, real_dir: Path | None = None) -> tuple[Path, Path]:
    """reports.build.build_report, imported when called (matplotlib stays out of CLI start-up)."""
    from fenestra.reports.build import build_report  # noqa: PLC0415

    return build_report(run_dir, real_dir=real_dir)


def report(run_dir: Path = typer.Argument(..., help="a run folder with results.parquet"),
           real: Path = typer.Option(None, "--real", help="a real-photo run folder (fenestra bench --profile real) "
                                                          "for the photo column of a synthetic run's report"),
           markdown: Path = typer.Option(None, "--markdown",
                                         help="instead of report.html: write the results docs (e.g. docs/results.md, "
                                              "its summary results/summary.json beside it, and the generated blocks "
                                              "of README.md one folder up and DESIGN.md beside it)")) -> None:
    """Regenerate report.html and report.md (+ figures/) of a run from its results, or (--markdown) the
    results docs."""
    if markdown is not None:
        from fenestra.reports.markdown import write_docs  # noqa: PLC0415

        for p in write_docs(run_dir, markdown, real_dir=real):
            typer.echo(f"wrote {p}")
        return
    html, md = write_report(run_dir, real_dir=real)
    typer.echo(f"report: {html}\nmarkdown: {md}")


def register(app: typer.Typer) -> None:
    """Add this stage's commands to the top-level app."""
    app.command("report")(report)
