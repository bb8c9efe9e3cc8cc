"""One registry type for every pluggable stage: name -> entry, lookups that name the choices,
selection by capability, ``--help`` text, and plug-ins from other installed packages.

    SNAPPERS = Registry("snapper", [NONE, HARRIS, ...])     # entries carry .name and .description
    SNAPPERS["lsd"]                       # UnknownName (a KeyError and a ValueError) naming the choices
    SNAPPERS.select("all")                # names of the entries with in_all (the default) True
    POSES.select({"per_wall": False})     # names of the entries that declare per_wall False
    SNAPPERS.describe()                   # "none: ...; harris: ..." for CLI help
    SNAPPERS.register(MY_SNAPPER)         # at run time, or from a plug-in (below)

An entry is any object with ``name`` and ``description`` (:class:`Entry`); what it can do is read
from its attributes named in :data:`CAPABILITIES` (an entry that lacks one has the default there).
Nothing outside the registries keeps a list of names: profiles, gates, reports and the CLI select
entries by name, by ``"all"`` or by capability, never by a hard-coded name.

Plug-ins: a package declares entry points in the group ``fenestra.plugins`` (pyproject.toml
``[project.entry-points."fenestra.plugins"] myname = "my_module"``). The first time any registry
is read, every such entry point is loaded (imported; an entry point naming a callable is then
called with no arguments) and registers its entries with ``REGISTRY.register(entry)``. A plug-in
replaces an entry already registered (a built-in) only when that entry says ``override = True``
(an attribute), and :func:`plugin_metadata` (recorded in a bench run's summary.json) names it.
A plug-in that fails to load (any exception, ``sys.exit`` during its import, a refused name) is
undone and named in one warning line; Fenestra goes on without it.
"""
from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator, Mapping, MutableMapping
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any, Generic, Protocol, TypeVar, runtime_checkable

from fenestra.errors import FenestraError, bounded

ALL = "all"
PLUGIN_GROUP = "fenestra.plugins"

# capability -> the value an entry that does not declare it has
CAPABILITIES: dict[str, Any] = {
    "in_all": True,  # part of a profile's "all" (False: e.g. a detector whose weights are not shipped)
    "needs_instances": False,  # a detector that reads the ground-truth instance map (the oracles)
    "trainable": False,  # a detector with a training recipe (fenestra/training/recipes/<arch>.py)
    "per_wall": False,  # a pose strategy that fits each wall once (False: each window on its own)
    "fits_focal": False,  # a pose strategy that fits the focal length itself: benchmarked with K withheld too
}


@runtime_checkable
class Entry(Protocol):
    """What every registry entry carries: its registry key and a one-line description (CLI help,
    docs). Capabilities are further attributes (:data:`CAPABILITIES`)."""

    name: str
    description: str


E = TypeVar("E")


class UnknownName(FenestraError, KeyError, ValueError):
    """A name that is not registered; the message names it and the choices."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


def capabilities(entry: object) -> dict[str, Any]:
    """{capability: value} of an entry (the defaults of :data:`CAPABILITIES` where it declares none)."""
    return {c: getattr(entry, c, default) for c, default in CAPABILITIES.items()}


@dataclass
class _Plugins:
    """Whether the ``fenestra.plugins`` entry points were loaded (once per process), which
    loaded, which failed (name -> reason), the one loading now, and which registry entries a
    plug-in replaced ("kind name" -> plug-in)."""

    loaded: bool = False
    names: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    current: str | None = None
    overrides: dict[str, str] = field(default_factory=dict)
    undo: list = field(default_factory=list)  # (registry, name, previous entry or None) of the current plug-in


_PLUGINS = _Plugins()


def _warn(line: str) -> None:
    import sys  # noqa: PLC0415

    print(f"warning: {' '.join(line.split())}", file=sys.stderr)


def _caller() -> str:
    """The module that called the Registry method that calls this."""

    return str(sys._getframe(2).f_globals.get("__name__", ""))


def load_plugins() -> list[str]:
    """Load every ``fenestra.plugins`` entry point once (see the module docstring); returns the
    names of those that loaded. A plug-in that fails (any exception, its own BaseException subclasses
    too, ``sys.exit`` during its import, a name already taken without ``override = True``) is undone
    (what it registered is removed, what it replaced restored) and named in one warning line on
    stderr: every command still works. Ctrl-C while one loads is the user's: raised."""
    if _PLUGINS.loaded:
        return list(_PLUGINS.names)
    _PLUGINS.loaded = True  # before loading: a plug-in reads and registers into the registries

    for ep in entry_points(group=PLUGIN_GROUP):
        _PLUGINS.current, _PLUGINS.undo = ep.name, []
        try:
            obj = ep.load()
            if callable(obj):
                obj()
        except KeyboardInterrupt:  # Ctrl-C while a plug-in loads: the user's, not the plug-in's
            raise
        except BaseException as e:  # noqa: BLE001 - foreign code (its own BaseException subclasses too): named, undone, never fatal
            for reg, name, previous in reversed(_PLUGINS.undo):
                reg._entries.pop(name, None)
                if previous is not None:
                    reg._entries[name] = previous
            _PLUGINS.overrides = {k: v for k, v in _PLUGINS.overrides.items() if v != ep.name}
            why = f"{type(e).__name__}: {bounded(e)}" if not isinstance(e, SystemExit) else f"it called sys.exit({bounded(repr(e.code))})"
            _PLUGINS.failed[ep.name] = why
            _warn(f"fenestra plug-in {ep.name!r} ({ep.value}) failed to load and is ignored: {why}")
            continue
        finally:
            _PLUGINS.current = None
        _PLUGINS.names.append(ep.name)
    return list(_PLUGINS.names)


def plugin_metadata() -> dict:
    """What a run records about plug-ins: {"loaded": [names], "failed": {name: reason},
    "overrides": {"<kind> <entry>": plug-in}} (a built-in a plug-in replaced with override = True)."""
    load_plugins()
    return {"loaded": list(_PLUGINS.names), "failed": dict(_PLUGINS.failed), "overrides": dict(_PLUGINS.overrides)}


class Registry(MutableMapping[str, E], Generic[E]):
    """Name -> entry of one kind (``kind``: "snapper", "detector", ... for messages), in
    registration order (the order of ``--help``, the bench's methods and the reports)."""

    def __init__(self, kind: str, entries: Iterable[E] = ()) -> None:
        self.kind = kind
        self._entries: dict[str, E] = {}
        for e in entries:
            self._add(e, replace=False)

    # -------------------------------------------------------------- registering

    def _add(self, entry: E, replace: bool, caller: str = "fenestra") -> E:
        """Add ``entry``; ``caller``: the module registering it. One outside fenestra registering
        while a plug-in loads is that plug-in: a built-in name needs override = True, and
        what it adds is undone if the plug-in then fails (a built-in that a module of fenestra
        registers while a plug-in imports it is never the plug-in's)."""
        name = getattr(entry, "name", None)
        if not isinstance(name, str) or not name:
            raise ValueError(f"a {self.kind} entry needs a non-empty str name, got {name!r}")
        if not str(getattr(entry, "description", "")).strip():
            raise ValueError(f"{self.kind} {name!r} needs a description (CLI help, docs)")
        taken = name in self._entries
        if taken and not replace:
            raise ValueError(f"{self.kind} {name!r} is already registered; choose another name")
        plugin = _PLUGINS.current if not (caller == "fenestra" or caller.startswith("fenestra.")) else None
        if taken and plugin is not None and getattr(entry, "override", False) is not True:
            raise ValueError(f"{self.kind} {name!r} is already registered; a plug-in replaces it only with an "
                             "explicit override = True on its entry")
        if plugin is not None:
            _PLUGINS.undo.append((self, name, self._entries.get(name)))
            if taken:
                _PLUGINS.overrides[f"{self.kind} {name}"] = plugin
        self._entries[name] = entry
        return entry

    def register(self, entry: E, replace: bool = False) -> E:
        """Add ``entry`` under ``entry.name`` (ValueError if taken, unless ``replace``); returns it."""
        load_plugins()
        return self._add(entry, replace, _caller())

    def unregister(self, name: str) -> E:
        """Remove and return the entry ``name`` (UnknownName if absent)."""
        entry = self[name]
        del self._entries[name]
        return entry

    # -------------------------------------------------------------- the mapping

    def __getitem__(self, name: str) -> E:
        load_plugins()
        try:
            return self._entries[name]
        except (KeyError, TypeError):
            raise UnknownName(f"unknown {self.kind} {name!r}; choose from {list(self._entries)}") from None

    def __setitem__(self, name: str, entry: E) -> None:
        if getattr(entry, "name", None) != name:
            raise ValueError(f"{self.kind} registered as {name!r} must be named so, got {getattr(entry, 'name', None)!r}")
        self._add(entry, replace=True, caller=_caller())

    def __delitem__(self, name: str) -> None:
        self.unregister(name)

    def __iter__(self) -> Iterator[str]:
        load_plugins()
        return iter(list(self._entries))

    def __len__(self) -> int:
        load_plugins()
        return len(self._entries)

    def __contains__(self, name: object) -> bool:
        load_plugins()
        return name in self._entries

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, {list(self._entries)})"

    def snapshot(self) -> list[E]:
        """The entries registered so far, without loading plug-ins: for building one registry from
        another while the modules are still being imported."""
        return list(self._entries.values())

    def lookup(self, name: str) -> E:
        """The entry ``name``; UnknownName (KeyError and ValueError) naming it and the choices."""
        return self[name]

    # -------------------------------------------------------------- selecting

    def where(self, **required: Any) -> list[str]:
        """Names of the entries whose capabilities equal ``required`` (e.g. ``per_wall=False``)."""
        unknown = sorted(set(required) - set(CAPABILITIES))
        if unknown:
            raise ValueError(f"unknown capability {unknown}; known: {list(CAPABILITIES)}")
        return [n for n, e in self.items() if all(capabilities(e)[k] == v for k, v in required.items())]

    def select(self, selector: str | Iterable[str] | Mapping[str, Any] = ALL) -> list[str]:
        """Names chosen by ``selector``: ``"all"`` (or ``["all"]``): every entry with ``in_all``;
        a mapping {capability: value}: those of the ``in_all`` entries that declare it; a list of
        names: those names, each checked (UnknownName naming it and the choices)."""
        if isinstance(selector, Mapping):
            return self.where(**{"in_all": True, **selector})
        names = (selector,) if isinstance(selector, str) else tuple(selector)
        if not names:
            raise ValueError(f"empty {self.kind} selection; give names of {list(self)}, [\"all\"] or a capability table")
        if names == (ALL,):
            return self.where(in_all=True)
        for n in names:
            self.lookup(n)
        return list(dict.fromkeys(names))

    def describe(self) -> str:
        """``"name: description; ..."`` of every entry, for CLI help."""
        return "; ".join(f"{n}: {e.description}" for n, e in self.items())


__all__ = ["ALL", "CAPABILITIES", "PLUGIN_GROUP", "Entry", "Registry", "UnknownName", "capabilities", "load_plugins",
           "plugin_metadata"]
