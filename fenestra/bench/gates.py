"""Accuracy gates: floors and ceilings on a run's summary numbers (``fenestra/bench/gates.toml``).

    [[gate]]
    profile = "smoke"                       # applies to runs of this profile
    method = "oracle/*/*"                   # fnmatch pattern over method labels (detector/snapper/pose)
    pose = { per_wall = false }             # optional: capabilities the pose strategy must have
    metric = "corner_err_px_snap.median"    # dotted path into summary.json results[method]
    max = 1.0                               # and/or min = ...

Every method matching the pattern (and, where given, whose detector / snapper / pose strategy has
the capabilities of the ``detector`` / ``snapper`` / ``pose`` table: fenestra.registry) must satisfy
the bound; so a new per-window solver is gated by ``pose = { per_wall = false }`` with no edit here.
A NaN/missing value, or a selection that matches no method of the run, is a violation too: a
gate never passes by finding nothing.
"""
from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fenestra.bench.manifest import load_verified_results, require_complete
from fenestra.bench.results import load_summary, summarize
from fenestra.config import read_toml
from fenestra.errors import FenestraError
from fenestra.methods import Method, read_methods
from fenestra.registry import CAPABILITIES
from fenestra.pipeline.detectors import DETECTORS
from fenestra.pipeline.snappers import SNAPPERS

DEFAULT_GATES = Path(__file__).parent / "gates.toml"


class GateError(FenestraError):
    """A gates file that is missing or malformed."""


@dataclass(frozen=True)
class Gate:
    """One bound on one metric for the methods matching ``method`` in runs of ``profile``."""

    profile: str
    method: str
    metric: str
    min: float | None = None
    max: float | None = None
    detector: tuple[tuple[str, Any], ...] = ()  # required capabilities, as sorted (name, value) pairs
    snapper: tuple[tuple[str, Any], ...] = ()
    pose: tuple[tuple[str, Any], ...] = ()

    def selects(self, label: str, method: Method) -> bool:
        """Whether this gate bounds the method ``label`` (its pattern and capability tables)."""
        return fnmatch.fnmatchcase(label, self.method) and all(
            getattr(method, stage) in registry.where(**dict(required))
            for stage, registry, required in zip(CAPABILITY_KEYS, stage_registries(), (self.detector, self.snapper, self.pose))
            if required)

    def describe(self) -> str:
        """The selection in words, for a violation that found no method."""
        caps = [f"{k} {dict(v)}" for k, v in zip(CAPABILITY_KEYS, (self.detector, self.snapper, self.pose)) if v]
        return f"a method matching {self.method!r}" + (f" with {', '.join(caps)}" if caps else "")


CAPABILITY_KEYS = ("detector", "snapper", "pose")


def stage_registries() -> tuple:
    """The registries whose capabilities a gate's ``detector``, ``snapper`` and ``pose`` tables test."""
    from fenestra.pipeline.reconstruct import POSES  # noqa: PLC0415 (fenestra.pipeline.reconstruct loads SciPy: imported when first used)

    return DETECTORS, SNAPPERS, POSES


@dataclass(frozen=True)
class Violation:
    """A gate that failed: the method, the metric, its value and the bound it broke."""

    profile: str
    method: str
    metric: str
    value: float | None
    bound: str  # e.g. "<= 1.0", ">= 0.9", "a method matching 'x/*/*'"

    def __str__(self) -> str:
        v = "missing" if self.value is None or not math.isfinite(self.value) else f"{self.value:.4g}"
        return f"{self.method}: {self.metric} = {v}, bound {self.bound} (profile {self.profile})"


def load_gates(path: str | Path = DEFAULT_GATES) -> list[Gate]:
    """Gates from a TOML file of [[gate]] tables; GateError naming the bad entry or key."""
    p = Path(path)
    data = read_toml(p, GateError, "gates file")
    extra = sorted(set(data) - {"gate"})
    if extra:
        raise GateError(f"{p}: unknown top-level key(s) {extra}; use [[gate]] tables")
    gates = []
    allowed = {"profile", "method", "metric", "min", "max", *CAPABILITY_KEYS}
    for i, g in enumerate(data.get("gate", [])):
        bad = sorted(set(g) - allowed)
        if bad:
            raise GateError(f"{p}: gate #{i + 1} has unknown key(s) {bad}; allowed {sorted(allowed)}")
        for k in ("profile", "method", "metric"):
            if not isinstance(g.get(k), str) or not g[k]:
                raise GateError(f"{p}: gate #{i + 1} needs a string '{k}', got {g.get(k)!r}")
        for k in ("min", "max"):
            if k in g and (isinstance(g[k], bool) or not isinstance(g[k], (int, float))):
                raise GateError(f"{p}: gate #{i + 1} key '{k}' must be a number, got {g[k]!r}")
            if k in g and not math.isfinite(g[k]):  # inf / -inf / nan would pass (or fail) vacuously
                raise GateError(f"{p}: gate #{i + 1} ({g['metric']}) has {k} = {g[k]!r}; a bound must be finite")
        if "min" not in g and "max" not in g:
            raise GateError(f"{p}: gate #{i + 1} ({g['metric']}) has neither 'min' nor 'max'")
        caps = {}
        for k in CAPABILITY_KEYS:
            table = g.get(k, {})
            if not isinstance(table, dict) or sorted(set(table) - set(CAPABILITIES)):
                raise GateError(f"{p}: gate #{i + 1} key '{k}' must be a table of capabilities "
                                f"{list(CAPABILITIES)}, got {table!r}")
            caps[k] = tuple(sorted(table.items()))
        gates.append(Gate(g["profile"], g["method"], g["metric"],
                          float(g["min"]) if "min" in g else None,
                          float(g["max"]) if "max" in g else None, **caps))
    return gates


def metric_value(method_summary: dict, metric: str) -> float | None:
    """Value at a dotted path ("corner_err_px_snap.recall.2") of one method's summary; None if absent."""
    v = method_summary
    for part in metric.split("."):
        if not isinstance(v, dict) or part not in v:
            return None
        v = v[part]
    return None if v is None or isinstance(v, dict) else float(v)


def check_results(results: dict, profile: str, gates: list[Gate]) -> list[Violation]:
    """Violations of ``gates`` (those for ``profile``) by a summary's results {method: {...}}."""
    out = []
    typed = read_methods(results)
    for g in (g for g in gates if g.profile == profile):
        methods = [m for m in results if g.selects(m, typed[m])]
        if not methods:
            out.append(Violation(profile, g.method, g.metric, None, g.describe()))
        for m in methods:
            v = metric_value(results[m], g.metric)
            finite = v is not None and math.isfinite(v)
            if g.min is not None and not (finite and v >= g.min):
                out.append(Violation(profile, m, g.metric, v, f">= {g.min:g}"))
            if g.max is not None and not (finite and v <= g.max):
                out.append(Violation(profile, m, g.metric, v, f"<= {g.max:g}"))
    return out


def check(run_dir: str | Path, gates: list[Gate] | str | Path = DEFAULT_GATES,
          profile: str | None = None) -> list[Violation]:
    """Violations of a run folder: its results table (checked against the run's manifest, see
    bench.manifest) re-summarised, its profile from summary.json.

    ``profile`` overrides the run's profile name (e.g. to gate a custom run against smoke bounds).
    A run whose run.json is not ``complete`` (failed, interrupted, still running) is refused
    (bench.manifest.require_complete).
    """
    if not isinstance(gates, list):
        gates = load_gates(gates)
    run_dir = Path(run_dir)
    require_complete(run_dir)
    if profile is None:
        profile = load_summary(run_dir)["metadata"].get("profile")
    if not any(g.profile == profile for g in gates):
        raise GateError(f"no gates for profile {profile!r}; gated profiles: {sorted({g.profile for g in gates})}")
    return check_results(summarize(load_verified_results(run_dir)), profile, gates)


# ---------------------------------------------------------------- suggesting gates from a run

# (metric, "max" | "min", absolute slack): ceilings on errors are measured * (1 + margin) + slack;
# ceilings on rates are measured + slack; floors are measured - slack (rates clipped to [0, 1]).
GROUP_METRICS = (
    ("detection_rate", "min", 0.05), ("failure_rate", "max", 0.1),
    ("corner_err_px_mask.median", "max", 0.1), ("corner_err_px_snap.median", "max", 0.1),
    ("corner_err_px_snap.p90", "max", 0.2), ("corner_err_px_snap.recall.2", "min", 0.1),
)
METHOD_METRICS = (
    ("corner_err_px_snap.median", "max", 0.1), ("corner_err_px_snap.recall.2", "min", 0.1),
    ("aspect_err_rel.p90", "max", 0.01), ("rot_err_deg.median", "max", 0.25),
)


def _bound(kind: str, values: list[float], margin: float, slack: float, rate: bool) -> float | None:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    if not vals:
        return None
    if kind == "max":
        return min(max(vals) + slack, 1.0) if rate else max(vals) * (1.0 + margin) + slack
    return max(min(vals) - slack, 0.0)


def run_profile(run_dir: str | Path) -> str | None:
    """The profile name a run folder's summary.json records."""
    return load_summary(run_dir)["metadata"].get("profile")


def suggest_gates(runs: dict | list[dict], profile: str, margin: float = 0.5) -> str:
    """gates.toml text from the results of one run or of several (e.g. seeds: the worst run sets
    each bound): per detector ("det/*/*", worst snapper) and per detector x snapper
    ("det/snapper/*", worst pose), measured values and margin in comments."""
    runs = [runs] if isinstance(runs, dict) else list(runs)
    groups: dict[str, list[tuple[int, str]]] = {}
    for i, results in enumerate(runs):
        for m, method in read_methods(results).items():
            groups.setdefault(f"{method.detector}/*/*", []).append((i, m))
            groups.setdefault(f"{method.detector}/{method.snapper}/*", []).append((i, m))
    lines = [f"# Accuracy gates, suggested from measured {profile!r} numbers"
             + (f" ({len(runs)} runs, the worst sets each bound)" if len(runs) > 1 else "") + f" with margin {margin:.0%}:",
             "# error ceilings = worst measured * (1 + margin) + slack; rate ceilings = worst + slack;",
             "# floors = worst measured - slack (slacks: fenestra/bench/gates.py GROUP_METRICS, METHOD_METRICS).",
             "# 'det/*/*' bounds every snapper of a detector (so a new or broken snapper is gated too)."]
    for pattern, methods in sorted(groups.items(), key=lambda kv: (kv[0].count("*") != 2, kv[0])):
        for metric, kind, slack in (GROUP_METRICS if pattern.endswith("/*/*") else METHOD_METRICS):
            vals = [metric_value(runs[i][m], metric) for i, m in methods]
            b = _bound(kind, vals, margin, slack, rate=metric.endswith("rate") or ".recall." in metric)
            if b is None:
                continue
            fin = [v for v in vals if v is not None and math.isfinite(v)]
            lines += ["", "[[gate]]", f"# measured over {len({m for _, m in methods})} method(s): "
                      f"{min(fin):.4g} .. {max(fin):.4g}",
                      f'profile = "{profile}"', f'method = "{pattern}"', f'metric = "{metric}"',
                      f"{kind} = {b:.4g}"]
    return "\n".join(lines) + "\n"
