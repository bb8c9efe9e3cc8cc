"""The `fenestra` command line (``fenestra ...`` or ``python -m app ...``): each stage registers its
own subcommands. This is the composition root, on the top floor: it imports every stage, and
nothing imports it.

    fenestra scenes list | show | make      (scenes/cli.py)
    fenestra render                         (renders/cli.py)
    fenestra reconstruct | calibrate        (pipeline/cli.py)
    fenestra train | evaluate-detector | ship-weights    (training/cli.py)
    fenestra bench | gate                   (bench/cli.py; bench ends with reports' writer)
    fenestra report                         (reports/cli.py)
"""
from __future__ import annotations

import signal
import sys

import typer

from fenestra.errors import FenestraError, one_line

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Fenestra: single-photo facade window reconstruction, measured against exact IFC ground truth.")


def _register() -> None:
    import bench.cli
    import pipeline.cli
    import renders.cli
    import reports.cli
    import scenes.cli
    import training.cli

    for module in (scenes.cli, renders.cli, pipeline.cli, training.cli):
        module.register(app)
    # the composition root: bench/ produces tables and never imports reports/, so the report step
    # of `fenestra bench` is handed in here
    bench.cli.register(app, write_report=reports.cli.write_report)
    reports.cli.register(app)


_register()


def main() -> None:
    """Entry point: run the app; user-facing errors (bad input, and every OS error: disk full,
    read-only or missing paths, names too long) become one line on stderr and exit code 2."""
    signal.signal(signal.SIGTERM, _terminate)  # unwinds: temporary outputs are removed
    try:
        app(prog_name="fenestra")
    except (FenestraError, OSError, ValueError) as e:
        typer.echo(f"error: {one_line(e)}", err=True)
        sys.exit(2)


def _terminate(signum: int, _frame) -> None:
    typer.echo(f"error: terminated (signal {signum}); partial outputs removed", err=True)
    raise SystemExit(128 + signum)
