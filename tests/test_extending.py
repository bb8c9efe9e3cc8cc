"""docs/EXTENDING.md stays true: what it names exists, and its code excerpts are the real code.

Checked mechanically: every registry it names (a dotted ``module.REGISTRY`` in backticks) imports
and is a non-empty registry; every file or folder path it names exists; every test it names is
defined in tests/; every fenced code block that starts with ``# <path>`` is a verbatim excerpt of
that file (its lines appear in that order, each block of consecutive lines contiguous; a ``...``
line skips ahead). And the worked example is registered and offered where the page says it is.
"""
from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "EXTENDING.md"
TEXT = DOC.read_text()
TICKED = re.findall(r"`([^`\n]+)`", TEXT)


def registries() -> list[str]:
    """Dotted names like ``pipeline.snappers.SNAPPERS`` in backticks."""
    return sorted({t for t in TICKED if re.fullmatch(r"[a-z_]+(\.[a-z_]+)+\.[A-Z][A-Z_]+", t)})


def paths() -> list[str]:
    """Repository paths in backticks (with a folder and, for files, a known suffix); placeholders
    such as ``renders/<name>.py`` are not paths."""
    return sorted({t for t in TICKED if re.fullmatch(r"[\w.-]+(/[\w.-]+)+/?", t)
                   and (t.endswith("/") or Path(t).suffix in (".py", ".md", ".toml"))})


def excerpts() -> list[tuple[str, list[str]]]:
    """(path, lines) of every fenced code block whose first line is ``# <path>``."""
    out = []
    for block in re.findall(r"```python\n(.*?)```", TEXT, re.S):
        first, *rest = block.rstrip("\n").split("\n")
        m = re.fullmatch(r"# ([\w./-]+)", first)
        if m:
            out.append((m.group(1), rest))
    return out


def test_the_page_names_things_to_check():
    assert len(registries()) >= 6 and len(paths()) >= 20 and len(excerpts()) >= 4


@pytest.mark.parametrize("dotted", registries())
def test_named_registry_exists(dotted):
    module, name = dotted.rsplit(".", 1)
    from fenestra.registry import Registry

    reg = getattr(importlib.import_module(module), name)
    assert isinstance(reg, (Registry, dict)) and reg, dotted


@pytest.mark.parametrize("path", paths())
def test_named_path_exists(path):
    assert (ROOT / path).exists(), path


def test_named_tests_exist():
    import dataclasses

    from fenestra.pipeline.snappers.base import Snapper

    fields = {f.name for f in dataclasses.fields(Snapper)}  # e.g. test_median_px: a field, not a test
    defined = {m for f in (ROOT / "tests").rglob("test_*.py") for m in re.findall(r"^def (test_\w+)", f.read_text(), re.M)}
    named = {t for t in TICKED if re.fullmatch(r"test_\w+", t)} - fields
    assert named and named <= defined, sorted(named - defined)


@pytest.mark.parametrize("path, lines", excerpts(), ids=[f"{p}:{i}" for i, (p, _) in enumerate(excerpts())])
def test_excerpt_is_verbatim(path, lines):
    source = (ROOT / path).read_text().split("\n")
    at = 0
    for chunk in "\n".join(lines).split("\n...\n"):
        want = chunk.split("\n")
        for start in range(at, len(source) - len(want) + 1):
            if source[start:start + len(want)] == want:
                at = start + len(want)
                break
        else:
            pytest.fail(f"{path}: excerpt not found verbatim (after line {at}):\n" + chunk)


def test_worked_example_is_offered_where_the_page_says():
    from typer.testing import CliRunner

    from fenestra.bench.profiles import load_profile
    from fenestra.bench.runner import plan_methods
    from fenestra.app.cli import app
    from fenestra.pipeline.snappers import SNAPPERS

    assert SNAPPERS["lsd"].name == "lsd"
    out = CliRunner().invoke(app, ["reconstruct", "--help"], env={"COLUMNS": "400"}).output
    help_text = " ".join(re.sub("[\u2500-\u257f]", " ", out).split())  # without rich's box drawing
    assert f"lsd: {SNAPPERS['lsd'].description}" in help_text
    methods, _ = plan_methods(load_profile("smoke"))
    assert any(m.snapper == "lsd" for m in methods)
