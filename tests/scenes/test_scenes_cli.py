"""`fenestra scenes ...` through the real command line (subprocess), good and bad input."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fenestra.errors import SceneError
from fenestra.scenes.generate import HouseSpec, make_house
from fenestra.scenes.loader import load_scene
from fenestra.scenes.registry import BUNDLED, resolve

ROOT = Path(__file__).resolve().parents[2]


def fenestra(*args: str, cache: Path | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYOPENGL_PLATFORM="egl")
    if cache is not None:
        env["FENESTRA_CACHE"] = str(cache)
    return subprocess.run([sys.executable, "-m", "fenestra", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


def test_show_fzk_haus_json():
    r = fenestra("scenes", "show", "fzk-haus", "--json")
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert len(data["windows"]) == 11 and data["skipped"] == []
    sizes = sorted((round(w["width"], 6), round(w["height"], 6)) for w in data["windows"])
    assert sizes == [(1.0, 1.0)] * 2 + [(2.0, 1.2)] * 9
    w = data["windows"][0]
    assert len(w["corners_world"]) == 4 and len(w["normal"]) == 3 and w["host_id"]


def test_show_duplex_reports_skylights():
    r = fenestra("scenes", "show", "duplex", "--json")
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert len(data["windows"]) == 22
    assert len(data["skipped"]) == 2 and all("IfcRoof" in s["reason"] for s in data["skipped"])


def test_show_table_for_humans():
    r = fenestra("scenes", "show", "duplex")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert "22 windows" in r.stdout and sum(line.startswith("skipped ") for line in lines) == 2
    assert "24 windows present, 22 extracted (fill 22), 2 skipped (not in a wall: 2)" in lines


def test_make_then_show(tmp_path):
    out = tmp_path / "h.ifc"
    r = fenestra("scenes", "make", str(out), "--seed", "4", "--rotation-deg", "30",
                 "--footprint", "0,0;8,0;8,6;0,6", "--json")
    assert r.returncode == 0, r.stderr
    made = json.loads(r.stdout)
    r = fenestra("scenes", "show", str(out), "--json", cache=tmp_path / "c")
    assert r.returncode == 0, r.stderr
    shown = {w["id"]: w for w in json.loads(r.stdout)["windows"]}
    assert len(shown) == len(made["windows"]) == 4
    for w in made["windows"]:
        got, want = np.array(shown[w["id"]]["corners_world"]), np.array(w["corners_world"])
        assert np.abs(got - want).max() <= 1e-6


def test_make_with_facade_features_and_a_bad_value(tmp_path):
    out = tmp_path / "f.ifc"
    r = fenestra("scenes", "make", str(out), "--seed", "3", "--footprint", "0,0;10,0;10,7;0,7",
                 "--windows-per-wall", "2", "--roof-overhang", "0.5", "--fascia-height", "0.3",
                 "--glazed-doors", "1", "--curtain-walls", "1", "--json")
    assert r.returncode == 0, r.stderr
    made = json.loads(r.stdout)
    assert len(made["doors"]) == 1 and len(made["curtain_walls"]) == 1
    cw_wall = made["curtain_walls"][0]["wall"]
    assert all(w["wall"] != cw_wall for w in made["windows"])
    r = fenestra("scenes", "make", str(tmp_path / "s.ifc"), "--seed", "3",
                 "--footprint", "0,0;10,0;10,7;0,7", "--windows-per-wall", "2", "--curtain-walls", "1", "--curtain-wall-width", "1.5",
                 "--curtain-wall-rows", "3", "--json")
    assert r.returncode == 0, r.stderr
    strip = json.loads(r.stdout)
    assert strip["curtain_walls"][0]["width"] == 1.5 and len(strip["windows"]) > len(made["windows"])
    r = fenestra("scenes", "make", str(tmp_path / "g.ifc"), "--curtain-walls", "9")
    assert r.returncode != 0
    msg = r.stderr.strip()
    assert msg.startswith("error:") and len(msg.splitlines()) == 1 and "curtain_walls" in msg, msg


def _bad(tmp_path, name: str, text: bytes) -> Path:
    p = tmp_path / name
    p.write_bytes(text)
    return p


def _assert_cli_error(tmp_path, path: Path, *words: str, extra: tuple[str, ...] = ()) -> None:
    r = fenestra("scenes", "show", str(path), *extra, cache=tmp_path / "c")
    assert r.returncode != 0
    msg = r.stderr.strip()
    assert msg.startswith("error:") and len(msg.splitlines()) == 1, msg
    for word in words:
        assert word in msg, msg


def test_missing_file(tmp_path):
    _assert_cli_error(tmp_path, tmp_path / "nope.ifc", "nope.ifc", "no such file")


def test_unknown_name():
    r = fenestra("scenes", "show", "no-such-house")
    assert r.returncode != 0 and "unknown scene 'no-such-house'" in r.stderr


def test_truncated_ifc(tmp_path):
    data = BUNDLED["fzk-haus"].read_bytes()
    p = _bad(tmp_path, "trunc.ifc", data[: len(data) // 3])
    _assert_cli_error(tmp_path, p, "trunc.ifc", "truncated")


def test_corrupt_ifc(tmp_path):
    p = _bad(tmp_path, "junk.ifc", b"this is not an IFC file\n")
    _assert_cli_error(tmp_path, p, "junk.ifc", "not an IFC")


def test_garbled_body(tmp_path):
    text = b"ISO-10303-21;\nHEADER;\nGARBAGE\nEND-ISO-10303-21;\n"
    _assert_cli_error(tmp_path, _bad(tmp_path, "garbled.ifc", text), "garbled.ifc", "unreadable")


def test_ifc_without_windows(tmp_path):
    house = make_house(HouseSpec(windows_per_wall=0), tmp_path / "blind.ifc")
    assert house.windows == ()
    _assert_cli_error(tmp_path, Path(house.path), "blind.ifc", "no IfcWindow")


def test_window_without_fill_is_found_and_strict_fails_on_a_skip(tmp_path):
    """No IfcRelFillsElement: the window is found by the opening that holds it (source "opening"),
    with the same rectangle; `--strict` fails (one line naming file and window) only on a skip."""
    import ifcopenshell
    import ifcopenshell.guid
    house = make_house(HouseSpec(seed=1), tmp_path / "h.ifc")
    f = ifcopenshell.open(house.path)
    victim = f.by_type("IfcWindow")[0]
    f.remove(victim.FillsVoids[0])
    f.write(str(tmp_path / "loose.ifc"))
    s = load_scene(tmp_path / "loose.ifc", cache_dir=tmp_path / "c2")
    by_id = {w.id: w for w in s.windows}
    assert s.skipped == () and len(s.windows) == 5 and by_id[victim.GlobalId].source == "opening"
    truth = {w.element_id: w.corners_world for w in house.windows}
    assert np.abs(by_id[victim.GlobalId].corners_world - truth[victim.GlobalId]).max() < 1e-3
    r = fenestra("scenes", "show", str(tmp_path / "loose.ifc"), "--json", cache=tmp_path / "c3")
    census = json.loads(r.stdout)["census"]
    assert r.returncode == 0 and census == {"present": 5, "extracted": 5, "skipped": {},
                                            "sources": {"fill": 4, "opening": 1}}
    # a window hosted in the roof slab instead: skipped with its reason; --strict refuses the file
    roof = next(e for e in f.by_type("IfcSlab") if e.Name == "Roof")
    op = next(o for o in f.by_type("IfcOpeningElement") if not o.HasFillings)
    op.VoidsElements[0].RelatingBuildingElement = roof
    f.add(victim.FillsVoids[0] if victim.FillsVoids else f.createIfcRelFillsElement(
        ifcopenshell.guid.new(), None, None, None, op, victim))
    f.write(str(tmp_path / "roofed.ifc"))
    s = load_scene(tmp_path / "roofed.ifc", cache_dir=tmp_path / "c2")
    assert [k.id for k in s.skipped] == [victim.GlobalId] and s.skipped[0].cause == "not in a wall"
    _assert_cli_error(tmp_path, tmp_path / "roofed.ifc", "roofed.ifc", victim.GlobalId, "not a wall",
                      extra=("--strict",))


def test_resolve_errors_are_scene_errors(tmp_path):
    with pytest.raises(SceneError, match="unknown scene 'fzk'"):
        resolve("fzk")
    with pytest.raises(SceneError, match="not a file"):
        resolve(tmp_path)
    assert resolve("samplehouse4") == BUNDLED["samplehouse4"]
