"""The results docs, generated from a bench run: docs/results.md, the README's answer and the
defaults statements, all rendered from one small committed summary.

    python -m lab.docs RUN [--real REAL_RUN] [--markdown docs/results.md]
        1. collect(RUN, REAL_RUN) -> the doc summary: the figures the tables show, rounded, and the
           runs' provenance; written to docs/results/summary.json (a few KB, committed);
        2. render it: docs/results.md, and the marked blocks of README.md and docs/DESIGN.md
           (``<!-- results:begin -->`` ... ``<!-- results:end -->``, ``<!-- defaults:begin -->`` ...).
    python -m lab.docs [--check]
        step 2 alone, from the committed summary (``--check``: exit 1 where a doc differs).

The docs are always rendered from the rounded summary (never from the run directly), so rendering
the committed summary again gives the committed docs byte for byte (tests/lab/test_docs.py).
Which method is "the CLI default" and "the paper's" comes from ``fenestra.conventions`` at render
time; a run that lacks the CLI default's method says so.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from lab.docs.blocks import fill_block
from lab.docs.figures import collect
from lab.docs.text import answer, defaults_text, results_md

SUMMARY_NAME = Path("results") / "summary.json"  # beside the markdown file: docs/results/summary.json


@dataclass(frozen=True)
class DocPaths:
    """Where the generator writes: the markdown file, its summary, and the docs with marked blocks
    (filled when the file exists)."""

    markdown: Path
    summary: Path
    readme: Path
    design: Path

    @staticmethod
    def for_markdown(markdown: Path) -> "DocPaths":
        """docs/results.md -> docs/results/summary.json, README.md one folder up, docs/DESIGN.md beside it."""
        markdown = Path(markdown)
        return DocPaths(markdown, markdown.parent / SUMMARY_NAME, markdown.parent.parent / "README.md",
                        markdown.parent / "DESIGN.md")


def rendered(doc: dict, paths: DocPaths) -> dict[Path, str]:
    """{path: new text} of every doc the summary renders (README/DESIGN only where they exist)."""
    out = {paths.markdown: results_md(doc)}
    if paths.readme.is_file():
        text = fill_block(paths.readme.read_text(), "results", answer(doc))
        out[paths.readme] = fill_block(text, "defaults", defaults_text())
    if paths.design.is_file():
        out[paths.design] = fill_block(paths.design.read_text(), "defaults", defaults_text())
    return out


def write_summary(doc: dict, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")


def write_docs(run_dir: Path, markdown: Path, real_dir: Path | None = None) -> list[Path]:
    """collect the run(s) into markdown's summary file, then render every doc from that file.

    Without a real-photo run, the real-photo figures of the summary already there are kept (marked
    ``kept``: their own provenance says which run they are from), never dropped."""
    paths = DocPaths.for_markdown(markdown)
    doc = collect(run_dir, real_dir)
    if doc["real"] is None and paths.summary.is_file():
        before = json.loads(paths.summary.read_text()).get("real")
        if before is not None:
            doc["real"] = {**before, "kept": True}
    write_summary(doc, paths.summary)
    return [paths.summary, *render_docs(paths)]


def render_docs(paths: DocPaths) -> list[Path]:
    """Render the docs from the committed summary file; the paths written."""
    doc = json.loads(paths.summary.read_text())
    written = []
    for p, text in rendered(doc, paths).items():
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
        written.append(p)
    return written


def stale(paths: DocPaths) -> list[Path]:
    """The docs whose committed text differs from what the committed summary renders."""
    doc = json.loads(paths.summary.read_text())
    return [p for p, text in rendered(doc, paths).items() if not p.is_file() or p.read_text() != text]
