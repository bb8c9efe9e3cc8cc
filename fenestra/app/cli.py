"""The `fenestra` command line (``fenestra ...`` or ``python -m fenestra ...``): each stage registers its
own subcommands. This is the composition root, on the top floor: it imports every stage, and
nothing imports it.

    fenestra scenes list | show | make      (fenestra/scenes/cli.py)
    fenestra render                         (fenestra/renders/cli.py)
    fenestra reconstruct | calibrate        (fenestra/pipeline/cli.py)
    fenestra train | evaluate-detector | ship-weights | train-verifier    (fenestra/training/cli.py)
    fenestra bench | gate                   (fenestra/bench/cli.py; bench ends with reports' writer)
    fenestra report | compare              (fenestra/reports/cli.py)
"""
from __future__ import annotations

import ctypes
import datetime
import os
import signal
import sys
import tempfile
import traceback
from pathlib import Path

import typer

import fenestra
from fenestra.errors import FenestraError, one_line
from fenestra.renders import cli as renders_cli
from fenestra.reports import cli as reports_cli
from fenestra.scenes import cli as scenes_cli
from fenestra.training import cli as training_cli

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Fenestra: single-photo facade window reconstruction, measured against exact IFC ground truth.")


def _version(value: bool) -> None:
    if value:
        typer.echo(f"fenestra {fenestra.__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", is_eager=True, callback=_version,
                                       help="print the version and exit")) -> None:
    """Fenestra: single-photo facade window reconstruction, measured against exact IFC ground truth."""


def _register() -> None:
    from fenestra.bench import cli as bench_cli  # noqa: PLC0415 (fenestra.bench.cli loads SciPy: imported when first used)
    from fenestra.pipeline import cli as pipeline_cli  # noqa: PLC0415 (fenestra.pipeline.cli loads IfcOpenShell, SciPy: imported when first used)

    for module in (scenes_cli, renders_cli, pipeline_cli, training_cli):
        module.register(app)
    # the composition root: bench/ produces tables and never imports reports/, so the report step
    # of `fenestra bench` is handed in here
    bench_cli.register(app, write_report=reports_cli.write_report)
    reports_cli.register(app)


_register()


USER_ERRORS = (FenestraError, OSError, ValueError)  # bad input, every OS error: exit 2
INTERNAL_EXIT = 3  # an unexpected exception: a bug of Fenestra's


def main() -> None:
    """Entry point: run the app. Every error ends with one line on stderr, never a traceback:
    user-facing errors (bad input, and every OS error: disk full, read-only or missing paths,
    names too long) exit 2; an unexpected exception exits 3 with "please report" and the path of
    a log file holding its traceback (:func:`crash_log`); Ctrl-C exits 130."""
    signal.signal(signal.SIGTERM, _terminate)  # unwinds: temporary outputs are removed
    for stream in (sys.stdout, sys.stderr):  # a file name that is not UTF-8 is printed escaped, never raw bytes
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    try:
        app(prog_name="fenestra")
    except USER_ERRORS as e:
        typer.echo(f"error: {one_line(e)}", err=True)
        sys.exit(2)
    except KeyboardInterrupt:
        _interrupted()
    except SystemExit as e:
        if e.code == INTERRUPTED:  # typer turns Ctrl-C into a silent exit 130: say so
            _interrupted()
        raise
    except Exception as e:  # noqa: BLE001  (the one place that turns a bug into one line)
        if was_interrupted(e):
            _interrupted()
        try:
            where = f"with the traceback in {crash_log(e, sys.argv)}"
        except OSError:
            where = "(its traceback could not be written to a log file)"
        typer.echo(f"error: internal error ({type(e).__name__}: {one_line(e)}); please report it {where}", err=True)
        sys.exit(INTERNAL_EXIT)


INTERRUPTED = 130  # 128 + SIGINT


def was_interrupted(e: BaseException) -> bool:
    """Whether ``e`` is Ctrl-C in disguise: a KeyboardInterrupt in its chain (__cause__ /
    __context__), or ctypes' ArgumentError for an interrupt that landed while a foreign call
    (pyrender's EGL, OpenGL) converted its arguments, which ctypes reports unchained as
    "argument N: KeyboardInterrupt: "."""

    seen = set()
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, KeyboardInterrupt) or (isinstance(e, ctypes.ArgumentError)
                                                and ": KeyboardInterrupt:" in str(e)):
            return True
        e = e.__cause__ or e.__context__
    return False


def _interrupted() -> None:
    typer.echo("error: interrupted; partial outputs removed", err=True)
    sys.exit(INTERRUPTED)


def crash_log(e: BaseException, argv: list[str], folder: str | Path | None = None) -> Path:
    """Write the command line and the traceback of ``e`` to a new file under ``folder`` (default:
    the system's temporary folder) and return its path."""
    folder = Path(tempfile.gettempdir() if folder is None else folder)
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    path = folder / f"fenestra-error-{stamp}-{os.getpid()}.log"
    text = f"command: {' '.join(map(repr, argv))}\n\n" + "".join(traceback.format_exception(e))
    path.write_text(text, encoding="utf-8", errors="backslashreplace")
    return path


def _terminate(signum: int, _frame) -> None:
    typer.echo(f"error: terminated (signal {signum}); partial outputs removed", err=True)
    raise SystemExit(128 + signum)
