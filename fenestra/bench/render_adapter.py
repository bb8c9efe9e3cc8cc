"""The bridge between the bench and renders/ and scenes/: house files, dataset configs, and the
rendered-view adapter (a view folder of the data contract -> bench.views.LabelledView).

Kept in one module so that changes to the renders/ config dataclasses or the view contract touch
only this file.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fenestra.bench.profiles import Profile, ProfileError
from fenestra.bench.views import NAN, LabelledView, LabelledWindow
from fenestra.masks import SparseMask
from fenestra.rendered_view import View, read_view
from fenestra.scenes.generate import HouseSpec, make_house
from fenestra.config import from_table
from fenestra.renders.base import RenderSettings
from fenestra.renders.dataset import DatasetConfig
from fenestra.renders.sampler import SamplerConfig
from fenestra.renders.sensor import SensorConfig

PROCEDURAL_DIR = Path("out") / "scenes"


def procedural_spec(seed: int):
    """A varied procedural house for seed (storeys, windows per wall, rotation drawn from it)."""


    rng = np.random.default_rng(seed)
    return HouseSpec(seed=seed, storeys=int(rng.integers(1, 3)), windows_per_wall=int(rng.integers(1, 4)),
                     rotation_deg=float(rng.uniform(0, 90)))


def house_path(house: str) -> str:
    """A bundled house name / IFC path as is; "procedural:<seed>" -> a generated IFC (cached)."""
    if not house.startswith("procedural:"):
        return house
    seed = int(house.split(":", 1)[1])

    p = PROCEDURAL_DIR / f"procedural-{seed}.ifc"
    if not p.is_file():
        p.parent.mkdir(parents=True, exist_ok=True)
        make_house(procedural_spec(seed), p)
    return str(p)


OPTION_SECTIONS = ("sampler", "settings", "sensor")


def _section(cls, opts: dict, where: str):
    """cls from a ``[render.options.*]`` table (fenestra.config.from_table): unknown keys and bad
    values are reported as ProfileError naming them."""

    return from_table(cls, opts, where, ProfileError)


def dataset_config(profile: Profile, house: str, renders_dir: Path):
    """renders.dataset.DatasetConfig for one house of a profile, rendering under ``renders_dir``.

    ``[render.options.sampler|settings|sensor]`` tables of the profile go to SamplerConfig,
    RenderSettings and SensorConfig; width/height always come from ``[render]``.
    """

    render = profile.source.render
    opts = dict(render.options)
    unknown = sorted(set(opts) - set(OPTION_SECTIONS))
    if unknown:
        raise ProfileError(f"profile {profile.name!r} [render.options]: unknown table(s) {unknown}; "
                           f"allowed: {list(OPTION_SECTIONS)}")
    where = f"profile {profile.name!r} [render.options.%s]"
    sampler = {**opts.get("sampler", {}), "width": render.width, "height": render.height}
    return DatasetConfig(scene=house_path(house), n_views=render.views_per_house,
                         seed=profile.seed, renderer=render.renderer,
                         sampler=_section(SamplerConfig, sampler, where % "sampler"),
                         settings=_section(RenderSettings, opts.get("settings", {}), where % "settings"),
                         sensor=_section(SensorConfig, opts.get("sensor", {}), where % "sensor"),
                         out_root=str(renders_dir))


# ---------------------------------------------------------------- rendered views

def _window(w: dict, mask: SparseMask) -> LabelledWindow:
    """A view.json window (exact truth) with its mask from instances.png."""
    Cw = np.asarray(w["corners_world"], dtype=np.float64)
    width, height = float(np.linalg.norm(Cw[1] - Cw[0])), float(np.linalg.norm(Cw[0] - Cw[3]))
    return LabelledWindow(id=w["id"], quad=np.asarray(w["corners_px"], dtype=np.float64), mask=mask,
                          aspect=width / height, size_m=(width, height), instance_id=int(w["instance_id"]),
                          corners_world=Cw, incidence_deg=float(w.get("incidence_deg", NAN)),
                          distance_m=float(w.get("distance_m", NAN)),
                          visible_fraction=float(w.get("visible_fraction", NAN)),
                          corner_visible=tuple(bool(v) for v in w.get("corner_visible", [True] * 4)))


def labelled_view(view: View, house: str, name: str, renderer: str) -> LabelledView:
    """The LabelledView of a rendered view (fenestra.rendered_view.View): every view.json window with its
    exact quad (corners_px, may lie outside the image), world corners, aspect and size, its mask
    from instances.png (View.window_masks: empty when hidden), the camera pose and K; the ignore
    regions present in ignore.png as masks (View.ignore_masks), with their kind."""
    ignore = tuple(LabelledWindow(id=str(r["id"]), mask=m, instance_id=int(r["instance_id"]), kind=r.get("kind"))
                   for r, m in view.ignore_masks())
    meta = view.meta
    return LabelledView(dataset=house, name=name, image=view.image,
                        windows=tuple(_window(w, m) for w, m in zip(view.windows, view.window_masks())), K=view.K,
                        ignore=ignore, renderer=renderer, instances=view.instances,
                        pose=(np.asarray(meta["R"], dtype=np.float64), np.asarray(meta["t"], dtype=np.float64)))


def read_rendered_view(view_dir: str | Path, house: str, renderer: str) -> LabelledView:
    """The LabelledView of a view folder (image.png, instances.png, ignore.png, view.json; see
    :func:`labelled_view`), named by the folder; DatasetError naming a missing or damaged file."""
    return labelled_view(read_view(view_dir), house, Path(view_dir).name, renderer)


@dataclass(frozen=True)
class RenderedViewRef:
    """A rendered view folder to read in a worker (picklable): bench.evaluate.ViewTask's source."""

    view_dir: str
    house: str
    renderer: str

    def load(self) -> LabelledView:
        return read_rendered_view(self.view_dir, self.house, self.renderer)
