"""Import direction: each floor of the one package ``fenestra`` imports only the floors before it
(the folders follow the data).

    fenestra (ground floor)  <-  scenes  <-  renders  <-  training
        ^                                      ^            |
        +------------ pipeline ----------------+------------+   (pipeline: what a user runs on a photo)
    bench: scenes, renders, pipeline (it feeds the pipeline renders and real photos, measures it)
    reports: pipeline (registry names), bench (the results/manifest contract: it reads the bench's
             tables); bench never imports reports (the CLI hands bench the report writer)
    app: the top floor, the composition root (fenestra/app/cli.py: the `fenestra` command line
         registers every stage's commands): it may import every floor, and no floor imports it
    lab: the repository's lab (lab/, not installed: data scripts, weight shipping, the results
         docs): every floor but app; the package never imports it
    tools: measuring scripts (tools/*.py, not installed): every floor but app, and lab; nothing imports them

The ground floor is the modules directly in fenestra/ (conventions, tolerances, checks, the data
contracts): they import nothing above it, with no exception but the package's ``__init__``, the
public API facade (``from fenestra import reconstruct_photo``, resolved on first use), which may
import ``fenestra.pipeline``. Nothing imports ``training`` except app and tools/. Every import
counts, also one inside a function (a lazy import is still a dependency).
"""
from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "fenestra"
ALLOWED: dict[str, set[str]] = {
    "fenestra": set(),
    "scenes": {"fenestra"},
    "renders": {"fenestra", "scenes"},
    "pipeline": {"fenestra"},
    "training": {"fenestra", "scenes", "renders", "pipeline"},
    "bench": {"fenestra", "scenes", "renders", "pipeline"},
    "reports": {"fenestra", "scenes", "renders", "pipeline", "bench"},
    "app": {"fenestra", "scenes", "renders", "pipeline", "training", "bench", "reports"},
    "lab": {"fenestra", "scenes", "renders", "pipeline", "training", "bench", "reports"},
    "tools": {"fenestra", "scenes", "renders", "pipeline", "training", "bench", "reports", "lab"},
}
OUTSIDE = {"tools", "lab"}  # top-level folders of the checkout, not installed
FLOORS = set(ALLOWED) - {"fenestra"} - OUTSIDE  # the subpackages of fenestra
# the package's two doors: the public API (imported lazily) and `python -m fenestra` (the command line)
FACADE = {"fenestra/__init__.py": {"pipeline"}, "fenestra/__main__.py": {"app"}}


def floor_of(module: str) -> str | None:
    """The floor an absolute module name belongs to: "pipeline" for fenestra.pipeline.photo,
    "fenestra" for a ground-floor module (fenestra.conventions) or the package itself; None
    outside fenestra."""
    parts = module.split(".")
    if parts[0] != "fenestra":
        return parts[0] if parts[0] in OUTSIDE else None
    return parts[1] if len(parts) > 1 and parts[1] in FLOORS else "fenestra"


def installed_packages() -> list[str]:
    """Top-level packages pyproject.toml installs (``include = ["fenestra*"]``)."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return [p.rstrip("*") for p in cfg["tool"]["setuptools"]["packages"]["find"]["include"]]


def imports(path: Path) -> set[str]:
    """Floors of every absolute import in a file (function-level ones included)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + ([f"{node.module}.{a.name}" for a in node.names] if node.module == "fenestra" else [])
        else:
            continue
        out |= {f for f in map(floor_of, names) if f is not None}
    return out


def floor_files(floor: str) -> list[Path]:
    """The Python files of one floor."""
    if floor == "fenestra":
        return sorted(PACKAGE.glob("*.py"))
    if floor in OUTSIDE:
        return sorted((ROOT / floor).rglob("*.py"))
    return sorted((PACKAGE / floor).rglob("*.py"))


def violations(floor: str) -> list[tuple[str, str, str]]:
    """(file, importer floor, imported floor) of every import the table does not allow."""
    bad = []
    for f in floor_files(floor):
        rel = f.relative_to(ROOT).as_posix()
        allowed = ALLOWED[floor] | FACADE.get(rel, set())
        for name in sorted(imports(f) - {floor} - allowed):
            bad.append((rel, floor, name))
    return bad


def test_one_installed_package():
    """The wheel installs one top-level package, ``fenestra`` (tests/test_wheel.py checks the wheel)."""
    assert installed_packages() == ["fenestra"]


def test_app_is_the_top_floor():
    """app may import every floor, nothing may import app (tools/ included), and every folder of
    Python files in the package has a row."""
    assert ALLOWED["app"] == set(ALLOWED) - {"app"} - OUTSIDE
    assert not [p for p, deps in ALLOWED.items() if "app" in deps]
    assert [f for f, deps in FACADE.items() if "app" in deps] == ["fenestra/__main__.py"]
    folders = {d.name for d in PACKAGE.iterdir() if d.is_dir() and any(d.glob("*.py"))}
    assert folders <= FLOORS, sorted(folders - FLOORS)
    top = {d.name for d in ROOT.iterdir() if d.is_dir() and not d.name.startswith(".") and any(d.glob("*.py"))}
    assert top <= {"fenestra", "lab", "tools", "tests", "examples"}, sorted(top)


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


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_imports_follow_the_data(package):
    bad = violations(package)
    assert not bad, "\n".join(f"{f}: {a} must not import {b}" for f, a, b in bad)


def test_checker_sees_a_violation(tmp_path, monkeypatch):
    """The checker itself: a lazy import of bench inside a pipeline module is reported, and so is a
    ground-floor module importing the pipeline through the package (``from fenestra import pipeline``)."""
    pkg = tmp_path / "fenestra" / "pipeline"
    pkg.mkdir(parents=True)
    (pkg / "x.py").write_text("def f():\n    from fenestra.bench.runner import run_benchmark\n    import fenestra.scenes\n")
    (tmp_path / "fenestra" / "y.py").write_text("from fenestra import pipeline, conventions\n")
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    monkeypatch.setattr(__import__(__name__), "PACKAGE", tmp_path / "fenestra")
    assert violations("pipeline") == [("fenestra/pipeline/x.py", "pipeline", "bench"),
                                      ("fenestra/pipeline/x.py", "pipeline", "scenes")]
    assert violations("fenestra") == [("fenestra/y.py", "fenestra", "pipeline")]
