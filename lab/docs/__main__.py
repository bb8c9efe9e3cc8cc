"""``python -m lab.docs [RUN] [--real REAL_RUN] [--markdown docs/results.md] [--check]``."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fenestra import outputs
from lab.docs import DocPaths, render_docs, stale, write_docs


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Collect a bench run into docs/results/summary.json (given RUN), then render "
                                             "docs/results.md and the README/DESIGN blocks from that summary.")
    ap.add_argument("run", type=Path, nargs="?", help="a bench run of the default profile: collect it first")
    ap.add_argument("--real", type=Path, default=None, help="the real-photo run (out/bench/real)")
    ap.add_argument("--markdown", type=Path, default=Path("docs/results.md"))
    ap.add_argument("--check", action="store_true", help="write nothing; exit 1 if a doc differs from its rendering")
    ap.add_argument("--force", action="store_true", help="replace a results page or summary that no Fenestra manifest lists")
    a = ap.parse_args(argv)
    paths = DocPaths.for_markdown(a.markdown)
    if a.check:
        bad = stale(paths)
        for p in bad:
            print(f"stale: {p} (python -m lab.docs renders it)", file=sys.stderr)
        return 1 if bad else 0
    if a.real is not None and a.run is None:
        ap.error("--real needs the default run (RUN) beside it")
    try:
        written = write_docs(a.run, a.markdown, a.real, a.force) if a.run is not None else render_docs(paths, a.force)
    except (outputs.OwnershipError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for p in written:
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
