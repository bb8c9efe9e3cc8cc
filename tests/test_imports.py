"""Import direction: each top-level package imports only the stages before it (the folders follow the data).

    fenestra  <-  scenes  <-  renders  <-  training
        ^                        ^            |
        +------ pipeline --------+------------+   (pipeline: what a user runs on a photo: fenestra only)
    bench: scenes, renders, pipeline (it feeds the pipeline renders and real photos, measures it)
    reports: pipeline (registry names), bench (the results/manifest contract: it reads the bench's
             tables); bench never imports reports (the CLI hands bench the report writer)
    app: the top floor, the composition root (app/cli.py: the `fenestra` command line registers
         every stage's commands): it may import every package, and no package imports it
    tools: lab scripts (tools/*.py, not installed): every package but app (they run the command
           line as a user does, in a subprocess); nothing imports them

The ground floor ``fenestra`` imports nothing above it, with no exception. Nothing imports
``training`` except app and tools/. Every import counts, also one inside a function (a lazy import
is still a dependency).
"""
from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ALLOWED: dict[str, set[str]] = {
    "fenestra": set(),
    "scenes": {"fenestra"},
    "renders": {"fenestra", "scenes"},
    "pipeline": {"fenestra"},
    "training": {"fenestra", "scenes", "renders", "pipeline"},
    "bench": {"fenestra", "scenes", "renders", "pipeline"},
    "reports": {"fenestra", "scenes", "renders", "pipeline", "bench"},
    "app": {"fenestra", "scenes", "renders", "pipeline", "training", "bench", "reports"},
    "tools": {"fenestra", "scenes", "renders", "pipeline", "training", "bench", "reports"},
}


def installed_packages() -> list[str]:
    """Top-level packages pyproject.toml installs (``include = ["fenestra*", ...]``)."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return [p.rstrip("*") for p in cfg["tool"]["setuptools"]["packages"]["find"]["include"]]


def imports(path: Path) -> set[str]:
    """Top-level names of every absolute import in a file (function-level ones included)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module.split(".")[0])
    return out


def violations(package: str) -> list[tuple[str, str, str]]:
    """(file, importer package, imported package) of every import the table does not allow."""
    known = set(ALLOWED)
    bad = []
    for f in sorted((ROOT / package).rglob("*.py")):
        rel = f.relative_to(ROOT).as_posix()
        for name in sorted(imports(f) & known - {package} - ALLOWED[package]):
            bad.append((rel, package, name))
    return bad


def test_every_installed_package_has_a_row():
    assert set(installed_packages()) <= set(ALLOWED), sorted(set(installed_packages()) - set(ALLOWED))
    assert all(deps <= set(ALLOWED) for deps in ALLOWED.values())


def test_app_is_the_top_floor():
    """app may import every installed package, nothing may import app (tools/ included), and
    every top-level folder of Python files has a row."""
    assert ALLOWED["app"] == set(installed_packages()) - {"app"}
    assert not [p for p, deps in ALLOWED.items() if "app" in deps]
    folders = {d.name for d in ROOT.iterdir() if d.is_dir() and not d.name.startswith(".")
               and any(d.glob("*.py")) and d.name != "tests"}
    assert folders <= set(ALLOWED), sorted(folders - set(ALLOWED))


def test_table_has_no_cycle():
    seen: dict[str, int] = {}

    def visit(p: str) -> None:
        assert seen.get(p) != 1, f"cycle through {p}"
        if seen.get(p) == 2:
            return
        seen[p] = 1
        for q in ALLOWED[p]:
            visit(q)
        seen[p] = 2

    for p in ALLOWED:
        visit(p)


@pytest.mark.parametrize("package", [p for p in ALLOWED if (ROOT / p).is_dir()])
def test_imports_follow_the_data(package):
    bad = violations(package)
    assert not bad, "\n".join(f"{f}: {a} must not import {b}" for f, a, b in bad)


def test_checker_sees_a_violation(tmp_path, monkeypatch):
    """The checker itself: a lazy import of bench inside a pipeline module is reported."""
    pkg = tmp_path / "pipeline"
    pkg.mkdir()
    (pkg / "x.py").write_text("def f():\n    from bench.runner import run_benchmark\n    import scenes\n")
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    assert violations("pipeline") == [("pipeline/x.py", "pipeline", "bench"), ("pipeline/x.py", "pipeline", "scenes")]
