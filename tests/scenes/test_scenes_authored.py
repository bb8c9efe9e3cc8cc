"""The hand-authored held-out houses (fenestra/scenes/authored.py, issue 36).

The committed files are the module's output; the loader's window ground truth is the authored
opening on the exterior wall face, computed here from the authoring constants (wall lines, offsets,
sills, sizes) with no help from the loader or the module's own ground-truth helpers; the files are
valid IFC4; no training script renders them.
"""
from __future__ import annotations

import re

from pathlib import Path

import ifcopenshell
import ifcopenshell.validate
import numpy as np
import pytest
from typer.testing import CliRunner

from fenestra.scenes import authored as A
from fenestra.scenes.cli import scenes_app
from fenestra.scenes.loader import load_scene
from fenestra.scenes.registry import BUNDLED

ROOT = Path(__file__).resolve().parents[2]
PLANS = {"authored-terrace": A.terrace_plan(), "authored-studio": A.studio_plan()}
TOL_M = 1e-6


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory) -> Path:
    """`fenestra scenes author OUT_DIR` into a fresh folder."""
    out = tmp_path_factory.mktemp("authored")
    r = CliRunner().invoke(scenes_app, ["author", str(out)])
    assert r.exit_code == 0, r.output
    assert r.output.count("wrote ") == 2 and "33 windows" in r.output and "27 windows" in r.output
    return out


@pytest.fixture(scope="module", params=list(PLANS))
def house(request):
    """(name, plan, loaded committed scene, loader window by IfcWindow name)."""
    scene = load_scene(request.param)  # the committed file (default on-disk cache)
    return request.param, PLANS[request.param], scene, {w.name: w for w in scene.windows}


def authored_rectangle(plan: A.Plan, win: A.Win) -> tuple[np.ndarray, np.ndarray]:
    """Corners (4, 3) TL TR BR BL and outward normal of a window's void on its wall's exterior
    face, from the plan's numbers alone: the face line a -> b, off, sill, width, height."""
    wall = next(w for w in plan.walls if w.name == win.wall)
    a, b = np.array([*wall.a, 0.0]), np.array([*wall.b, 0.0])
    u = (b - a) / np.linalg.norm(b - a)
    bl = a + win.off * u + [0.0, 0.0, win.sill]
    up, along = np.array([0.0, 0.0, win.height]), win.width * u
    return np.stack([bl + up, bl + along + up, bl + along, bl]), np.array([u[1], -u[0], 0.0])


def step_content(path: Path) -> list[str]:
    """A STEP file's entity lines with every list of references sorted: ifcopenshell writes the
    members of an unordered IFC SET in an order that can change between processes (it keeps them
    in Python sets; fenestra.scenes.generate.make_house says the same), so two writes of one model
    can differ in bytes, never in content."""
    def sort_refs(m: re.Match) -> str:
        return "(" + ",".join(sorted(m.group(1).split(","))) + ")"

    lines = path.read_text().split(";\n")
    return [re.sub(r"\((#\d+(?:,#\d+)+)\)", sort_refs, ln) for ln in lines]


def test_registered_and_regenerated_content(regenerated):
    for name, (file, _) in A.AUTHORED.items():
        assert BUNDLED[name].name == file
        assert step_content(regenerated / file) == step_content(BUNDLED[name]), (
            f"{file} differs from the module's output: run `fenestra scenes author fenestra/scenes/ifc`")
        assert BUNDLED[name].stat().st_size < 400_000  # small enough to commit


def test_loader_windows_are_the_authored_voids(house, regenerated):
    """Every window: the loader's rectangle = the authored void (same GlobalId as regenerated)."""
    name, plan, scene, by_name = house
    assert scene.skipped == () and len(scene.windows) == len(plan.windows)
    ids = {e.name: e.element_id for e in A.write_plan(plan, regenerated / "again.ifc")}
    for win in plan.windows:
        w = by_name[win.name]
        corners, normal = authored_rectangle(plan, win)
        assert np.abs(w.corners_world - corners).max() <= TOL_M, win.name
        assert np.abs(w.normal - normal).max() <= 1e-9, win.name
        assert w.shape == "rectangle" and w.notes == "" and w.id == ids[win.name]
        assert w.ifc_overall_width == pytest.approx(win.width) and w.width == pytest.approx(win.width)


def test_house_shape_and_features(house):
    """Each house: >= 20 windows, >= 2 storeys, storey heights the generator's specs never use
    (it draws one height for every storey), its features (names of authored.FEATURES)."""
    name, plan, scene, _ = house
    feats = {f for w in plan.windows for f in w.features}
    assert len(plan.windows) >= 20 and len(plan.storeys) >= 2 and feats <= set(A.FEATURES)
    heights = np.diff([z for _, z in plan.storeys])
    if name == "authored-terrace":
        assert {"recessed", "deep_sill", "thin_tall", "dormer", "mullioned"} <= feats
        assert heights.tolist() == pytest.approx([3.05, 2.65])
    else:
        assert {"ribbon", "corner", "thin_tall", "mullioned", "recessed"} <= feats
        assert heights.tolist() == pytest.approx([3.45])  # the upper storey is 3.1 m (roof on top)
        e = np.diff(np.vstack([A.S_FOOTPRINT, A.S_FOOTPRINT[:1]]), axis=0)  # edges, counter-clockwise
        turns = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
        assert len(e) == 6 and np.sum(turns < 0) == 1  # L-shaped: one reflex corner


def test_recessed_window_outline_is_the_wall_face_opening():
    """A terrace window with glass 0.22 m back: its ground truth lies on the wall's exterior face
    (the reveal included: the opening's full 1.1 x 1.5 m), while every vertex of the window body
    (frame and glass) lies 0.22-0.29 m behind that face."""
    plan = PLANS["authored-terrace"]
    scene = load_scene("authored-terrace")
    win = next(w for w in plan.windows if w.name == "T1 front F left")
    gt = next(w for w in scene.windows if w.name == win.name)
    body = next(m for m in scene.meshes if m.global_id == gt.id)
    corners, normal = authored_rectangle(plan, win)
    face = 0.0  # the front wall's exterior face: the plane y = 0 (the outward normal is -y)
    assert np.allclose(gt.corners_world[:, 1], face) and np.allclose(gt.normal, [0, -1, 0])
    assert gt.width == pytest.approx(1.1) and gt.height == pytest.approx(1.5)
    behind = face - body.vertices @ normal  # depth behind the face, m
    assert behind.min() == pytest.approx(0.22) and behind.max() == pytest.approx(0.22 + A.FRAME_DEPTH)
    assert np.abs(gt.corners_world - corners).max() <= TOL_M


@pytest.mark.parametrize("name, feature, aspect", [
    ("authored-terrace", "thin_tall", (0.0, 1 / 3)), ("authored-studio", "thin_tall", (0.0, 1 / 3)),
    ("authored-studio", "ribbon", (4.0, np.inf))])
def test_thin_tall_and_ribbon_windows(name, feature, aspect):
    """Thin tall windows (width / height <= 1/3) and ribbons (>= 4) keep their authored size."""
    plan, scene = PLANS[name], load_scene(name)
    by_name = {w.name: w for w in scene.windows}
    wins = [w for w in plan.windows if feature in w.features]
    assert len(wins) >= 3
    for win in wins:
        gt = by_name[win.name]
        assert aspect[0] <= gt.aspect_ratio <= aspect[1], (win.name, gt.aspect_ratio)
        assert gt.width == pytest.approx(win.width) and gt.height == pytest.approx(win.height)


def test_corner_windows_meet_at_the_building_corner():
    """Each corner window is two windows, one per wall: the first's right edge (seen from outside)
    is the second's left edge, on the footprint's corner, and their walls are perpendicular."""
    plan = PLANS["authored-studio"]
    by_name = {w.name: w for w in load_scene("authored-studio").windows}
    ends = [w for w in plan.windows if w.corner == "end"]
    starts = [w for w in plan.windows if w.corner == "start"]
    assert len(ends) == len(starts) == 2
    for end, start in zip(ends, starts):
        e, s = by_name[end.name], by_name[start.name]
        corner = next(w.b for w in plan.walls if w.name == end.wall)
        assert next(w.a for w in plan.walls if w.name == start.wall) == corner
        assert np.abs(e.corners_world[1] - s.corners_world[0]).max() <= TOL_M  # TR = TL
        assert np.abs(e.corners_world[2] - s.corners_world[3]).max() <= TOL_M  # BR = BL
        assert np.allclose(e.corners_world[2][:2], corner, atol=TOL_M)
        assert abs(e.normal @ s.normal) < 1e-9


def test_dormer_windows_stand_in_the_roof():
    """The terrace's dormer windows are hosted by their dormer's front wall, above the eaves."""
    plan = PLANS["authored-terrace"]
    scene = load_scene("authored-terrace")
    host_name = {m.global_id: m.name for m in scene.meshes}
    dormers = [w for w in scene.windows if "dormer" in w.name]
    assert len(dormers) == 3
    for w in dormers:
        assert host_name[w.host_id].startswith("dormer-") and w.corners_world[:, 2].min() > A.T_H0 + A.T_H1
        assert np.allclose(w.normal, [0, -1, 0]) and np.allclose(w.corners_world[:, 1], A.T_DORMER_Y)
    assert len(plan.windows) == 33


def _validate(path: Path, express_rules: bool) -> list:
    logger = ifcopenshell.validate.json_logger()
    ifcopenshell.validate.validate(ifcopenshell.open(str(path)), logger, express_rules=express_rules)
    return logger.statements


@pytest.mark.parametrize("name", list(A.AUTHORED))
def test_schema_valid(name):
    assert _validate(BUNDLED[name], express_rules=False) == []


@pytest.mark.slow
@pytest.mark.parametrize("name", list(A.AUTHORED))
def test_express_rules_valid(name):  # ~8 s a house
    assert _validate(BUNDLED[name], express_rules=True) == []


def test_no_training_script_renders_them():
    """Held out by family: neither house (name or file) appears in any training script or config."""
    files = [p for d in (ROOT / "lab" / "scripts", ROOT / "fenestra" / "training" / "configs") for p in d.glob("*")
             if p.is_file()]
    assert any(p.name == "make_data.sh" for p in files)
    for p in files:
        text = p.read_text()
        for name, (file, _) in A.AUTHORED.items():
            assert name not in text and file not in text and "authored" not in text, p
