"""The bridge from a benchmark profile to renders/ and scenes/: house files and dataset configs.

Kept in one module so that changes to the renders/ config dataclasses touch only this file.
"""
from __future__ import annotations

from pathlib import Path

from bench.profiles import Profile, ProfileError

PROCEDURAL_DIR = Path("out") / "scenes"


def procedural_spec(seed: int):
    """A varied procedural house for seed (storeys, windows per wall, rotation drawn from it)."""
    import numpy as np  # noqa: PLC0415

    from scenes.generate import HouseSpec  # noqa: PLC0415

    rng = np.random.default_rng(seed)
    return HouseSpec(seed=seed, storeys=int(rng.integers(1, 3)), windows_per_wall=int(rng.integers(1, 4)),
                     rotation_deg=float(rng.uniform(0, 90)))


def house_path(house: str) -> str:
    """A bundled house name / IFC path as is; "procedural:<seed>" -> a generated IFC (cached)."""
    if not house.startswith("procedural:"):
        return house
    seed = int(house.split(":", 1)[1])
    from scenes.generate import make_house  # noqa: PLC0415

    p = PROCEDURAL_DIR / f"procedural-{seed}.ifc"
    if not p.is_file():
        p.parent.mkdir(parents=True, exist_ok=True)
        make_house(procedural_spec(seed), p)
    return str(p)


OPTION_SECTIONS = ("sampler", "settings", "sensor")


def _section(cls, opts: dict, where: str):
    """cls from a ``[render.options.*]`` table (fenestra.config.from_table): unknown keys and bad
    values are reported as ProfileError naming them."""
    from fenestra.config import from_table  # noqa: PLC0415

    return from_table(cls, opts, where, ProfileError)


def dataset_config(profile: Profile, house: str, renders_dir: Path):
    """renders.dataset.DatasetConfig for one house of a profile, rendering under ``renders_dir``.

    ``[render.options.sampler|settings|sensor]`` tables of the profile go to SamplerConfig,
    RenderSettings and SensorConfig; width/height always come from ``[render]``.
    """
    from renders.base import RenderSettings  # noqa: PLC0415
    from renders.dataset import DatasetConfig  # noqa: PLC0415
    from renders.sampler import SamplerConfig  # noqa: PLC0415
    from renders.sensor import SensorConfig  # noqa: PLC0415

    opts = dict(profile.render.options)
    unknown = sorted(set(opts) - set(OPTION_SECTIONS))
    if unknown:
        raise ProfileError(f"profile {profile.name!r} [render.options]: unknown table(s) {unknown}; "
                           f"allowed: {list(OPTION_SECTIONS)}")
    where = f"profile {profile.name!r} [render.options.%s]"
    sampler = {**opts.get("sampler", {}), "width": profile.render.width, "height": profile.render.height}
    return DatasetConfig(scene=house_path(house), n_views=profile.render.views_per_house,
                         seed=profile.seed, renderer=profile.render.renderer,
                         sampler=_section(SamplerConfig, sampler, where % "sampler"),
                         settings=_section(RenderSettings, opts.get("settings", {}), where % "settings"),
                         sensor=_section(SensorConfig, opts.get("sensor", {}), where % "sensor"),
                         out_root=str(renders_dir))
