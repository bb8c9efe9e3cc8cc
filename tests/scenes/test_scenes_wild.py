"""The public IFC models of ../shared/ifc/wild (issue 47): every valid file loads, >= 95 % of the
windows that sit in walls are extracted, every size is within 5 mm of the IFC's own, loading is
bounded, and the rendered instance masks agree with the projected ground truth.

Truth is counted here with plain ifcopenshell, not by the loader: a window sits in a wall when the
opening it fills voids an IfcWall / IfcCurtainWall, or (no fill relation) when its body's centre lies
in a wall's bounding box. Sizes: IfcWindow.OverallWidth/Height when set (> 0), else the opening's
IfcRectangleProfileDef or its body's extent, else the hole in the host wall's own body (its nearest
reveal, sill and head faces around the window) or the window body's extent along the wall and up.
The folder is ``$FENESTRA_WILD_IFC`` or ../shared/ifc/wild; without it these tests skip, saying so.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fenestra.errors import SceneError
from fenestra.scenes.loader import load_scene
from fenestra.scenes.registry import WILD_HOUSES, wild_dir

WILD = wild_dir()
pytestmark = pytest.mark.skipif(not WILD.is_dir(), reason=f"the wild IFC models are not bundled (GPL, CC BY-SA or no licence: read from ../shared only) and there is no folder at {WILD} (set FENESTRA_WILD_IFC)")
SMALL = "IfcOpenHouse_IFC4.ifc"  # 5 windows, none with a fill relation, parts aggregated: the fast case
SIZE_TOL_M = 0.005
UNREADABLE = {"Allplan-Smiley-West.ifc": "IFC2X_FINAL"}  # older than IFC2X3: refused in one line


def _settings():
    import ifcopenshell.geom
    s = ifcopenshell.geom.settings()
    s.set("use-world-coords", True)
    return s


def _verts(settings, element) -> np.ndarray | None:
    """World vertices (N, 3) m of an element's body (its aggregated parts' when it has none)."""
    import ifcopenshell.geom
    try:
        v = np.asarray(ifcopenshell.geom.create_shape(settings, element).geometry.verts).reshape(-1, 3)
        if len(v):
            return v
    except RuntimeError:
        pass
    parts = [_verts(settings, p) for r in getattr(element, "IsDecomposedBy", ()) for p in r.RelatedObjects]
    parts = [p for p in parts if p is not None]
    return np.concatenate(parts) if parts else None


def windows_in_walls(f) -> dict[str, object]:
    """GlobalId -> IfcWindow entity of every window of the open file f that sits in a wall (see the
    module docstring)."""
    s = _settings()
    walls = [w for c in ("IfcWall", "IfcCurtainWall") for w in f.by_type(c)]
    boxes = [(v.min(axis=0) - 0.05, v.max(axis=0) + 0.05) for w in walls if (v := _verts(s, w)) is not None]
    out = {}
    for win in f.by_type("IfcWindow"):
        if win.FillsVoids:
            hosts = [r.RelatingBuildingElement for r in win.FillsVoids[0].RelatingOpeningElement.VoidsElements]
            if hosts and (hosts[0].is_a("IfcWall") or hosts[0].is_a("IfcCurtainWall")):
                out[win.GlobalId] = win
            continue
        v = _verts(s, win)
        if v is not None:
            c = (v.min(axis=0) + v.max(axis=0)) / 2.0
            if any(np.all(c >= lo) and np.all(c <= hi) for lo, hi in boxes):
                out[win.GlobalId] = win
    return out


def expected_sizes(f, win, gt, scale: float, settings) -> list[tuple[float, float]]:
    """Candidate (width, height) m of a window from the IFC alone (module docstring); x of the
    extents is along the wall (up x the loader's normal), y is world z."""
    out = []
    if win.OverallWidth and win.OverallHeight:
        out.append((float(win.OverallWidth) * scale, float(win.OverallHeight) * scale))
    x_ax = np.cross([0.0, 0.0, 1.0], gt.normal)
    elements = [win]
    if gt.opening_id:
        op = f.by_guid(gt.opening_id)
        elements.insert(0, op)
        for rep in op.Representation.Representations if op.Representation else ():
            for item in rep.Items:
                prof = getattr(item, "SweptArea", None)
                if prof is not None and prof.is_a("IfcRectangleProfileDef"):
                    a, b = float(prof.XDim) * scale, float(prof.YDim) * scale
                    out += [(a, b), (b, a)]
    for e in elements:
        v = _verts(settings, e)
        if v is not None:
            out.append((float(np.ptp(v @ x_ax)), float(np.ptp(v[:, 2]))))
    hole = reveal_size(f.by_guid(gt.host_id), gt.center, x_ax, settings)
    return out + ([hole] if hole else [])


def reveal_size(wall, centre: np.ndarray, x_ax: np.ndarray, settings) -> tuple[float, float] | None:
    """(width, height) m of the hole in the wall's own body around centre (3,): the nearest reveal
    faces (normal along x_ax) left and right of it at its height, the nearest sill / head faces
    (normal along z) below and above it at its x; None when one is missing."""
    import ifcopenshell.geom
    sh = ifcopenshell.geom.create_shape(settings, wall)
    v = np.asarray(sh.geometry.verts).reshape(-1, 3)
    tri = v[np.asarray(sh.geometry.faces).reshape(-1, 3)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    tx, tz = tri @ x_ax, tri[..., 2]
    cx, cz = float(centre @ x_ax), float(centre[2])
    side = (np.abs(n @ x_ax) > 0.99) & (tz.min(axis=1) < cz) & (tz.max(axis=1) > cz)
    flat = (np.abs(n[:, 2]) > 0.99) & (tx.min(axis=1) < cx) & (tx.max(axis=1) > cx)
    xs, zs = tx[side].mean(axis=1), tz[flat].mean(axis=1)
    left, right, low, high = xs[xs < cx], xs[xs > cx], zs[zs < cz], zs[zs > cz]
    if not (len(left) and len(right) and len(low) and len(high)):
        return None
    return float(right.min() - left.max()), float(high.min() - low.max())


def check_file(path: Path) -> dict:
    """Load one wild file and check it against the plain-ifcopenshell truth; returns its census
    with the count of windows in walls and of those extracted."""
    import ifcopenshell
    import ifcopenshell.util.unit
    scene = load_scene(path)
    f = ifcopenshell.open(str(path))
    truth = windows_in_walls(f)
    got = {w.id: w for w in scene.windows}
    assert scene.n_present == len({*got, *(s.id for s in scene.skipped)})  # none dropped silently
    for s in scene.skipped:
        assert s.reason and "\n" not in s.reason and s.cause, s
    settings = _settings()
    scale = ifcopenshell.util.unit.calculate_unit_scale(f)
    for gid, w in got.items():
        win = truth[gid] if gid in truth else None
        if win is None:
            continue
        cands = expected_sizes(f, win, w, scale, settings)
        assert any(abs(w.width - a) <= SIZE_TOL_M and abs(w.height - b) <= SIZE_TOL_M for a, b in cands), \
            (path.name, gid, w.source, w.width, w.height, cands)
    return {**scene.census(), "in_walls": len(truth), "in_walls_extracted": len(set(truth) & set(got))}


def test_small_wild_file_no_fill_relation():
    """Fast case: IfcOpenShell's IfcOpenHouse writes its windows without IfcRelFillsElement, as
    IfcMember frames and an IfcPlate pane; three of them share one opening (each then its own body)."""
    c = check_file(WILD / SMALL)
    assert c["in_walls"] == 5 and c["in_walls_extracted"] == 5 and c["skipped"] == {}
    assert c["sources"] == {"opening": 1, "window_body": 4}


def test_unreadable_schema_is_refused_in_one_line():
    for name, schema in UNREADABLE.items():
        with pytest.raises(SceneError) as e:
            load_scene(WILD / name, use_cache=False)
        assert "\n" not in str(e.value) and name in str(e.value) and schema in str(e.value)


def test_scenes_show_prints_the_census():
    r = subprocess.run([sys.executable, "-m", "fenestra", "scenes", "show", str(WILD / SMALL), "--json"],
                       capture_output=True, text=True, timeout=300, cwd=Path(__file__).resolve().parents[2])
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["census"] == {"present": 5, "extracted": 5, "skipped": {},
                                              "sources": {"opening": 1, "window_body": 4}}


@pytest.mark.slow
def test_every_valid_wild_file_loads_and_95_percent_of_wall_windows_are_extracted():
    files = sorted(p for p in WILD.glob("*.ifc") if p.name not in UNREADABLE)
    assert {p.name for p in files} | set(UNREADABLE) == set(WILD_HOUSES.values())
    census = {p.name: check_file(p) for p in files}
    walls = sum(c["in_walls"] for c in census.values())
    found = sum(c["in_walls_extracted"] for c in census.values())
    assert found >= 0.95 * walls, census


def _inside(poly: np.ndarray, h: int, w: int) -> np.ndarray:
    """(h, w) bool: pixel centres (u, v) inside the convex polygon (4, 2) px (either winding)."""
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    sides = []
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        sides.append((b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0]))
    s = np.stack(sides)
    return np.all(s >= 0, axis=0) | np.all(s <= 0, axis=0)


def mask_ious(root: Path) -> list[tuple[str, float, float, float]]:
    """(window id, IoU of instances.png's mask with its projected corners' polygon, visible
    fraction, incidence deg) for every window of every view whose corners all lie in the image."""
    from fenestra.images import read_instances
    out = []
    for view in sorted((root / "views").iterdir()):
        meta = json.loads((view / "view.json").read_text())
        inst = read_instances(view / "instances.png")
        h, w = inst.shape
        for win in meta["windows"]:
            c = np.asarray(win["corners_px"], dtype=float)
            if c.min() < -0.5 or c[:, 0].max() > w - 0.5 or c[:, 1].max() > h - 0.5:
                continue
            poly, mask = _inside(c, h, w), inst == win["instance_id"]
            if poly.sum() < 30:
                continue
            out.append((win["id"], float((poly & mask).sum() / (poly | mask).sum()), float(win["visible_fraction"]),
                        float(win["incidence_deg"])))
    return out


def _render(name: str, tmp_path: Path, n_views: int) -> list[tuple[str, float, float, float]]:
    from fenestra.renders.dataset import DatasetConfig, render_dataset
    from fenestra.renders.sampler import SamplerConfig
    cfg = DatasetConfig(scene=name, n_views=n_views, seed=0, out_root=str(tmp_path),
                        sampler=SamplerConfig(width=320, height=240, street_fraction=0.5))
    return mask_ious(Path(render_dataset(cfg, progress=False)))


def _check_masks(ious: list[tuple[str, float, float, float]], name: str) -> None:
    seen = [(gid, iou) for gid, iou, vis, _ in ious if vis >= 0.9]
    assert seen, f"{name}: no unoccluded window in any view"
    bad = [(gid, round(iou, 3)) for gid, iou in seen if iou < 0.9]
    assert not bad, (name, bad)
    # nothing spurious lies over the voids: of the windows in frame facing the camera (incidence
    # < 60 deg), most are seen whole (a window's own parts counted as occluders hid 9 of 14 here)
    facing = [iou for _, iou, _, inc in ious if inc < 60.0]
    assert sum(iou >= 0.9 for iou in facing) >= 0.5 * len(facing), (name, sorted(round(i, 2) for i in facing))


def test_small_wild_house_masks_match_projected_truth(tmp_path):
    _check_masks(_render("wild:ifcopenhouse-ifc4", tmp_path, 3), SMALL)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["wild:curved-wall", "wild:vectorworks-unicode", "wild:renga-house",
                                  "wild:examplehom", "wild:kit-edc", "wild:ifcopenhouse-cvillagrasa",
                                  "wild:lanternhollow", "wild:largebuilding", "wild:ac11-institute"])
def test_wild_house_masks_match_projected_truth(name, tmp_path):
    _check_masks(_render(name, tmp_path, 4), name)


@pytest.mark.slow
def test_loading_the_largest_valid_wild_file_is_bounded(tmp_path):
    """Target: <= 30 s and <= 1 GB for a 5 MB file; checked on the largest file the loader reads
    (AC11-Institute, 2.8 MB), uncached, in a fresh process (its peak resident memory)."""
    largest = max((p for p in WILD.glob("*.ifc") if p.name not in UNREADABLE), key=lambda p: p.stat().st_size)
    code = ("import resource, time; t = time.perf_counter(); from fenestra.scenes.loader import load_scene; "
            f"s = load_scene({str(largest)!r}, use_cache=False); "
            "print(time.perf_counter() - t, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, len(s.windows))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    seconds, max_rss_kb, n = r.stdout.split()[-3:]
    assert int(n) > 0 and float(seconds) <= 30.0 and int(max_rss_kb) <= 1024 * 1024, r.stdout
