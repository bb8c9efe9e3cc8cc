"""Detector v8 (`quadnet`) beside the CLI's method on the families neither trained on, from the kept seed runs.

    .venv/bin/python tools/v8_side_by_side.py [--doc fenestra/pipeline/models/README.md --block v8-side-by-side]

Reads the JSON that tools/seed_spread.py wrote for each (``--json``): the bench's held-out
families (docs/results/seed_spread.json: the CLI's method; docs/results/seed_spread_quadnet.json:
``quadnet/none/wall+lines/network``; seed_spread_quadnet_refine.json, the same snapped by ``refine``,
where it was measured) and the held-out wild families (wild_heldout_default.json,
wild_heldout_quadnet.json), and writes one table of the pooled "held-out families" row of each:
median over the seeds [min-max]. No figure is typed: every cell comes from those files.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

RESULTS = ROOT / "docs" / "results"
RUNS = (("bench held-out families", ("seed_spread.json", "seed_spread_quadnet.json", "seed_spread_quadnet_refine.json")),
        ("wild held-out families", ("wild_heldout_default.json", "wild_heldout_quadnet.json")))
COLUMNS = (("detection_rate", "found", 100, " %", 0), ("quad_rate", "quads", 100, " %", 0),
           ("all_corners_close", "all 4 corners within 5 px", 100, " %", 0),
           ("snap_median", "corner median", 1, " px", 2), ("rot_median", "rotation median", 1, "°", 2),
           ("aspect_p90", "aspect p90", 100, " %", 1), ("thin_quad_rate", "quads, thin windows", 100, " %", 0),
           ("oblique_quad_rate", "quads at 60-80°", 100, " %", 0))


def cell(fig: dict, scale: float, unit: str, dec: int) -> str:
    if "median" not in fig:
        return "-"
    f = lambda x: f"{scale * x:.{dec}f}"  # noqa: E731
    return f"**{f(fig['median'])}**{unit} [{f(fig['min'])}–{f(fig['max'])}]"


def rows(title: str, path: Path) -> str:
    doc = json.loads(path.read_text())
    figs = doc["houses"]["held-out families"]["figures"]
    seeds = ", ".join(str(s) for s in doc["seeds"])
    return (f"| {title} | `{doc['method']}` | {seeds} | "
            + " | ".join(cell(figs.get(k, {}), s, u, d) for k, _, s, u, d in COLUMNS) + " |")


def table_head() -> list[str]:
    """The Markdown header and rule of a table of :func:`rows`."""
    head = ["families", "method", "seeds"] + [t for _, t, *_ in COLUMNS]
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]


def doc_arguments(doc: str | None, block: str) -> argparse.Namespace:
    """--results (the JSON folder), --doc (repeatable), --block, parsed from the command line."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", type=Path, default=RESULTS)
    ap.add_argument("--doc", type=Path, action="append", default=[])
    ap.add_argument("--block", default=block)
    return ap.parse_args()


def main() -> None:
    a = doc_arguments(__doc__, "v8-side-by-side")
    lines = [f"<!-- `python tools/v8_side_by_side.py {' '.join(sys.argv[1:])}` -->",
             "Pooled held-out families, median over the seeds [min–max] (tools/seed_spread.py's JSON files in "
             "docs/results/; quads and corners within 5 px are shares of the evaluable windows):", "", *table_head()]
    for title, names in RUNS:
        for name in names:
            if (a.results / name).is_file():
                lines.append(rows(title, a.results / name))
    text = "\n".join(lines) + "\n"
    print(text)
    from lab.docs.blocks import write_block  # noqa: PLC0415

    for doc in a.doc:
        write_block(doc, a.block, text)


if __name__ == "__main__":
    main()
