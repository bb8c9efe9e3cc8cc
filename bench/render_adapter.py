"""The bridge from a benchmark profile to renders/ and scenes/: house files and dataset configs.

Kept in one module so that changes to the renders/ config dataclasses touch only this file.
"""
from __future__ import annotations

from pathlib import Path

from bench.profiles import Profile

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


def dataset_config(profile: Profile, house: str, index: int, out: Path):
    """The renders/ dataset config for one house of a profile, writing into ``out``."""
    raise NotImplementedError("renders.dataset is not available yet")
