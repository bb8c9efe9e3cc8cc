"""fenestra.config.from_table: TOML tables -> frozen dataclasses, with errors naming key and value."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import pytest

from fenestra.config import choices, from_table


@dataclass(frozen=True)
class Inner:
    ratio: float = 0.5
    names: tuple[str, ...] = ("a",)


@dataclass(frozen=True)
class Outer:
    name: str
    count: int = 1
    flag: bool = False
    span: tuple[float, float] = (0.0, 1.0)
    limit: float | None = None
    options: tuple[tuple[str, Any], ...] = ()
    inner: Inner = field(default_factory=Inner)

    def __post_init__(self) -> None:
        if self.count < 0:
            raise ValueError(f"count must be >= 0, got {self.count}")


def test_converts_lists_ints_options_and_nested_tables():
    o = from_table(Outer, {"name": "x", "count": 3, "span": [2, 5], "limit": 7, "options": {"b": [1, 2], "a": 1},
                           "inner": {"ratio": 1, "names": ["p", "q"]}})
    assert o == Outer("x", 3, False, (2.0, 5.0), 7.0, (("a", 1), ("b", [1, 2])), Inner(1.0, ("p", "q")))
    assert isinstance(o.span[0], float) and isinstance(o.limit, float) and isinstance(o.inner.ratio, float)
    assert from_table(Outer, {"name": "y"}) == Outer("y")  # defaults fill the rest


@pytest.mark.parametrize("table, message", [
    ({"name": "x", "cuont": 3}, r"T: unknown key\(s\) \['cuont'\]; allowed: \['count', 'flag', 'inner'"),
    ({}, r"T: missing key\(s\) \['name'\]"),
    ({"name": "x", "count": "3"}, r"T: key 'count' has bad value '3' \(expected int\)"),
    ({"name": "x", "count": True}, r"key 'count' has bad value True \(expected int\)"),
    ({"name": "x", "flag": 1}, r"key 'flag' has bad value 1 \(expected bool\)"),
    ({"name": "x", "span": [1, 2, 3]}, r"key 'span' has bad value \[1, 2, 3\] \(expected a list of 2\)"),
    ({"name": "x", "span": ["a", 2]}, r"key 'span' has bad value 'a' \(expected float\)"),
    ({"name": "x", "options": [1]}, r"key 'options' has bad value \[1\] \(expected a table\)"),
    ({"name": "x", "inner": {"ratio": "big"}}, r"T \[inner\]: key 'ratio' has bad value 'big'"),
    ({"name": "x", "inner": {"nmes": []}}, r"T \[inner\]: unknown key\(s\) \['nmes'\]"),
    ({"name": "x", "inner": 3}, r"T \[inner\] must be a table, got 3"),
    ({"name": "x", "count": -1}, r"T: count must be >= 0, got -1"),
])
def test_errors_name_the_table_key_and_value(table, message):
    class MyError(Exception):
        pass

    with pytest.raises(MyError, match=message):
        from_table(Outer, table, where="T", error=MyError)


def test_result_is_the_frozen_dataclass():
    o = from_table(Outer, {"name": "x"})
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.name = "y"
    with pytest.raises(TypeError, match="needs a dataclass type"):
        from_table(dict, {})


def test_choices_lists_a_registry_with_descriptions():
    @dataclass(frozen=True)
    class Entry:
        description: str

    assert choices({"a": Entry("first"), "b": "second", "c": object()}) == "a: first; b: second; c"
