"""renders/: mitsuba camera convention, backend agreement, dataset determinism, sampler, sensor."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from fenestra.conventions import look_at, make_K
from fenestra.tolerances import TOL
from fenestra.renders.base import RenderSettings
from fenestra.renders.camera import Camera
from fenestra.rendered_view import read_view
from fenestra.renders.dataset import DatasetConfig, render_dataset
from fenestra.renders.sampler import SamplerConfig, sample_views
from fenestra.renders.sensor import REALISTIC, SensorConfig, apply_sensor
from wall_scenes import wall_scene

SMALL = SamplerConfig(width=160, height=120, street_fraction=0.3, distance_m=(3.0, 8.0))


def test_mitsuba_camera_matches_projection():
    """An emitting quad, box pixel filter: pixel values = coverage; area and centroid pin the camera."""
    from fenestra.renders.gt import polygon_area
    from fenestra.renders.photoreal import import_mitsuba, mesh_object, mitsuba_sensor

    mi = import_mitsuba()
    W, H = 160, 120
    R, t = look_at([0.3, -4, 1.9], [0.6, 0, 1.5], roll_deg=7)
    cam = Camera(make_K(150, 150, 70.3, 66.8), W, H, R, t)  # off-centre principal point
    quad = np.array([[0, 0, 2], [1.2, 0, 2.2], [1.1, 0, 1.1], [0.1, 0, 1.0]])
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "direct"},
                          "q": mesh_object(mi, "q", quad, np.array([[0, 2, 1], [0, 3, 2]]), {"type": "diffuse"},
                                           emitter={"type": "area", "radiance": {"type": "rgb", "value": 1.0}})})
    img = np.array(mi.render(scene, sensor=mi.load_dict(mitsuba_sensor(mi, cam, 256, "box"))))[..., 0]
    px = cam.project(quad)
    x, y = px[:, 0], px[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    cr = x * y1 - x1 * y
    A = cr.sum() / 2
    uu, vv = np.meshgrid(np.arange(W), np.arange(H))
    cx, cy = (img * uu).sum() / img.sum(), (img * vv).sum() / img.sum()
    assert abs(img.sum() - polygon_area(px)) < 0.01 * polygon_area(px)
    assert abs(cx - ((x + x1) * cr).sum() / (6 * A)) < TOL.projection_vs_mask_px
    assert abs(cy - ((y + y1) * cr).sum() / (6 * A)) < TOL.projection_vs_mask_px


def test_backends_agree_and_mitsuba_renders_daylight():
    from fenestra.renders.backends import make_renderer

    scene = wall_scene(sill_top=1.2)
    R, t = look_at([0.5, -5, 2.2], [2.5, 0, 1.5], roll_deg=3)
    cam = Camera.from_fov(160, 120, 60, R, t)
    outs = {}
    for name in ("pyrender", "mitsuba"):
        r = make_renderer(name, scene, RenderSettings(seed=1, spp=4))
        try:
            outs[name] = r.render(cam)
        finally:
            r.close()
    a, b = outs["pyrender"].instances, outs["mitsuba"].instances
    for i in range(1, len(scene.windows) + 1):
        inter, union = ((a == i) & (b == i)).sum(), ((a == i) | (b == i)).sum()
        assert union > 0 and inter / union >= TOL.backend_instance_iou
    rgb = outs["mitsuba"].rgb
    assert rgb.shape == (120, 160, 3) and rgb.dtype == np.uint8
    assert rgb[:10].mean(axis=(0, 1))[2] > rgb[:10].mean(axis=(0, 1))[0]  # blue sky at the top
    assert rgb.std() > 20  # not a flat image
    with pytest.raises(ValueError, match="unknown renderer"):
        make_renderer("povray", scene)


def test_raster_antialias_modes_share_exact_ground_truth():
    """fxaa/none draw the occluder pass as a second render target of the RGB pass, msaa4 draws it
    separately: every mode gives the standalone occluder pass's instances and depth exactly."""
    from fenestra.renders.raster import RasterRenderer, ground_truth

    scene = wall_scene(sill_top=1.2)
    views = sample_views(scene, SMALL, 3, seed=2).views
    rgb = {}
    for aa in ("fxaa", "msaa4", "none"):
        with RasterRenderer(scene, RenderSettings(seed=1, antialias=aa)) as r:
            for v in views:
                out, (inst, depth, _, _) = r.render(v.camera), ground_truth(r.occluders, v.camera)
                np.testing.assert_array_equal(out.instances, inst)
                np.testing.assert_array_equal(out.depth, depth)
                rgb.setdefault(aa, []).append(out.rgb.astype(int))
    for a, b in zip(rgb["fxaa"], rgb["msaa4"]):  # same picture, different edge filtering
        assert np.abs(a - b).mean() < 3
    with pytest.raises(ValueError, match="antialias"):
        RenderSettings(antialias="ssaa")


def test_sampler_is_deterministic_and_counts_rejections():
    from fenestra.renders.sampler import iter_views

    scene = wall_scene()
    a = sample_views(scene, SMALL, 6, seed=3)
    b = sample_views(scene, SMALL, 6, seed=3)
    c = sample_views(scene, SMALL, 6, seed=4)
    for va, vb in zip(a.views, b.views):
        np.testing.assert_array_equal(va.camera.R, vb.camera.R)
    one_by_one = list(iter_views(scene, SMALL, 6, seed=3))  # what render_dataset consumes
    assert [x.index for x in one_by_one] == list(range(6))
    assert (one_by_one[-1].tries, one_by_one[-1].rejected) == (a.tries, a.rejected)
    for x, va in zip(one_by_one, a.views):
        np.testing.assert_array_equal(x.view.camera.t, va.camera.t)
    assert not np.allclose(a.views[0].camera.t, c.views[0].camera.t)
    assert a.tries == 6 + sum(a.rejected.values())
    for v in a.views:  # every accepted target is in front and inside the frame
        for wid in v.targets:
            w = next(w for w in scene.windows if w.id == wid)
            px = v.camera.project(w.corners_world)
            assert np.all(v.camera.depths(w.corners_world) > 0)
            assert np.all((px >= -0.5) & (px <= [159.5, 119.5]))
    tight = SamplerConfig(width=160, height=120, hfov_deg=(10, 10), distance_m=(2, 2), max_tries=5)
    with pytest.raises(ValueError, match="outside_frame"):
        sample_views(scene, tight, 3, seed=0)
    with pytest.raises(ValueError, match="hfov_deg"):
        SamplerConfig(hfov_deg=(70, 50))


def test_dataset_same_seed_same_files_and_reuse(tmp_path):
    scene = wall_scene(sill_top=1.2)
    cfg = DatasetConfig(scene="test-wall", n_views=3, seed=5, sampler=SMALL, out_root=str(tmp_path / "a"))
    root_a = render_dataset(cfg, scene=scene, progress=False)
    root_b = render_dataset(DatasetConfig(**{**cfg.__dict__, "out_root": str(tmp_path / "b")}), scene=scene,
                            progress=False)
    for i in range(3):  # byte-identical files, images included (a fresh GL context each time)
        for f in ("image.png", "instances.png", "view.json"):
            assert (root_a / "views" / f"{i:06d}" / f).read_bytes() == (root_b / "views" / f"{i:06d}" / f).read_bytes()
    v = read_view(root_a / "views" / "000000")
    img, inst, meta = v.image, v.instances, v.meta
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8 and inst.dtype == np.int32 and v.ignore is None
    assert set(meta) >= {"K", "width", "height", "R", "t", "distortion", "renderer", "seed", "windows"}
    w = meta["windows"][0]
    assert set(w) >= {"id", "instance_id", "corners_world", "corners_px", "corner_visible", "visible_fraction",
                      "incidence_deg", "distance_m"}
    coco = json.loads((root_a / "coco.json").read_text())
    assert coco["categories"] == [{"id": 1, "name": "window"}] and len(coco["images"]) == 3
    from fenestra.renders.dataset import coco_from_views

    # coco.json, built from the arrays the run wrote, = the one built by reading the files back
    assert coco == json.loads(json.dumps(coco_from_views(root_a, 3)))
    from pycocotools import mask as mask_utils

    ann = coco["annotations"][0]
    v0 = read_view(root_a / "views" / f"{ann['image_id']:06d}")
    inst0, meta0 = v0.instances, v0.meta
    wid = next(x["instance_id"] for x in meta0["windows"] if x["id"] == ann["window_id"])
    np.testing.assert_array_equal(mask_utils.decode(ann["segmentation"]).astype(bool), inst0 == wid)
    # same config again: everything reused
    assert render_dataset(cfg, scene=scene, progress=False) == root_a
    assert json.loads((root_a / "stats.json").read_text())["reused"] == 3
    # a different seed: a different folder and different cameras
    root_c = render_dataset(DatasetConfig(**{**cfg.__dict__, "seed": 6}), scene=scene, progress=False)
    assert root_c != root_a
    assert read_view(root_c / "views" / "000000").meta["t"] != meta["t"]


def test_sensor_changes_images_only():
    rgb = np.full((40, 50, 3), 120, np.uint8)
    out = apply_sensor(rgb, REALISTIC, np.random.default_rng(0))
    assert out.shape == rgb.shape and out.dtype == np.uint8 and not np.array_equal(out, rgb)
    assert np.array_equal(rgb, np.full((40, 50, 3), 120, np.uint8))  # input untouched
    assert np.array_equal(apply_sensor(rgb, SensorConfig(), np.random.default_rng(0)), rgb)
    with pytest.raises(ValueError, match="uint8"):
        apply_sensor(rgb.astype(np.float32), REALISTIC, np.random.default_rng(0))
    with pytest.raises(ValueError, match="jpeg_quality"):
        SensorConfig(jpeg_quality=(0, 120))


def test_fzk_haus_views_have_consistent_ground_truth():
    from fenestra.renders.raster import RasterRenderer, ground_truth
    from fenestra.scenes import load_scene

    scene = load_scene("fzk-haus")
    res = sample_views(scene, SamplerConfig(width=320, height=240, street_fraction=0.5), 3, seed=0)
    with RasterRenderer(scene) as r:
        for v in res.views:
            out = r.render(v.camera)
            # the view's ground truth = a fresh occluder pass of its camera (what the sampler tested)
            np.testing.assert_array_equal(out.instances, ground_truth(r.occluders, v.camera)[0])
            ids = set(np.unique(out.instances)) - {0}
            assert ids <= set(range(1, len(scene.windows) + 1))
            for w in out.windows:
                assert 0.0 <= w.visible_fraction <= 1.0
                assert w.visible_px == int((out.instances == w.instance_id).sum())
            t = next(w for w in out.windows if w.id == v.targets[0])
            assert t.visible_px > 0


def test_one_occluder_pass_per_view_and_an_exact_depth_prepass():
    """The sampler's visibility test keeps its occluder pass's ground truth for the render of the
    accepted camera (one pass per view) and issues the candidate's RGB pass with that pass's depth
    as its pre-pass; the image must be exactly the one of a plain depth test, coplanar ties
    included (walls and ground, glazing in frames): when the render follows the test (the dataset
    path), after a rejected candidate, and when another renderer in the same GL context drew its
    own occluder pass in between (the framebuffer they share then holds the other's pass)."""
    from fenestra.renders.backends import visibility_function
    from fenestra.renders.raster import RasterRenderer, ground_truth
    from fenestra.scenes import load_scene

    scene = load_scene("fzk-haus")
    views = sample_views(scene, SamplerConfig(width=320, height=240, street_fraction=0.5), 5, seed=1).views
    other = wall_scene(sill_top=1.2)
    with RasterRenderer(scene) as r, RasterRenderer(other) as r2:
        vis = visibility_function("pyrender", r)
        plain = [r.render_rgb(v.camera, prepass=False) for v in views]
        for k, v in enumerate(views):
            wins = vis(v.camera)
            out = r.render(v.camera)  # the dataset path: the test's pass and RGB triangles taken
            assert out.windows is wins
            np.testing.assert_array_equal(out.rgb, plain[k])
            fresh = ground_truth(r.occluders, v.camera)
            np.testing.assert_array_equal(out.instances, fresh[0])
            np.testing.assert_array_equal(out.depth, fresh[1])
            assert r.occluders.truth(v.camera)[2] is not wins  # taken once, then drawn afresh
            if k % 2:  # the other renderer's occluder pass of a same-size view, in between
                r2.occluders.truth(v.camera)
            np.testing.assert_array_equal(r.render_rgb(v.camera), plain[k])
        vis(views[0].camera)  # a candidate rejected, the next one accepted
        vis(views[1].camera)
        np.testing.assert_array_equal(r.render(views[1].camera).rgb, plain[1])
        np.testing.assert_array_equal(r.render(views[0].camera).rgb, plain[0])
        vis(views[2].camera)  # tested, then another camera rendered
        np.testing.assert_array_equal(r.render(views[3].camera).rgb, plain[3])


def test_oidn_denoising_brings_low_spp_render_closer_to_high_spp_reference():
    """4 spp + OIDN (colour only, and guided by AOVs) vs the same 4 spp samples raw, against the mean
    of two independent 128-spp renders of the view (their disagreement bounds the reference's own
    noise); cache names keep apart. Measured (80x60, sRGB RMSE): reference 2.1, raw 17.9, oidn 5.8, oidn-aov 5.7."""
    from fenestra.renders.dataset import DatasetConfig, config_hash
    from fenestra.renders.photoreal import PhotorealRenderer, linear_to_srgb

    scene = wall_scene(sill_top=1.2)
    R, t = look_at([0.5, -5, 2.2], [2.5, 0, 1.5], roll_deg=3)
    cam = Camera.from_fov(80, 60, 60, R, t)
    srgb = lambda x: linear_to_srgb(x) * 255  # noqa: E731
    rmse = lambda a, b: float(np.sqrt(np.mean((a - b) ** 2)))  # noqa: E731
    errs = {}
    for mode in ("oidn", "oidn-aov"):
        with PhotorealRenderer(scene, RenderSettings(seed=1, spp=4, denoise=mode)) as r:
            den, den2 = srgb(r.render_linear(cam)), srgb(r.render_linear(cam))
            raw = srgb(r.render_linear(cam, denoise=False))  # the same samples, not denoised
            if mode == "oidn":  # box pixel filter, like every denoised render
                refs = [srgb(r.render_linear(cam, spp=128, seed=s, denoise=False)) for s in (101, 102)]
                ref, ref_noise = (refs[0] + refs[1]) / 2, rmse(*refs) / 2  # noise of the mean, sRGB levels
        np.testing.assert_allclose(den, den2, atol=0.01)  # mitsuba's LLVM sums vary in the last float bits only
        errs[mode] = rmse(raw, ref), rmse(den, ref)
        assert abs(den.mean() - ref.mean()) < 2.0, (mode, den.mean(), ref.mean())  # no brightness shift
    for e_raw, e_den in errs.values():
        assert ref_noise < 0.2 * e_raw, (ref_noise, e_raw)
        assert e_den < 0.4 * e_raw, errs
    hashes = {(r, d): config_hash(DatasetConfig(scene="w", renderer=r, settings=RenderSettings(denoise=d)), scene)
              for r in ("pyrender", "mitsuba") for d in ("none", "oidn", "oidn-aov")}
    assert len({hashes["mitsuba", d] for d in ("none", "oidn", "oidn-aov")}) == 3
    assert len({hashes["pyrender", d] for d in ("none", "oidn", "oidn-aov")}) == 1  # raster ignores it
    with pytest.raises(ValueError, match="denoise"):
        RenderSettings(denoise="optix")


def test_renderer_entries_declare_their_visibility_test(tmp_path, monkeypatch):
    """Every registered backend declares a visibility test that gives the same per-window visibility
    as its own render; one without a test cannot render a dataset that needs one (an error naming it,
    never a silent skip), and can when the sampler does not need it."""
    from fenestra.renders import backends
    from fenestra.renders.backends import RENDERERS, RendererEntry, visibility_function

    scene = wall_scene(sill_top=1.2)
    R, t = look_at([0.5, -5, 2.2], [2.5, 0, 1.5], roll_deg=3)
    cam = Camera.from_fov(160, 120, 60, R, t)
    for name, entry in RENDERERS.items():
        assert entry.name == name and entry.description.strip() and entry.visibility is not None
    r = backends.make_renderer("pyrender", scene, RenderSettings(seed=1))
    try:
        vis = {w.id: w.visible_fraction for w in visibility_function("pyrender", r)(cam)}
        rendered = {w.id: w.visible_fraction for w in r.render(cam).windows}
    finally:
        r.close()
    assert vis == rendered and len(vis) == len(scene.windows) and max(vis.values()) > 0.5

    class Flat:
        name = "flat"

        def render(self, camera):
            from fenestra.renders.base import RenderOutput
            W, H = camera.width, camera.height
            return RenderOutput(camera, np.zeros((H, W, 3), np.uint8), np.zeros((H, W), np.uint16),
                                np.zeros((H, W), np.float32), ())

        def close(self):
            pass

    monkeypatch.setitem(RENDERERS, "flat", RendererEntry("flat", lambda s, st: Flat(), "no visibility test", None))
    with pytest.raises(ValueError, match="renderer 'flat' declares no visibility test"):
        render_dataset(DatasetConfig("wall", n_views=1, renderer="flat", sampler=SMALL, out_root=str(tmp_path)),
                       scene=scene, progress=False)
    free = dataclasses.replace(SMALL, min_visible_fraction=0.0)
    root = render_dataset(DatasetConfig("wall", n_views=1, renderer="flat", sampler=free, out_root=str(tmp_path)),
                          scene=scene, progress=False)
    assert (root / "views" / "000000" / "view.json").is_file()
