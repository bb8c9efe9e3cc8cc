"""Reading the project's TOML files (bench profiles, gates, training configs) with clear errors.

    data = read_toml("fenestra/bench/profiles/smoke.toml", ProfileError, "profile file")
    spec = from_table(RenderSpec, data["render"], where="smoke.toml [render]", error=ProfileError)

:func:`from_table` is the one TOML-table -> frozen-dataclass conversion: every config dataclass
read from a file (bench profiles, render options, training configs) goes through it, so unknown
keys, wrong types and lists-for-tuples are handled the same way everywhere.
"""
from __future__ import annotations

import dataclasses
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")


def read_toml(path: str | Path, error: type[Exception] = ValueError, what: str = "file") -> dict:
    """Parse a TOML file into a dict.

    Raises ``error`` naming the path when the file is missing, unreadable, binary (not UTF-8) or
    not valid TOML; ``what`` names the kind of file in the message (e.g. "profile file").
    """
    p = Path(path)
    if not p.is_file():
        raise error(f"{what} {p} does not exist")
    try:
        return tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise error(f"{p}: not valid TOML: {e}") from e
    except UnicodeDecodeError as e:  # a binary file: TOML is UTF-8 text
        raise error(f"{p}: not a TOML {what} (not UTF-8 text: byte {e.object[e.start]:#04x} at offset {e.start})") from e
    except OSError as e:
        raise error(f"{p}: cannot read the {what}: {e.strerror or e}") from e


def choices(registry: dict) -> str:
    """``"name: description; ..."`` of a registry's entries, for CLI help generated from the registry
    (an entry's ``description`` attribute, or the entry itself when it is a string; else the name alone)."""
    def one(name: str, entry: Any) -> str:
        d = entry if isinstance(entry, str) else getattr(entry, "description", "")
        return f"{name}: {d}" if d else name
    return "; ".join(one(n, e) for n, e in registry.items())


def from_table(cls: type[T], table: Any, where: str = "table", error: type[Exception] = ValueError) -> T:
    """The frozen dataclass ``cls`` from a TOML table (a dict), checked against its field types.

    - a key that is not a field raises ``error`` naming it and the allowed keys; a missing key
      takes the field's default (a field without one must be given);
    - values are checked against the field annotations: ``bool``, ``int``, ``float`` (an int is
      accepted and converted), ``str``, ``X | None`` (as X: TOML has no null), ``tuple[X, ...]``
      and ``tuple[X, Y]`` (from a list, item by item), a nested dataclass (from a sub-table,
      recursively), ``tuple[tuple[str, Any], ...]`` (a table of options, stored as sorted
      (key, value) pairs with the values as parsed), ``dict`` and ``Any`` (as parsed);
    - the dataclass's own checks (``__post_init__`` ValueError/TypeError) are re-raised as ``error``.

    where: names the table in messages (e.g. ``"smoke.toml [render]"``); nested tables add
    ``[key]``. Raises ``error`` (default ValueError) naming the table, the key and the bad value.
    """
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise TypeError(f"from_table needs a dataclass type, got {cls!r}")
    if not isinstance(table, dict):
        raise error(f"{where} must be a table, got {table!r}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(table) - set(fields))
    if unknown:
        raise error(f"{where}: unknown key(s) {unknown}; allowed: {sorted(fields)}")
    missing = sorted(n for n, f in fields.items() if n not in table and f.default is dataclasses.MISSING
                     and f.default_factory is dataclasses.MISSING)
    if missing:
        raise error(f"{where}: missing key(s) {missing}")
    hints = typing.get_type_hints(cls)
    kw = {k: _convert(hints[k], v, where, k, error) for k, v in table.items()}
    try:
        return cls(**kw)
    except (TypeError, ValueError) as e:
        if isinstance(e, error):
            raise
        raise error(f"{where}: {e}") from e


def _is_options(tp: Any) -> bool:
    """True for ``tuple[tuple[str, Any], ...]``: a table of options kept as sorted pairs."""
    args = typing.get_args(tp)
    return (typing.get_origin(tp) is tuple and len(args) == 2 and args[1] is Ellipsis
            and typing.get_origin(args[0]) is tuple and typing.get_args(args[0])[:1] == (str,))


def _convert(tp: Any, value: Any, where: str, key: str, error: type[Exception]) -> Any:
    """``value`` checked against (and converted to) annotation ``tp``; ``error`` naming key/value."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)

    def bad(expected: str) -> Exception:
        return error(f"{where}: key '{key}' has bad value {value!r} (expected {expected})")

    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        options = [a for a in args if a is not type(None)]
        for a in options:
            try:
                return _convert(a, value, where, key, error)
            except error:
                continue
        raise bad(" or ".join(getattr(a, "__name__", str(a)) for a in options))
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return from_table(tp, value, f"{where} [{key}]", error)
    if tp is bool:
        if not isinstance(value, bool):
            raise bad("bool")
        return value
    if tp is int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise bad("int")
        return value
    if tp is float:
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise bad("float")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise bad("str")
        return value
    if _is_options(tp):
        if not isinstance(value, dict):
            raise bad("a table")
        return tuple(sorted(value.items()))
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise bad("a list")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, where, key, error) for v in value)
        if len(value) != len(args):
            raise bad(f"a list of {len(args)}")
        return tuple(_convert(a, v, where, key, error) for a, v in zip(args, value))
    if tp is dict or origin is dict:
        if not isinstance(value, dict):
            raise bad("a table")
        return value
    return value  # an annotation this helper does not know: the dataclass checks it
