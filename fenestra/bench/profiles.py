"""Benchmark profiles: data (``fenestra/bench/profiles/<name>.toml``) loaded into frozen dataclasses.

A profile names what to render (houses, views, renderer), which methods to run (detectors x
snappers x pose solvers) and which ground-truth windows count as evaluable. Unknown keys and bad
values raise :class:`ProfileError` naming the file, the key and the value.

    [scenes]      houses = ["all"] | [names], procedural = N, procedural_seed = S
    [render]      renderer, views_per_house, width, height, options = {...}  (options go to renders/)
    [methods]     detectors, snappers, pose_solvers: names, ["all"] or {capability = value};
                  withhold_K = [false] | [true] | [false, true]; height_m
                  or, instead of the four selectors, [[methods.grids]] tables (question, detectors,
                  snappers, pose_solvers, withhold_K): the union of their cross products
                  (:func:`planned_methods`); a name "@cli" / "@paper" in a selector stands for the
                  entry of fenestra.conventions.DEFAULTS / PAPER (no profile types a default's name)
    [evaluation]  min_visible_fraction, require_corners_in_frame, min_window_px, max_incidence_deg

Tables become the dataclasses below through ``fenestra.config.from_table``. Names are checked
against the registries, not against lists kept here: ``render.renderer`` against
``renders.backends.RENDERERS``, ``[methods]`` against ``pipeline.detectors.DETECTORS``,
``pipeline.snappers.SNAPPERS`` and ``pipeline.reconstruct.POSES`` (so a newly registered strategy is
accepted, and ``["all"]`` or a capability table that it matches runs it, with no edit here).
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fenestra.config import from_table, read_toml
from fenestra.conventions import DEFAULTS, LIMITS, PAPER
from fenestra.errors import FenestraError
from fenestra.methods import Method
from fenestra.pipeline.detectors import DETECTORS
from fenestra.pipeline.snappers import SNAPPERS
from fenestra.renders.backends import RENDERERS
from fenestra.scenes.registry import BUNDLED

if TYPE_CHECKING:
    from fenestra.bench.real.profile import Datasets

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
# selector names standing for a field of fenestra.conventions.DEFAULTS (the CLI's method) or PAPER
CLI_TOKEN, PAPER_TOKEN = "@cli", "@paper"
SELECTOR_FIELD = {"detectors": "detector", "snappers": "snapper", "pose_solvers": "pose"}


@dataclass(frozen=True)
class Grid:
    """One cross product of a profile's methods (a ``[[methods.grids]]`` table) and the question it
    answers; a profile runs the union of its grids."""

    question: str = ""
    detectors: Selector = (ALL,)
    snappers: Selector = (ALL,)
    pose_solvers: Selector = (ALL,)
    withhold_K: tuple[bool, ...] = (False,)


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
    grids: tuple[Grid, ...] = ()  # when given: the union of these instead of the selectors above


@dataclass(frozen=True)
class EvalSpec:
    """Which ground-truth windows are evaluable (others keep a row with a ``reason``)."""

    min_visible_fraction: float = 0.9
    require_corners_in_frame: bool = True
    min_window_px: float = 12.0  # shortest projected side of the window, px
    max_incidence_deg: float = 80.0


@dataclass(frozen=True)
class Renders:
    """A profile's views when it renders them: which houses (``scenes``), how they are rendered
    (``render``) and which of their windows are evaluable (``evaluation``); each view has exact
    truth (pose, corners, sizes)."""

    scenes: ScenesSpec = field(default_factory=ScenesSpec)
    render: RenderSpec = field(default_factory=RenderSpec)
    evaluation: EvalSpec = field(default_factory=EvalSpec)

    def to_dict(self) -> dict:
        """Its sections as plain JSON-able dicts (render options as a dict)."""
        d = asdict(self)
        d["render"]["options"] = dict(self.render.options)
        return d


@dataclass(frozen=True)
class Profile:
    """One benchmark profile: its name, what its views are (``source``: :class:`Renders`, or
    bench.real.profile.Datasets, labelled photos read by the dataset adapters) and the methods run
    on them. The same type for both kinds; the runner routes on the source (bench.runner).
    See the module docstring for a rendering profile's TOML, bench.real.profile for a dataset one."""

    name: str
    source: Renders | Datasets = field(default_factory=Renders)
    description: str = ""
    seed: int = 0
    methods: MethodsSpec = field(default_factory=MethodsSpec)

    @property
    def photos(self) -> bool:
        """Whether its views are labelled photos (a Datasets source), not renders."""
        return not isinstance(self.source, Renders)

    def to_dict(self) -> dict:
        """Plain JSON-able dict: name, description, seed, methods and the source's sections, at
        the top level as in the profile's TOML."""
        return {"name": self.name, "description": self.description, "seed": self.seed,
                "methods": asdict(self.methods), **self.source.to_dict()}

    def config_hash(self) -> str:
        """8 hex digits identifying everything that changes results (not name/description)."""
        return config_hash(self.to_dict())


@dataclass(frozen=True)
class _RenderProfileTable:
    """A rendering profile's TOML as it reads (from_table's schema; :func:`profile_from_dict`)."""

    name: str
    description: str = ""
    seed: int = 0
    scenes: ScenesSpec = field(default_factory=ScenesSpec)
    render: RenderSpec = field(default_factory=RenderSpec)
    methods: MethodsSpec = field(default_factory=MethodsSpec)
    evaluation: EvalSpec = field(default_factory=EvalSpec)


def config_hash(config: dict) -> str:
    """8 hex digits of a profile's plain dict (``to_dict()``) without its ``name`` and
    ``description``: everything that changes results. Every kind of profile hashes with this."""
    d = {k: v for k, v in config.items() if k not in ("name", "description")}
    if isinstance(d.get("methods"), dict) and not d["methods"].get("grids", True):  # no grids: hashes as before them
        d["methods"] = {k: v for k, v in d["methods"].items() if k != "grids"}
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:8]


def method_registries() -> dict[str, Any]:
    """The registry each ``[methods]`` selector chooses entries of."""
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415 (fenestra.pipeline.reconstruct loads SciPy: imported when first used)

    return {"detectors": DETECTORS, "snappers": SNAPPERS, "pose_solvers": POSES}


def _resolve(selector: Selector, key: str) -> Selector:
    """A selector with "@cli" / "@paper" replaced by DEFAULTS' / PAPER's entry for ``key``."""
    if isinstance(selector, dict):
        return selector

    method = {CLI_TOKEN: DEFAULTS, PAPER_TOKEN: PAPER}
    names = (selector,) if isinstance(selector, str) else tuple(selector)
    return tuple(getattr(method[n], SELECTOR_FIELD[key]) if n in method else n for n in names)


def _select(selector: Selector, key: str) -> list[str]:
    try:
        return method_registries()[key].select(_resolve(selector, key))
    except ValueError as e:  # an unknown name or capability, or an empty list
        raise ProfileError(f"methods.{key}: {e}") from e


def selected(methods: MethodsSpec | Grid, key: str) -> list[str]:
    """The names ``methods.<key>`` selects (fenestra.registry.Registry.select, "@cli"/"@paper"
    resolved); for a spec with grids, the union over its grids in the registry's order. ProfileError naming
    the key, the bad value and the choices."""
    grids = getattr(methods, "grids", ())
    if grids:
        union = {n for g in grids for n in _select(getattr(g, key), key)}
        return [n for n in method_registries()[key] if n in union]  # in the registry's order
    return _select(getattr(methods, key), key)


def _conditions(poses: list[str], withhold_K: tuple[bool, ...]) -> list[tuple[str, bool]]:
    """(pose, withhold_K) pairs: K withheld only from the strategies that fit the focal length."""
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415 (fenestra.pipeline.reconstruct loads SciPy: imported when first used)

    return [(p, wk) for wk in withhold_K for p in poses if not wk or POSES[p].fits_focal]


def planned_methods(methods: MethodsSpec, detectors: list[str] | None = None) -> tuple[Method, ...]:
    """The methods a ``[methods]`` spec runs, for ``detectors`` (the available ones; default: every
    selected one): detector x snapper x pose x K condition, or with grids the union of each grid's
    cross product. Order: detector, snapper, then the K-given poses and the K-withheld ones (a
    designed profile's methods are a subsequence of its full cross product's)."""
    dets = selected(methods, "detectors") if detectors is None else list(detectors)
    grids = methods.grids or (methods,)
    wanted = {Method(d, s, p, withhold_K=wk) for g in grids for d in selected(g, "detectors") if d in dets
              for s in selected(g, "snappers") for p, wk in _conditions(selected(g, "pose_solvers"), g.withhold_K)}
    withhold = tuple(dict.fromkeys(wk for g in grids for wk in sorted(g.withhold_K)))
    return tuple(m for m in (Method(d, s, p, withhold_K=wk) for d, s, (p, wk) in itertools.product(
        dets, selected(methods, "snappers"), _conditions(selected(methods, "pose_solvers"), withhold))) if m in wanted)


def _check_withhold(withhold_K: tuple[bool, ...], where: str) -> None:
    if not withhold_K or len(set(withhold_K)) != len(withhold_K):
        raise ProfileError(f"{where}: methods.withhold_K must be [false], [true] or [false, true], got {list(withhold_K)}")


def check_methods(methods: MethodsSpec, where: str) -> None:
    """Every ``[methods]`` selector (each grid's) chooses registered entries, at least one, and
    withhold_K is a non-empty list of distinct bools; ProfileError naming the key, the bad value
    and the choices."""
    for i, g in enumerate(methods.grids or (methods,)):
        at = f"{where}: methods.grid[{i}]" if methods.grids else where
        for key in method_registries():
            try:
                names = selected(g, key)
            except ProfileError as e:
                raise ProfileError(f"{at}: {e}") from e
            if not names:
                raise ProfileError(f"{at}: methods.{key} = {getattr(g, key)!r} selects nothing")
        _check_withhold(g.withhold_K, at)


def _validate(p: _RenderProfileTable, where: str) -> None:
    """Range checks and registry names, each naming the key and the bad value."""

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
    _check_counts(p, where)


def _check_counts(p: _RenderProfileTable, where: str) -> None:
    """The profile's counts within fenestra.conventions.LIMITS (procedural houses, views per house,
    views in all); ProfileError naming the key, its value and the bound."""

    LIMITS.check("max_procedural_houses", p.scenes.procedural, f"{where}: scenes.procedural", ProfileError)
    LIMITS.check("max_views_per_dataset", p.render.views_per_house, f"{where}: render.views_per_house", ProfileError)
    n_houses = (len(BUNDLED) if p.scenes.houses == (ALL,) else len(p.scenes.houses)) + p.scenes.procedural
    LIMITS.check("max_views_per_run", n_houses * p.render.views_per_house,
                 f"{where}: houses x render.views_per_house ({n_houses} x {p.render.views_per_house})", ProfileError)


def profile_from_dict(data: dict, where: str = "profile") -> Profile:
    """A rendering Profile from a parsed TOML dict (top-level: name, description, seed and the
    sections); ProfileError naming the file, the key and the bad value."""
    m = data.get("methods")
    both = sorted(k for k in ("detectors", "snappers", "pose_solvers", "withhold_K") if k in m) \
        if isinstance(m, dict) and m.get("grids") else []
    if both:
        raise ProfileError(f"{where}: [methods] has [[methods.grids]] and also {both}: give the selectors in each grid")
    t = from_table(_RenderProfileTable, data, where, ProfileError)
    _validate(t, where)
    return Profile(t.name, Renders(t.scenes, t.render, t.evaluation), t.description, t.seed, t.methods)


def available_profiles() -> list[str]:
    """Names of the bundled profiles (fenestra/bench/profiles/*.toml)."""
    return sorted(p.stem for p in PROFILE_DIR.glob("*.toml"))


def load_profile(name_or_path: str | Path) -> Profile:
    """A bundled profile by name (``smoke``, ``real``) or any TOML file by path, of either kind:
    ``kind = "real"`` reads labelled datasets (bench.real.profile.real_profile_from_dict), else
    it renders (:func:`profile_from_dict`)."""
    p = Path(name_or_path)
    if not p.suffix:
        p = PROFILE_DIR / f"{name_or_path}.toml"
        if not p.is_file():
            raise ProfileError(f"unknown profile {str(name_or_path)!r}; bundled: {available_profiles()}")
    data = read_toml(p, ProfileError, "profile file")
    if data.get("kind") == "real":
        from fenestra.bench.real.profile import real_profile_from_dict  # noqa: PLC0415 - it imports this module

        return real_profile_from_dict(data, where=str(p))
    return profile_from_dict(data, where=str(p))
