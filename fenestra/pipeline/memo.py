"""A per-photo memo of the pipeline's pure steps (:class:`StepMemo`), so that the methods run on one
photo share the result of every step whose inputs are identical.

The bench runs many methods on each view and they repeat work: the per-window solvers ``lm`` and
``ippe`` snap the same quads and compute the same aspect ratios (pipeline.reconstruct); the
per-wall strategies ``wall`` and ``building`` group the same quads into walls and find the same
vanishing points (and fit the same walls when no two are tied at right angles), ``wall+lines``
and ``building+lines`` the same with the façade's segments, and the outlier loop of
pipeline.walls.strategies.fit_walls refits every wall that kept its windows. Each step is a pure
function of its inputs, so its result is kept under the exact bytes of those inputs (:func:`key`):
a repeated step gives the very result (bit for bit) that computing it again would.

An explicit cache, like pipeline.segments.SegmentCache: make one per photo (``StepMemo()``) and
pass it down (pipeline.reconstruct.reconstruct_from_quads, pipeline.walls.strategies.apply_walls);
no global state. Results kept are shared by the callers: their arrays are made read-only
(:func:`frozen`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields, is_dataclass
from typing import TypeVar

import numpy as np

T = TypeVar("T")


def key(*parts: object) -> tuple:
    """A hashable key of ``parts`` that equals another only when the parts are identical: arrays
    by dtype, shape and bytes (so 0.0 and -0.0, or two NaN payloads, differ: a miss, never a wrong
    hit), lists and tuples element by element, anything else (numbers, strings, None, frozen
    dataclasses) by its type and value (1 and 1.0, or a float and a numpy float, differ)."""
    out = []
    for p in parts:
        if isinstance(p, np.ndarray):
            a = np.ascontiguousarray(p)
            out.append(("array", a.dtype.str, a.shape, a.tobytes()))
        elif isinstance(p, (list, tuple)):
            out.append((type(p).__name__, key(*p)))
        else:
            hash(p)  # TypeError naming an unhashable part now, not at lookup
            out.append((type(p).__qualname__, p))
    return tuple(out)


def frozen(value: T) -> T:
    """``value`` with every numpy array in it (itself, the items of a list or tuple, the fields of
    a dataclass) made read-only, in place; returned for chaining."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    elif isinstance(value, (list, tuple)):
        for v in value:
            frozen(v)
    elif is_dataclass(value) and not isinstance(value, type):
        for f in fields(value):
            frozen(getattr(value, f.name))
    return value


class StepMemo:
    """Results of the pipeline's steps on one photo, each computed once per distinct input.

    ``memo(step, k, compute)``: the result kept under (step, k), else ``compute()``'s, kept (read-
    only) and returned; an exception is not kept (the next call computes again and raises again).
    ``hits`` and ``misses`` count the lookups.
    """

    def __init__(self) -> None:
        self._results: dict[tuple, object] = {}
        self.hits = 0
        self.misses = 0

    def __len__(self) -> int:
        return len(self._results)

    def __call__(self, step: str, k: tuple, compute: Callable[[], T]) -> T:
        full = (step, k)
        if full in self._results:
            self.hits += 1
            return self._results[full]  # type: ignore[return-value]
        self.misses += 1
        value = frozen(compute())
        self._results[full] = value
        return value
