"""``python -m fenestra`` and the console script ``fenestra``: the `fenestra` command line
(fenestra.app.cli). :func:`run` imports it first: Ctrl-C while its stages load (the first second)
ends as Ctrl-C during a command does, with one line and exit 130, never a traceback."""
import os
import sys

INTERRUPTED = 130  # 128 + SIGINT, as fenestra.app.cli's


def run() -> None:
    """Import the command line and run it (fenestra.app.cli.main)."""
    try:
        from fenestra.app.cli import main  # noqa: PLC0415  (every stage's commands: ~1 s of imports)
    except KeyboardInterrupt:
        print("error: interrupted; nothing was written", file=sys.stderr, flush=True)
        os._exit(INTERRUPTED)  # nothing to clean up yet; a plain exit may re-raise SIGINT (exit -2)
    main()


if __name__ == "__main__":  # guarded: spawned worker processes import this module too
    run()
