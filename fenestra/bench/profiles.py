"""Benchmark profiles: data (``fenestra/bench/profiles/<name>.toml``) loaded into frozen dataclasses.

A profile names what to render (houses, views, renderer), which methods to run (detectors x
snappers x pose solvers) and which ground-truth windows count as evaluable. Unknown keys and bad
values raise :class:`ProfileError` naming the file, the key and the value.

    [scenes]      houses = ["all"] | [names], procedural = N, procedural_seed = S
    [render]      renderer, views_per_house, width, height, options = {...}  (options go to renders/)
    [methods]     detectors, snappers, pose_solvers: names, ["all"] or {capability = value};
                  withhold_K = [false] | [true] | [false, true]; height_m
    [evaluation]  min_visible_fraction, require_corners_in_frame, min_window_px, max_incidence_deg

Tables become the dataclasses below through ``fenestra.config.from_table``. Names are checked
against the registries, not against lists kept here: ``render.renderer`` against
``renders.backends.RENDERERS``, ``[methods]`` against ``pipeline.detectors.DETECTORS``,
``pipeline.snappers.SNAPPERS`` and ``pipeline.reconstruct.POSES`` (so a newly registered strategy is
accepted, and ``["all"]`` or a capability table that it matches runs it, with no edit here).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from fenestra.config import from_table, read_toml
from fenestra.errors import FenestraError

PROFILE_DIR = Path(__file__).parent / "profiles"
ALL = "all"


class ProfileError(FenestraError):
    """A profile file that is missing, unreadable or has bad keys/values."""


@dataclass(frozen=True)
class ScenesSpec:
    """Which houses: bundled names (or ["all"]) plus ``procedural`` generated ones."""

    houses: tuple[str, ...] = (ALL,)
    procedural: int = 0
    procedural_seed: int = 0


@dataclass(frozen=True)
class RenderSpec:
    """How to render. ``options`` is passed unchanged to the renders/ dataset config."""

    renderer: str = "pyrender"
    views_per_house: int = 20
    width: int = 640
    height: int = 480
    options: tuple[tuple[str, Any], ...] = ()


Selector = tuple[str, ...] | dict  # names, ["all"], or a capability table {capability = value}


@dataclass(frozen=True)
class MethodsSpec:
    """Method combinations: every detector x snapper x pose strategy x K condition.

    detectors, snappers, pose_solvers: each a list of registered names, ``["all"]`` (every entry
    with ``in_all``) or a capability table such as ``{per_wall = false}`` (fenestra.registry);
    withhold_K: the K conditions to run, ``[false]`` (K given), ``[true]`` or ``[false, true]``;
    K is withheld only from the strategies that fit the focal length (capability ``fits_focal``).
    """

    detectors: Selector = ("oracle",)
    snappers: Selector = (ALL,)
    pose_solvers: Selector = (ALL,)
    withhold_K: tuple[bool, ...] = (False,)
    height_m: float = 1.0  # the pose's scale parameter (errors are rescaled with the true height)


@dataclass(frozen=True)
class EvalSpec:
    """Which ground-truth windows are evaluable (others keep a row with a ``reason``)."""

    min_visible_fraction: float = 0.9
    require_corners_in_frame: bool = True
    min_window_px: float = 12.0  # shortest projected side of the window, px
    max_incidence_deg: float = 80.0


@dataclass(frozen=True)
class Profile:
    """One benchmark profile (see the module docstring for the TOML layout)."""

    name: str
    description: str = ""
    seed: int = 0
    scenes: ScenesSpec = field(default_factory=ScenesSpec)
    render: RenderSpec = field(default_factory=RenderSpec)
    methods: MethodsSpec = field(default_factory=MethodsSpec)
    evaluation: EvalSpec = field(default_factory=EvalSpec)

    def to_dict(self) -> dict:
        """Plain JSON-able dict (options as a dict)."""
        d = asdict(self)
        d["render"]["options"] = dict(self.render.options)
        return d

    def config_hash(self) -> str:
        """8 hex digits identifying everything that changes results (not name/description)."""
        return config_hash(self.to_dict())


def config_hash(config: dict) -> str:
    """8 hex digits of a profile's plain dict (``to_dict()``) without its ``name`` and
    ``description``: everything that changes results. Every kind of profile hashes with this."""
    d = {k: v for k, v in config.items() if k not in ("name", "description")}
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:8]


def method_registries() -> dict[str, Any]:
    """The registry each ``[methods]`` selector chooses entries of."""
    from fenestra.pipeline.detectors import DETECTORS  # noqa: PLC0415
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415
    from fenestra.pipeline.snappers import SNAPPERS  # noqa: PLC0415

    return {"detectors": DETECTORS, "snappers": SNAPPERS, "pose_solvers": POSES}


def selected(methods: MethodsSpec, key: str) -> list[str]:
    """The names ``methods.<key>`` selects (fenestra.registry.Registry.select); ProfileError naming
    the key, the bad value and the choices."""
    registry = method_registries()[key]
    try:
        return registry.select(getattr(methods, key))
    except ValueError as e:  # an unknown name or capability, or an empty list
        raise ProfileError(f"methods.{key}: {e}") from e


def check_methods(methods: MethodsSpec, where: str) -> None:
    """Every ``[methods]`` selector chooses registered entries, at least one, and withhold_K is a
    non-empty list of distinct bools; ProfileError naming the key, the bad value and the choices."""
    for key in method_registries():
        try:
            names = selected(methods, key)
        except ProfileError as e:
            raise ProfileError(f"{where}: {e}") from e
        if not names:
            raise ProfileError(f"{where}: methods.{key} = {getattr(methods, key)!r} selects nothing")
    if not methods.withhold_K or len(set(methods.withhold_K)) != len(methods.withhold_K):
        raise ProfileError(f"{where}: methods.withhold_K must be [false], [true] or [false, true], got "
                           f"{list(methods.withhold_K)}")


def _validate(p: Profile, where: str) -> None:
    """Range checks and registry names, each naming the key and the bad value."""
    from fenestra.renders.backends import RENDERERS  # noqa: PLC0415

    if not p.name:
        raise ProfileError(f"{where}: 'name' must be a non-empty string, got {p.name!r}")
    if p.render.renderer not in RENDERERS:
        raise ProfileError(f"{where}: render.renderer has bad value {p.render.renderer!r}; registered: {list(RENDERERS)}")
    check_methods(p.methods, where)
    if not math.isfinite(p.evaluation.min_window_px):
        raise ProfileError(f"{where}: evaluation.min_window_px = {p.evaluation.min_window_px!r} would leave no "
                           "window large enough to evaluate; give a finite size in px")
    checks = [
        ("render.views_per_house", p.render.views_per_house, p.render.views_per_house >= 1),
        ("render.width", p.render.width, p.render.width >= 16),
        ("render.height", p.render.height, p.render.height >= 16),
        ("scenes.procedural", p.scenes.procedural, p.scenes.procedural >= 0),
        ("methods.height_m", p.methods.height_m, p.methods.height_m > 0),
        ("evaluation.min_visible_fraction", p.evaluation.min_visible_fraction,
         0.0 <= p.evaluation.min_visible_fraction <= 1.0),
        ("evaluation.min_window_px", p.evaluation.min_window_px, p.evaluation.min_window_px >= 0),
        ("evaluation.max_incidence_deg", p.evaluation.max_incidence_deg,
         0.0 < p.evaluation.max_incidence_deg <= 90.0),
    ]
    for key, value, ok in checks:
        if not ok:
            raise ProfileError(f"{where}: {key} has bad value {value!r}")
    if not p.scenes.houses and p.scenes.procedural == 0:
        raise ProfileError(f"{where}: no houses: scenes.houses is empty and scenes.procedural = 0")


def profile_from_dict(data: dict, where: str = "profile") -> Profile:
    """Profile from a parsed TOML dict (top-level: name, description, seed and the sections)."""
    p = from_table(Profile, data, where, ProfileError)
    _validate(p, where)
    return p


def available_profiles() -> list[str]:
    """Names of the bundled profiles (fenestra/bench/profiles/*.toml)."""
    return sorted(p.stem for p in PROFILE_DIR.glob("*.toml"))


def load_profile(name_or_path: str | Path) -> Profile:
    """A bundled profile by name (``smoke``) or any TOML file by path."""
    p = Path(name_or_path)
    if not p.suffix:
        p = PROFILE_DIR / f"{name_or_path}.toml"
        if not p.is_file():
            raise ProfileError(f"unknown profile {str(name_or_path)!r}; bundled: {available_profiles()}")
    return profile_from_dict(read_toml(p, ProfileError, "profile file"), where=str(p))
