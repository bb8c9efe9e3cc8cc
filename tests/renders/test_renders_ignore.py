"""Ignore regions in rendered views (curtain-wall glazing, glazed doors: COCO ``iscrowd``):
fenestra/renders/gt.py + raster.py draw them, fenestra/renders/dataset.py writes and backfills them, the bench's
detection AP honours them."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from fenestra.bench.detection_ap import coco_ap
from fenestra.coco import coco_result
from fenestra.masks import mask_box, rle_from_mask
from fenestra.rendered_view import check_view, read_view, view_annotations, write_view
from fenestra.renders.camera import Camera
from fenestra.renders.dataset import DatasetConfig, render_dataset
from fenestra.renders.gt import inside_convex
from fenestra.renders.sampler import SamplerConfig
from fenestra.scenes.generate import HouseSpec, make_house
from fenestra.scenes.loader import load_scene

# seed 16 of this house's street views: view 0 sees the curtain wall, view 1 the glazed door, both
# with windows in view (a change of the sampler may need another seed: the test says which view lacks what)
SPEC = HouseSpec(seed=3, glazed_doors=1, curtain_walls=1, windows_per_wall=2)
SAMPLER = SamplerConfig(width=160, height=120, street_fraction=1.0)


@pytest.fixture(scope="module")
def facade(tmp_path_factory):
    """(generated house, scene, rendered 2-view dataset folder)."""
    tmp = tmp_path_factory.mktemp("facade")
    house = make_house(SPEC, tmp / "house.ifc")
    scene = load_scene(tmp / "house.ifc", cache_dir=tmp / "cache")
    cfg = DatasetConfig(scene=str(tmp / "house.ifc"), n_views=2, seed=16, sampler=SAMPLER, out_root=str(tmp / "r"))
    return house, scene, render_dataset(cfg, scene=scene, progress=False), cfg


def _void_mask(camera: Camera, corners_world: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixel centres inside the projected void rectangle, grown by 1 px (pinhole)."""
    p = camera.project(corners_world)
    uu, vv = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    m = inside_convex(p, uu, vv).astype(np.uint8)
    return cv2.dilate(m, np.ones((3, 3), np.uint8)).astype(bool)


def test_generated_house_views_carry_curtain_wall_and_glazed_door_ignore_regions(facade):
    import ifcopenshell

    house, scene, root, _ = facade
    (cwall,) = ifcopenshell.open(house.path).by_type("IfcCurtainWall")  # one storey: one curtain wall
    expected = [("curtain_wall", cwall.GlobalId, house.curtain_walls[0].corners_world),
                ("glazed_door", house.doors[0].element_id, house.doors[0].corners_world)]
    coco = json.loads((root / "coco.json").read_text())
    for i, (kind, gid, void) in enumerate(expected):
        d = root / "views" / f"{i:06d}"
        assert (d / "ignore.png").is_file(), f"view {i} shows no {kind}: pick another SAMPLER seed"
        v = read_view(d)
        assert [(r["kind"], r["id"]) for r in v.ignore_regions] == [(kind, gid)], f"view {i}"
        (r,) = v.ignore_regions
        ign = v.ignore == r["instance_id"]
        assert ign.sum() == r["visible_px"] > 50
        assert (v.instances > 0).sum() > 50, f"view {i} has no window: pick another SAMPLER seed"
        assert not (ign & (v.instances > 0)).any()  # ignore pixels never take a window's
        # the glazing is seen through its void (the wall hides the rest), and fills most of it:
        # a door set back in its reveal, panes between mullions
        cam = Camera.from_dict(v.meta)
        void_px = _void_mask(cam, void)
        assert not (ign & ~void_px).any()
        assert ign.sum() >= 0.5 * void_px.sum()
        crowd = [a for a in coco["annotations"] if a["image_id"] == i and a["iscrowd"]]
        assert [(a["kind"], a["ignore_id"], a["area"]) for a in crowd] == [(kind, gid, float(ign.sum()))]
    # the curtain wall's panes are one region: the IfcCurtainWall, not its IfcPlates
    assert {m.parent_id for m in scene.meshes if m.ifc_class == "IfcPlate"} == {cwall.GlobalId}


def test_cached_views_without_ignore_regions_get_them_without_re_rendering(facade):
    """A view rendered before the renderers drew ignore regions (no ``ignore`` key) gets ignore.png
    and its view.json list from the occluder pass alone; image and instances stay as they are."""
    house, scene, root, cfg = facade
    d = root / "views" / "000001"
    before = {n: (d / n).read_bytes() for n in ("image.png", "instances.png", "ignore.png")}
    meta = json.loads((d / "view.json").read_text())
    old = {k: v for k, v in meta.items() if k != "ignore"}
    old["files"] = {k: v for k, v in meta["files"].items() if k != "ignore.png"}
    (d / "ignore.png").unlink()
    (d / "view.json").write_text(json.dumps(old))
    mtime = (d / "image.png").stat().st_mtime_ns
    assert render_dataset(cfg, scene=scene, progress=False) == root
    assert json.loads((root / "stats.json").read_text())["ignore_added"] == 1
    assert {n: (d / n).read_bytes() for n in before} == before
    assert (d / "image.png").stat().st_mtime_ns == mtime
    assert json.loads((d / "view.json").read_text()) == meta and check_view(d) is None


def test_bench_detection_ap_honours_a_rendered_views_ignore_region(tmp_path):
    """The bench's AP (bench.detection_ap.coco_ap) on the ground truth of a written view
    (fenestra.rendered_view.view_annotations: windows A, B and ignore region R from ignore.png).

    Detections, best score first: d1 (0.9) inside R, d2 (0.8) on nothing, d3 (0.7) exactly A; B is
    missed. With R: d1 counts neither way; ranked d2 (FP: precision 0/1, recall 0), d3 (TP:
    precision 1/2, recall 1/2). COCO's interpolated precision is 1/2 at the 51 recall points
    0, 0.01, ..., 0.50 and 0 at the 50 above: AP50 = 0.5 * 51 / 101 = 0.2525 (d3 is exact: the
    same at every IoU threshold). Without R, d1 is a false positive too: d1 (0/1), d2 (0/2), d3
    (1/3 at recall 1/2): AP50 = (1/3) * 51 / 101 = 0.1683."""
    S = (100, 100)
    inst, ign = np.zeros(S, np.int32), np.zeros(S, np.int32)
    inst[10:30, 10:30], inst[10:30, 50:70] = 1, 2  # A, B
    ign[60:90, 10:90] = 3  # R
    meta = {"K": np.eye(3).tolist(), "width": 100, "height": 100, "R": np.eye(3).tolist(), "t": [0, 0, 1],
            "windows": [{"id": "A", "instance_id": 1}, {"id": "B", "instance_id": 2}],
            "ignore": [{"id": "R", "instance_id": 3, "kind": "curtain_wall"}]}
    write_view(tmp_path / "v", np.zeros((*S, 3), np.uint8), inst, meta, ignore=ign)
    gt = view_annotations(read_view(tmp_path / "v"), "house/000000")
    assert [a["iscrowd"] for a in gt] == [0, 0, 1]

    def rect(r0, r1, c0, c1):
        m = np.zeros(S, bool)
        m[r0:r1, c0:c1] = True
        return m

    dt = [coco_result("house/000000", s, mask_box(m), rle_from_mask(m))
          for s, m in ((0.9, rect(65, 85, 20, 40)), (0.8, rect(40, 50, 80, 96)), (0.7, inst == 1))]
    with_r, without_r = coco_ap(gt, dt), coco_ap(gt[:2], dt)
    for t in ("bbox", "segm"):
        assert with_r[f"{t}_AP50"] == pytest.approx(0.5 * 51 / 101, abs=1e-12)
        assert with_r[f"{t}_AP"] == pytest.approx(0.5 * 51 / 101, abs=1e-12)
        assert without_r[f"{t}_AP50"] == pytest.approx(51 / 101 / 3, abs=1e-12)


def test_every_backend_draws_the_same_ignore_map(facade):
    """pyrender (the occluder codes as a second render target of its RGB pass, FXAA; or the
    separate occluder pass, MSAA) and mitsuba (the separate pass) give the dataset's ignore map."""
    from fenestra.renders.backends import make_renderer
    from fenestra.renders.base import RenderSettings

    _, scene, root, _ = facade
    v = read_view(root / "views" / "000001")
    cam = Camera.from_dict(v.meta)
    for name, settings in (("pyrender", RenderSettings(seed=16, antialias="fxaa")),
                           ("pyrender", RenderSettings(seed=16, antialias="msaa4")),
                           ("mitsuba", RenderSettings(seed=16, spp=1))):
        r = make_renderer(name, scene, settings)
        try:
            out = r.render(cam)
        finally:
            r.close()
        np.testing.assert_array_equal(out.ignore, v.ignore, err_msg=f"{name} {settings.antialias}")
        assert list(out.ignore_regions) == v.ignore_regions


def test_a_standard_case_door_is_an_ignore_region_like_a_door(facade):
    """IfcDoorStandardCase (base class IfcDoor, scenes.model.ElementMesh.kind) is a glazed door too."""
    import dataclasses

    from fenestra.renders.gt import ignore_regions

    _, scene, _, _ = facade
    assert any(r.kind == "glazed_door" for r in ignore_regions(scene))
    as_standard_case = [dataclasses.replace(m, ifc_class="IfcDoorStandardCase", base_class="IfcDoor")
                        if m.ifc_class == "IfcDoor" else m for m in scene.meshes]
    renamed = dataclasses.replace(scene, meshes=type(scene.meshes)(as_standard_case))
    assert [(r.id, r.kind) for r in ignore_regions(renamed)] == [(r.id, r.kind) for r in ignore_regions(scene)]
