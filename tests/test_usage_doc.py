"""docs/usage.md says what `fenestra reconstruct` is: its option table lists exactly the options the
command line (Typer) exposes, each with a value placeholder exactly when it takes a value, its
default where it has one and, for the registry choices, the registry's names; the files a
reconstruct folder holds are named in its "Your own photo" section.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer.main

ROOT = Path(__file__).resolve().parents[1]
USAGE = ROOT / "docs" / "usage.md"
HEADING = "### Options of `fenestra reconstruct`"
OPTION = re.compile(r"`(--[A-Za-z][\w+-]*)( [^`]+)?`")  # `--name` or `--name VALUE`


def option_table(text: str) -> list[list[str]]:
    """The rows (cells: option, default, what it does) of the table under HEADING."""
    assert HEADING in text, f"docs/usage.md has no {HEADING!r} section"
    section = text.split(HEADING, 1)[1].split("\n#", 1)[0]
    lines = [ln for ln in section.splitlines() if ln.startswith("|")]
    assert lines[0].split("|")[1:-1] and lines[1].startswith("|---"), "the section's table has no header"
    rows = [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in lines[2:]]
    assert all(len(r) == 3 for r in rows), [r for r in rows if len(r) != 3]
    return rows


@pytest.fixture(scope="module")
def command():
    from fenestra.app.cli import app  # noqa: PLC0415

    return typer.main.get_command(app).commands["reconstruct"]


@pytest.fixture(scope="module")
def rows() -> list[list[str]]:
    return option_table(USAGE.read_text())


def documented(rows: list[list[str]]) -> dict[str, tuple[str | None, list[str]]]:
    """{option name: (its value placeholder or None, its row)} of the table's first column."""
    out = {}
    for row in rows:
        for name, value in OPTION.findall(row[0]):
            assert name not in out, f"{name} is listed twice"
            out[name] = (value.strip() or None, row)
    return out


def test_the_table_lists_exactly_the_commands_options(command, rows):
    opts = {o: p for p in command.params if p.param_type_name == "option" for o in p.opts + p.secondary_opts}
    doc = documented(rows)
    missing, extra = sorted(set(opts) - set(doc)), sorted(set(doc) - set(opts))
    assert not missing and not extra, f"docs/usage.md's reconstruct table: missing {missing}, not options {extra}"
    for name, p in opts.items():
        value, _ = doc[name]
        if p.is_flag:
            assert value is None, f"{name} is a flag: no value after it in the table"
        else:
            assert value, f"{name} takes a value: the table shows a placeholder after it (`{name} VALUE`)"
    arguments = [p for p in command.params if p.param_type_name == "argument"]
    first = [r[0] for r in rows]
    for a in arguments:
        shown = f"`{a.name.upper()}{'...' if a.nargs == -1 else ''}`"
        assert shown in first, f"the argument {shown} is not in the table"
    for p in {id(p): p for p in opts.values()}.values():  # a parameter's aliases share its row
        assert len({id(doc[o][1]) for o in p.opts + p.secondary_opts}) == 1, f"{p.opts}: on one row"


def test_the_defaults_are_the_commands(command, rows):
    doc = documented(rows)
    for p in command.params:
        if p.param_type_name == "argument" or p.opts[0] not in doc:
            continue
        cell = doc[p.opts[0]][1][1]
        if p.required:
            assert cell == "(required)", (p.opts[0], cell)
        elif p.is_flag:
            assert cell == ("on" if p.default else "off"), (p.opts[0], cell)
        elif p.default is not None:
            assert f"`{p.default}`" in cell, f"{p.opts[0]}: default {p.default!r}, the table says {cell!r}"
        else:
            assert f"`{p.default}`" not in cell


def test_the_choices_are_the_registries(rows):
    from fenestra.pipeline.catalogue import CATALOGUE  # noqa: PLC0415
    from fenestra.pipeline.detectors import DETECTORS  # noqa: PLC0415
    from fenestra.pipeline.quad import QUAD_SOURCES  # noqa: PLC0415
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415
    from fenestra.pipeline.snappers import SNAPPERS  # noqa: PLC0415

    doc = documented(rows)

    def named(option: str) -> set[str]:
        return {w for w in re.findall(r"`([^`\s]+)`", doc[option][1][2]) if not w.startswith("-")}

    assert named("--snapper") == set(SNAPPERS)
    assert named("--pose") == set(POSES)
    assert named("--quad-source") == set(QUAD_SOURCES)
    assert named("--substitute") - {"substituted.png"} == set(CATALOGUE)
    assert named("--detector") <= set(DETECTORS) and "default" in named("--detector")


def test_the_output_files_are_named(tmp_path):
    """Every file a reconstruct folder holds (with --substitute: all of them) is named, in
    backquotes, in the "Your own photo" section."""
    import fenestra  # noqa: PLC0415

    ex = ROOT / "examples" / "curtainwall"
    options = fenestra.PhotoOptions(snapper="none", known=fenestra.Known(window_width_m=0.0932),
                                    substitute="casement-white")
    fenestra.reconstruct_photo(ex / "img017.jpg", tmp_path / "o", K_json=ex / "K.json", masks=ex / "panes017.png",
                               options=options)
    files = sorted(p.name for p in (tmp_path / "o").iterdir() if not p.name.startswith("."))
    assert "index.html" in files
    section = USAGE.read_text().split("## Your own photo", 1)[1].split("\n## ", 1)[0]
    named = set(re.findall(r"`([^`]+)`", re.sub(r"```.*?```", "", section, flags=re.S)))  # code blocks out
    named |= {"model" + n for n in named if n.startswith(".")}  # `model.obj`/`.mtl`
    assert [f for f in files if f not in named] == []
