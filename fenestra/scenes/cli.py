"""CLI commands of scenes/ (registered on the `fenestra` app by fenestra/app/cli.py).

    fenestra scenes list                       bundled houses: schema, windows, skipped
    fenestra scenes show NAME_OR_PATH [--json] [--strict]  census (windows present, extracted, skipped
                                               by cause), every window's ground truth, skipped ones + reasons
    fenestra scenes make OUT.ifc [--seed S] [--footprint "x,y;x,y;..."] [--storeys N] ...
    fenestra scenes author OUT_DIR             the hand-authored held-out houses (scenes/authored.py)
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import typer

from fenestra import outputs
from fenestra.scenes.generate import HouseSpec, make_house
from fenestra.scenes.loader import load_scene
from fenestra.scenes.registry import BUNDLED
from rich.console import Console
from rich.table import Table
from fenestra.scenes.authored import AUTHORED

scenes_app = typer.Typer(no_args_is_help=True, help="IFC houses and their window ground truth.")


def scene_summary(scene) -> dict:
    """Machine-readable summary of a Scene (what `scenes show --json` prints)."""
    return {
        "name": scene.name, "path": scene.path, "schema": scene.schema, "sha256": scene.sha256,
        "n_meshes": len(scene.meshes), "census": scene.census(),
        "windows": [{
            "id": w.id, "name": w.name, "host_id": w.host_id, "host_class": w.host_class,
            "opening_id": w.opening_id, "width": w.width, "height": w.height,
            "aspect_ratio": w.aspect_ratio, "shape": w.shape, "notes": w.notes, "source": w.source,
            "ifc_overall_width": w.ifc_overall_width, "ifc_overall_height": w.ifc_overall_height,
            "normal": [float(x) for x in w.normal],
            "corners_world": [[float(x) for x in c] for c in w.corners_world],
        } for w in scene.windows],
        "skipped": [{"id": s.id, "name": s.name, "reason": s.reason, "cause": s.cause}
                    for s in scene.skipped],
    }


def census_line(census: dict) -> str:
    """One line: 'N windows present, E extracted (by source), S skipped (by cause)'."""
    src = ", ".join(f"{k} {v}" for k, v in sorted(census["sources"].items()))
    skipped = sum(census["skipped"].values())
    why = ", ".join(f"{k}: {v}" for k, v in sorted(census["skipped"].items()))
    return (f"{census['present']} windows present, {census['extracted']} extracted"
            + (f" ({src})" if src else "") + f", {skipped} skipped" + (f" ({why})" if why else ""))


@scenes_app.command("list")
def list_cmd(json_out: bool = typer.Option(False, "--json", help="print JSON")) -> None:
    """Bundled houses with schema, window and skipped-window counts (loads each, cached)."""

    rows = []
    for name, path in BUNDLED.items():
        s = load_scene(name)
        rows.append({"name": name, "file": path.name, "schema": s.schema,
                     "windows": len(s.windows), "skipped": len(s.skipped),
                     "meshes": len(s.meshes)})
    if json_out:
        typer.echo(json.dumps(rows, indent=1))
        return

    t = Table(title="Bundled houses (fenestra/scenes/ifc, see SOURCES.md)")
    for col in ("name", "file", "schema", "windows", "skipped", "meshes"):
        t.add_column(col, justify="right" if col in ("windows", "skipped", "meshes") else "left")
    for r in rows:
        t.add_row(*(str(r[c]) for c in ("name", "file", "schema", "windows", "skipped", "meshes")))
    Console().print(t)


@scenes_app.command("show")
def show_cmd(scene: str = typer.Argument(..., help="bundled name or path to an .ifc"),
             json_out: bool = typer.Option(False, "--json", help="print JSON"),
             strict: bool = typer.Option(False, "--strict", help="fail on the first window that cannot be "
                                         "measured instead of skipping it")) -> None:
    """The census (windows present, extracted by source, skipped by cause), every window's void
    rectangle (id, host, width, height, normal, corners) and each skipped window's reason."""

    summary = scene_summary(load_scene(scene, strict=strict))
    if json_out:
        typer.echo(json.dumps(summary, indent=1))
        return

    t = Table(title=f"{summary['name']} ({summary['schema']}): {len(summary['windows'])} windows")
    for col in ("id", "host", "w (m)", "h (m)", "shape", "source", "normal", "TL corner (m)"):
        t.add_column(col)
    for w in summary["windows"]:
        t.add_row(w["id"], f"{w['host_class']} {w['host_id']}", f"{w['width']:.4f}",
                  f"{w['height']:.4f}", w["shape"], w["source"], " ".join(f"{x:+.3f}" for x in w["normal"]),
                  " ".join(f"{x:.3f}" for x in w["corners_world"][0]))
    console = Console()
    console.print(t)
    console.print(census_line(summary["census"]), markup=False)
    for s in summary["skipped"]:
        console.print(f"skipped {s['id']} ({s['name']}): {s['reason']}", markup=False, soft_wrap=True)


def parse_footprint(text: str) -> list[tuple[float, float]]:
    """'x,y;x,y;...' (m) -> list of points; ValueError naming the text when malformed."""
    try:
        pts = [tuple(float(v) for v in p.split(",")) for p in text.strip().split(";") if p.strip()]
    except ValueError:
        raise ValueError(f"footprint '{text}': expected 'x,y;x,y;...' in metres") from None
    if any(len(p) != 2 for p in pts):
        raise ValueError(f"footprint '{text}': every point needs exactly x,y")
    return pts  # type: ignore[return-value]


_H = HouseSpec()  # the option defaults are the spec's


@scenes_app.command("make")
def make_cmd(out: Path = typer.Argument(..., help="output .ifc path"),
             seed: int = typer.Option(_H.seed, help="random seed for window sizes and positions"),
             footprint: str = typer.Option(None, help="polygon 'x,y;x,y;...' m, counter-clockwise (default: the spec's)"),
             storeys: int = typer.Option(_H.storeys, help="number of storeys"),
             rotation_deg: float = typer.Option(_H.rotation_deg, help="rotate the whole footprint (deg)"),
             storey_height: float = typer.Option(_H.storey_height, help="m"),
             wall_thickness: float = typer.Option(_H.wall_thickness, help="m"),
             windows_per_wall: int = typer.Option(_H.windows_per_wall, help="windows per wall and storey"),
             roof_overhang: float = typer.Option(_H.roof_overhang, help="roof beyond the walls (m)"),
             fascia_height: float = typer.Option(_H.fascia_height, help="dark band at the roof edge (m)"),
             glazed_doors: int = typer.Option(_H.glazed_doors, help="ground-floor walls with a glazed door (not a window)"),
             curtain_walls: int = typer.Option(_H.curtain_walls, help="walls glazed as curtain walls (no windows)"),
             curtain_wall_width: float = typer.Option(
                 _H.curtain_wall_width, help="0: a curtain wall fills its wall; else a strip this wide (m), other windows kept"),
             curtain_wall_rows: int = typer.Option(_H.curtain_wall_rows, help="panel rows of a curtain wall (1-4)"),
             sill_depth: float = typer.Option(_H.sill_depth, help="0: none; else a sill under each window protruding this far (m)"),
             surround_width: float = typer.Option(_H.surround_width, help="0: none; else an architrave this wide around each window (m)"),
             shutters: bool = typer.Option(_H.shutters, "--shutters/--no-shutters", help="shutter panels beside each window"),
             json_out: bool = typer.Option(False, "--json", help="print the expected GT as JSON"),
             ) -> None:
    """Write a procedural IFC4 house with known window voids; print its expected ground truth."""

    kw = {} if footprint is None else {"footprint": tuple(parse_footprint(footprint))}
    spec = HouseSpec(seed=seed, storeys=storeys, rotation_deg=rotation_deg,
                     storey_height=storey_height, wall_thickness=wall_thickness,
                     windows_per_wall=windows_per_wall, roof_overhang=roof_overhang,
                     fascia_height=fascia_height, glazed_doors=glazed_doors,
                     curtain_walls=curtain_walls, curtain_wall_width=curtain_wall_width,
                     curtain_wall_rows=curtain_wall_rows, sill_depth=sill_depth,
                     surround_width=surround_width, shutters=shutters, **kw)
    house = write_scene(out, lambda p: make_house(spec, p))
    if json_out:
        typer.echo(json.dumps(house.to_json(), indent=1))
    else:
        typer.echo(f"wrote {out}: {len(house.windows)} windows, {len(house.doors)} glazed doors, "
                   f"{len(house.curtain_walls)} curtain-wall bays, {len(spec.footprint)} walls "
                   f"x {spec.storeys} storeys")


@scenes_app.command("author")
def author_cmd(out_dir: Path = typer.Argument(..., help="folder for the .ifc files (created)")) -> None:
    """Write the hand-authored held-out houses (authored-terrace, authored-studio) into OUT_DIR;
    `fenestra scenes author fenestra/scenes/ifc` regenerates the bundled copies."""

    for file, _ in AUTHORED.values():  # every file checked before any is written
        outputs.check_file(out_dir / file)
    for name, (file, writer) in AUTHORED.items():
        windows = write_scene(out_dir / file, writer)
        typer.echo(f"wrote {out_dir / file}: {name}, {len(windows)} windows")


def write_scene(path: Path, write):
    """``write(tmp)``'s result, the IFC file it wrote at a temporary name moved to ``path`` under
    fenestra.outputs' rule (never over a file Fenestra did not write; listed in the folder's
    manifest), with ``path`` in place of the temporary name where the result records it."""

    made = []
    outputs.write_file(path, lambda tmp: made.append(write(tmp)))
    result = made[0]
    return dataclasses.replace(result, path=str(path)) if dataclasses.is_dataclass(result) else result


def register(app: typer.Typer) -> None:
    """Add this stage's commands to the top-level app."""
    app.add_typer(scenes_app, name="scenes")
