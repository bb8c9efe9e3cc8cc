"""load_scene: meshes, colours, and the on-disk cache (fresh load vs cached load)."""
from __future__ import annotations

import time
from pathlib import Path

import ifcopenshell
import numpy as np

from fenestra.scenes import list_scenes, load_scene
from fenestra.scenes.registry import BUNDLED


def test_fresh_and_cached_load_agree_and_cache_is_fast(tmp_path):
    t0 = time.perf_counter()
    fresh = load_scene("fzk-haus", cache_dir=tmp_path)
    t_fresh = time.perf_counter() - t0
    assert len(list(tmp_path.glob("*.npz"))) == 1 and len(list(tmp_path.glob("*.json"))) == 1
    t0 = time.perf_counter()
    cached = load_scene("fzk-haus", cache_dir=tmp_path)
    t_cached = time.perf_counter() - t0
    assert t_cached < 1.0 < t_fresh, (t_fresh, t_cached)
    assert cached.sha256 == fresh.sha256 and cached.schema == "IFC4"
    assert [m.global_id for m in cached.meshes] == [m.global_id for m in fresh.meshes]
    for a, b in zip(fresh.meshes, cached.meshes):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
        assert a.rgba == b.rgba and (a.face_rgba is None) == (b.face_rgba is None)
    for a, b in zip(fresh.windows, cached.windows):
        assert a.id == b.id and np.array_equal(a.corners_world, b.corners_world)
        assert a.width == b.width and a.shape == b.shape and a.notes == b.notes


def test_meshes_one_per_element_with_ifc_identity_and_colours():
    scene = load_scene("fzk-haus")
    f = ifcopenshell.open(str(BUNDLED["fzk-haus"]))
    ids = {m.global_id for m in scene.meshes}
    assert len(ids) == len(scene.meshes)
    assert ids >= {w.GlobalId for w in f.by_type("IfcWindow")}
    assert ids >= {w.GlobalId for w in f.by_type("IfcWall")}
    assert not {m.ifc_class for m in scene.meshes} & {"IfcOpeningElement", "IfcSpace",
                                                       "IfcAnnotation"}
    for m in scene.meshes:
        assert f.by_guid(m.global_id).is_a() == m.ifc_class
        assert m.vertices.ndim == 2 and m.vertices.shape[1] == 3 and m.faces.max() < len(m.vertices)
        assert all(0.0 <= c <= 1.0 for c in m.rgba)
    # walls are the ArchiCAD style's light grey (0.81); windows mix frame and 88 %-transparent glass
    wall = next(m for m in scene.meshes if m.ifc_class == "IfcWallStandardCase")
    assert np.allclose(wall.rgba, (0.81, 0.81, 0.81, 1.0))
    win = next(m for m in scene.meshes if m.ifc_class == "IfcWindow")
    assert win.face_rgba.shape == (len(win.faces), 4)
    assert np.isclose(win.face_rgba[:, 3].min(), 0.12)


def test_holes_are_cut_in_host_walls():
    """A wall with an opening has more triangles than the 12 of an uncut box."""
    scene = load_scene("jasmin-sun")
    meshes = {m.global_id: m for m in scene.meshes}
    for w in scene.windows:
        assert len(meshes[w.host_id].faces) > 12


def test_list_scenes():
    assert list_scenes() == ["fzk-haus", "duplex", "samplehouse4", "jasmin-sun", "niedriha", "office-a",
                             "authored-terrace", "authored-studio"]


def test_cache_key_is_derived_from_the_loader_code(tmp_path):
    """No version number to bump by hand: the key digests the sources the cached Scene is computed by
    (any byte of them changes it), and those are every scenes module the cached code imports
    (registry.py only maps names to paths: not part of the cached content)."""
    import ast
    from importlib.metadata import version

    from fenestra.files import source_digest
    from fenestra.scenes import loader

    f = tmp_path / "a.py"
    f.write_text("x = 1\n")
    before = source_digest([f])
    f.write_text("x = 2\n")
    assert source_digest([f]) != before
    here = Path(loader.__file__).parent
    assert loader.cache_version() == source_digest([here / s for s in loader.CACHE_SOURCES],
                                                   f"ifcopenshell {version('ifcopenshell')}")
    used = set()
    for s in loader.CACHE_SOURCES:
        for node in ast.walk(ast.parse((here / s).read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("scenes."):
                used.add(node.module.split(".")[1] + ".py")
    assert used - {"registry.py"} <= set(loader.CACHE_SOURCES), used
