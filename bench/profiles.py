"""Benchmark profiles: data (``bench/profiles/<name>.toml``) loaded into frozen dataclasses.

A profile names what to render (houses, views, renderer), which methods to run (detectors x
snappers x pose solvers) and which ground-truth windows count as evaluable. Unknown keys and bad
values raise :class:`ProfileError` naming the file, the key and the value.

    [scenes]      houses = ["all"] | [names], procedural = N, procedural_seed = S
    [render]      renderer, views_per_house, width, height, options = {...}  (options go to renders/)
    [methods]     detectors, snappers, pose_solvers (lists; ["all"] = every registered one), height_m
    [evaluation]  min_visible_fraction, require_corners_in_frame, min_window_px, max_incidence_deg
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from fenestra.config import read_toml
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


@dataclass(frozen=True)
class MethodsSpec:
    """Method combinations: every detector x snapper x pose solver; ["all"] = every registered."""

    detectors: tuple[str, ...] = ("oracle",)
    snappers: tuple[str, ...] = (ALL,)
    pose_solvers: tuple[str, ...] = (ALL,)
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
        d = self.to_dict()
        d.pop("name"), d.pop("description")
        return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:8]


_SECTIONS = {"scenes": ScenesSpec, "render": RenderSpec, "methods": MethodsSpec,
             "evaluation": EvalSpec}


def _check_type(where: str, key: str, value: Any, default: Any) -> Any:
    """Coerce a TOML value to the type of the field's default; ProfileError naming key/value."""
    if isinstance(default, bool):
        ok = isinstance(value, bool)
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        value = float(value) if ok else value
    elif isinstance(default, str):
        ok = isinstance(value, str)
    elif isinstance(default, tuple) and key == "options":
        ok = isinstance(value, dict)
        value = tuple(sorted(value.items())) if ok else value
    elif isinstance(default, tuple):
        ok = isinstance(value, list) and all(isinstance(v, str) for v in value) and value
        value = tuple(value) if ok else value
    else:  # pragma: no cover - every field has one of the types above
        ok = True
    if not ok:
        raise ProfileError(f"{where}: key '{key}' has bad value {value!r} "
                           f"(expected {type(default).__name__}{' of strings' if isinstance(default, tuple) and key != 'options' else ''})")
    return value


def _build(cls: type, table: dict, where: str) -> Any:
    """Dataclass ``cls`` from a TOML table, rejecting unknown keys."""
    if not isinstance(table, dict):
        raise ProfileError(f"{where} must be a table, got {table!r}")
    defaults = cls()
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(table) - names)
    if unknown:
        raise ProfileError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(names)}")
    return cls(**{k: _check_type(where, k, v, getattr(defaults, k)) for k, v in table.items()})


def _validate(p: Profile, where: str) -> None:
    """Range checks, each naming the key and the bad value."""
    if not math.isfinite(p.evaluation.min_window_px):
        raise ProfileError(f"{where}: evaluation.min_window_px = {p.evaluation.min_window_px!r} would leave no "
                           "window large enough to evaluate; give a finite size in px")
    checks = [
        ("render.views_per_house", p.render.views_per_house, p.render.views_per_house >= 1),
        ("render.width", p.render.width, p.render.width >= 16),
        ("render.height", p.render.height, p.render.height >= 16),
        ("render.renderer", p.render.renderer, p.render.renderer in ("pyrender", "mitsuba")),
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
    top = {"name", "description", "seed", *_SECTIONS}
    unknown = sorted(set(data) - top)
    if unknown:
        raise ProfileError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(top)}")
    if not isinstance(data.get("name"), str) or not data["name"]:
        raise ProfileError(f"{where}: 'name' must be a non-empty string, got {data.get('name')!r}")
    seed = data.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool):
        raise ProfileError(f"{where}: key 'seed' has bad value {seed!r} (expected int)")
    kw = {s: _build(cls, data.get(s, {}), f"{where} [{s}]") for s, cls in _SECTIONS.items()}
    p = Profile(name=data["name"], description=str(data.get("description", "")), seed=seed, **kw)
    _validate(p, where)
    return p


def available_profiles() -> list[str]:
    """Names of the bundled profiles (bench/profiles/*.toml)."""
    return sorted(p.stem for p in PROFILE_DIR.glob("*.toml"))


def load_profile(name_or_path: str | Path) -> Profile:
    """A bundled profile by name (``smoke``) or any TOML file by path."""
    p = Path(name_or_path)
    if not p.suffix:
        p = PROFILE_DIR / f"{name_or_path}.toml"
        if not p.is_file():
            raise ProfileError(f"unknown profile {str(name_or_path)!r}; bundled: {available_profiles()}")
    return profile_from_dict(read_toml(p, ProfileError, "profile file"), where=str(p))
