"""RenderSettings.look: "classic" draws exactly what it always did; "wide" widens the palette,
wall materials, glass and lighting without touching the ground truth or old dataset folders."""
from __future__ import annotations

import numpy as np
import pytest

from fenestra.renders.base import RenderSettings
from fenestra.renders.dataset import DatasetConfig, config_hash
from fenestra.renders.materials import ashlar_texture, glass_texture, sample_look
from fenestra.renders.sampler import SamplerConfig, sample_views
from wall_scenes import wall_scene


def test_classic_look_draws_what_it_always_drew():
    """The numbers below were printed by sample_look(default_rng(0)) BEFORE the look option
    existed (commit b859264), as was the generator's next draw: classic makes the same calls."""
    rng = np.random.default_rng(0)
    look = sample_look(rng)
    assert look == sample_look(np.random.default_rng(0), "classic")
    assert (look.wall_style, look.wall_rgb, look.frame_rgb, look.roof_rgb, look.ground_style) == (
        "plaster", (0.86, 0.86, 0.84), (0.22, 0.23, 0.25), (0.55, 0.2, 0.14), "grass")
    assert look.sun_azimuth_deg == pytest.approx(292.77728611209807, abs=1e-12)
    assert look.sun_elevation_deg == pytest.approx(56.51022309110887, abs=1e-12)
    assert look.sun_intensity == pytest.approx(3.10663577576718, abs=1e-12)
    assert look.ambient == pytest.approx(0.45942448414759973, abs=1e-12)
    assert look.sky_zenith == pytest.approx((0.33154374871981346, 0.5902608635681652, 0.9223780331182299))
    assert rng.random() == pytest.approx(0.002738500170148095, abs=1e-15)
    assert look.weather == "clear" and look.sun_tint == (1.0, 1.0, 1.0) and look.glass_tint == (1.0, 1.0, 1.0)
    from fenestra.renders.photoreal import glass_diffuse
    assert glass_diffuse(look) == [0.01, 0.012, 0.015]  # mitsuba's classic glass BSDF
    seven = sample_look(np.random.default_rng(7))
    assert seven.roof_rgb == (0.25, 0.25, 0.27) and seven.sun_intensity == pytest.approx(2.5052653045655746)
    # the parameterised glass texture's defaults are the old formula
    v = np.linspace(1.0, 0.0, 256)[:, None]
    sky = np.float32([0.82, 0.88, 0.95]) * 0.45 + np.float32([0.3, 0.5, 0.9]) * 0.15
    dark = np.float32([0.10, 0.12, 0.14])
    old = np.clip((dark + (sky - dark) * (v ** 1.5)[..., None]) * 255, 0, 255).astype(np.uint8)
    np.testing.assert_array_equal(glass_texture((0.82, 0.88, 0.95), (0.3, 0.5, 0.9)),
                                  np.broadcast_to(old, (256, 256, 3)))


def test_wide_look_spreads_colours_materials_and_weather():
    looks = [sample_look(np.random.default_rng(s), "wide") for s in range(50)]
    assert len({lk.wall_rgb for lk in looks}) > 40
    assert len({tuple(np.round(lk.wall_rgb, 1)) for lk in looks}) > 15  # not one colour jittered
    assert {lk.wall_style for lk in looks} == {"plaster", "brick", "stone"}
    assert {lk.weather for lk in looks} == {"clear", "low_sun", "overcast"}
    for lk in looks:
        if lk.weather == "overcast":
            assert lk.ambient >= 0.8 and lk.sun_intensity <= 0.8
        if lk.weather == "low_sun":
            assert 8 <= lk.sun_elevation_deg <= 20
    assert len({lk.glass_tint for lk in looks}) >= 4 and len({lk.sky_horizon for lk in looks}) >= 3
    with pytest.raises(ValueError, match="look.*'baroque'"):
        sample_look(np.random.default_rng(0), "baroque")
    with pytest.raises(ValueError, match="look.*'baroque'"):
        RenderSettings(look="baroque")


def test_ashlar_texture_has_dark_joints_and_tiles():
    t = ashlar_texture(np.random.default_rng(0), (0.8, 0.75, 0.65)).astype(float)
    lum = t.mean(axis=2)
    assert lum[0].mean() < 0.6 * lum[32].mean()  # the bed joint at each course's top edge
    assert abs(lum[:, 0].mean() - lum[:, -1].mean()) < 0.25 * lum.mean()  # wraps without a seam


def test_look_counts_in_the_dataset_hash_only_when_not_classic():
    """4e2ec70ae75e and 71b36db4ef21 were printed BEFORE the look option existed (commit b859264):
    existing dataset folders keep their names."""
    scene = wall_scene()
    assert config_hash(DatasetConfig("w"), scene) == "4e2ec70ae75e"
    mitsuba = DatasetConfig("w", n_views=3, seed=5, renderer="mitsuba",
                            settings=RenderSettings(seed=5, spp=4, denoise="oidn"))
    assert config_hash(mitsuba, scene) == "71b36db4ef21"
    wide = DatasetConfig("w", settings=RenderSettings(look="wide"))
    assert config_hash(wide, scene) != "4e2ec70ae75e"


def test_wide_look_changes_pixels_not_ground_truth():
    from fenestra.renders.raster import RasterRenderer

    scene = wall_scene(sill_top=1.2)
    views = sample_views(scene, SamplerConfig(width=96, height=72, street_fraction=0.0,
                                              distance_m=(3.0, 6.0)), 2, seed=2).views
    out = {}
    for look in ("classic", "wide"):
        with RasterRenderer(scene, RenderSettings(seed=3, look=look)) as r:
            out[look] = [r.render(v.camera) for v in views]
    for c, w in zip(out["classic"], out["wide"]):
        np.testing.assert_array_equal(c.instances, w.instances)
        np.testing.assert_array_equal(c.depth, w.depth)
        assert (c.instances > 0).any()
        assert np.abs(c.rgb.astype(int) - w.rgb.astype(int)).mean() > 5


# ---------------------------------------------------------------- a look per view (issue #36)
def _per_view_config(root, look_per: str, seed: int = 4, n_views: int = 3) -> DatasetConfig:
    sampler = SamplerConfig(width=96, height=72, street_fraction=0.0, distance_m=(3.0, 6.0))
    return DatasetConfig("w", n_views=n_views, seed=seed, sampler=sampler, out_root=str(root),
                         settings=RenderSettings(look="wide", look_per=look_per))


def test_each_view_draws_its_own_look_and_renders_in_it(tmp_path):
    """look_per = "view": two views of one house get different looks (drawn from each view's own
    stream, recomputed here with numpy), and each image is what a renderer built with that look
    draws for the view's camera; look_per = "set" keeps one look and view.json as it was."""
    import json

    from fenestra.rendered_view import read_view
    from fenestra.renders.camera import Camera
    from fenestra.renders.dataset import LOOK_STREAM, render_dataset
    from fenestra.renders.raster import RasterRenderer

    scene = wall_scene(sill_top=1.2)
    root = render_dataset(_per_view_config(tmp_path, "view"), scene, progress=False)
    views = [read_view(root / "views" / f"{i:06d}") for i in range(3)]
    seeds = [int(np.random.SeedSequence([4, i, LOOK_STREAM]).generate_state(1, np.uint32)[0]) for i in range(3)]
    assert [v.meta["look"]["seed"] for v in views] == seeds and len(set(seeds)) == 3
    looks = [sample_look(np.random.default_rng(s), "wide") for s in seeds]
    for v, lk in zip(views, looks):
        assert v.meta["look"]["wall_rgb"] == list(lk.wall_rgb) and v.meta["look"]["weather"] == lk.weather
    assert len({lk.wall_rgb for lk in looks}) == 3 and len({lk.sun_azimuth_deg for lk in looks}) == 3
    for i in (0, 2):  # rendered in its own look: a renderer with that look's seed draws the same bytes
        with RasterRenderer(scene, RenderSettings(seed=seeds[i], look="wide")) as r:
            out = r.render(Camera.from_dict(views[i].meta))
        np.testing.assert_array_equal(out.rgb, views[i].image)
        np.testing.assert_array_equal(out.instances, views[i].instances)
    # one look per set: no look in view.json, every view drawn by the one renderer of the dataset's seed
    flat = render_dataset(_per_view_config(tmp_path, "set"), scene, progress=False)
    assert flat != root and "look" not in json.loads((flat / "views" / "000001" / "view.json").read_text())
    same = read_view(flat / "views" / "000001")
    with RasterRenderer(scene, RenderSettings(seed=4, look="wide")) as r:
        np.testing.assert_array_equal(r.render(Camera.from_dict(same.meta)).rgb, same.image)


def test_a_view_with_its_seed_is_bit_identical_and_the_look_changes_the_folder(tmp_path):
    from fenestra.renders.dataset import render_dataset

    scene = wall_scene()
    a = render_dataset(_per_view_config(tmp_path / "a", "view", n_views=2), scene, progress=False)
    b = render_dataset(_per_view_config(tmp_path / "b", "view", n_views=2), scene, progress=False)
    assert a.name == b.name
    for i in range(2):
        for f in ("image.png", "instances.png", "view.json"):
            assert (a / "views" / f"{i:06d}" / f).read_bytes() == (b / "views" / f"{i:06d}" / f).read_bytes(), f
    other = render_dataset(_per_view_config(tmp_path / "a", "view", seed=5, n_views=2), scene, progress=False)
    assert (other / "views" / "000000" / "image.png").read_bytes() != (a / "views" / "000000" / "image.png").read_bytes()
    # the folder hash: look_per counts only when it is not "set" (old folders keep their names)
    assert config_hash(DatasetConfig("w", settings=RenderSettings(look_per="set")), scene) == "4e2ec70ae75e"
    assert config_hash(DatasetConfig("w", settings=RenderSettings(look_per="view")), scene) != "4e2ec70ae75e"
    assert len({a.name, other.name}) == 2
    with pytest.raises(ValueError, match="look_per.*'house'"):
        RenderSettings(look_per="house")


def test_a_renderer_like_another_shares_its_occluder_pass_and_draws_the_same_bytes(tmp_path):
    """A renderer built ``like`` another of the same scene in another look takes its SceneGeometry and,
    when its triangles come out in the same draw order (two plaster or brick looks), its occluder
    pass: the sampler's ground truth of a view is then drawn once, and the image, instance map and
    depth are byte for byte those of a renderer built alone. A stone wall draws its groups in
    another order (renders.raster.draw_priority): its own pass. A per-view dataset draws one occluder
    pass per view."""
    from dataclasses import replace

    from fenestra.conventions import look_at
    from fenestra.renders import dataset
    from fenestra.renders.camera import Camera
    from fenestra.renders.dataset import render_dataset
    from fenestra.renders.raster import OccluderPass, RasterRenderer

    scene = wall_scene(sill_top=1.2)
    styles = {s: sample_look(np.random.default_rng(s), "wide").wall_style for s in range(40)}
    plain = [s for s, st in styles.items() if st != "stone"][:2]
    stone = next(s for s, st in styles.items() if st == "stone")
    R, t = look_at([0.5, -5, 2.2], [2.5, 0, 1.5], roll_deg=3)
    cam = Camera.from_fov(160, 120, 60, R, t)
    with RasterRenderer(scene, RenderSettings(seed=plain[0], look="wide")) as base:
        for seed, shared in ((plain[1], True), (stone, False)):
            with RasterRenderer(scene, RenderSettings(seed=seed, look="wide")) as alone:
                want = alone.render(cam)
            base.occluders.truth(cam, keep=True)  # the sampler's visibility test, on the base renderer
            with RasterRenderer(scene, RenderSettings(seed=seed, look="wide"), like=base) as r:
                assert (r.occluders is base.occluders) == shared and r.geometry is base.geometry
                got = r.render(cam)
            for a, b in ((got.rgb, want.rgb), (got.instances, want.instances), (got.depth, want.depth)):
                np.testing.assert_array_equal(a, b)
        assert base.occluders._geom is not None  # the sharers' close() left the base's pass alive

    draws, tests = [], []
    real_draw, real_test = OccluderPass._draw, dataset.occluder_visibility

    def counted(self, PV, width, height):
        draws.append((width, height))
        return real_draw(self, PV, width, height)

    def test(renderer, camera):
        tests.append(camera)
        return real_test(renderer, camera)

    config = _per_view_config(tmp_path, "view", n_views=3)
    config = replace(config, settings=replace(config.settings, look="classic"))  # no stone wall: always shared
    OccluderPass._draw, dataset.occluder_visibility = counted, test
    try:
        render_dataset(config, scene, progress=False)
    finally:
        OccluderPass._draw, dataset.occluder_visibility = real_draw, real_test
    assert len(tests) >= 3 and draws.count((96, 72)) == len(tests)  # none again for an accepted view
    assert len(draws) - len(tests) == 4  # shadow maps: the sampler's renderer's and one per view's own look
