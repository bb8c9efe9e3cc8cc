"""Compatibility shims for unmaintained dependencies, applied in one place.

pyrender 0.1.45 (last release 2021) still uses ``np.infty``, removed in NumPy 2, and must run
headless through EGL. Import :func:`import_pyrender` instead of ``import pyrender``.
"""
from __future__ import annotations

import importlib.util
import os

import numpy as np


def import_pyrender():
    """Import pyrender headless (EGL) with the NumPy 2 alias it needs; return the module."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    _preload_triton()
    if not hasattr(np, "infty"):
        np.infty = np.inf  # pyrender.Scene.bounds and others
    import pyrender  # noqa: PLC0415 (after triton and the NumPy 2 shim above)

    return pyrender


def _preload_triton() -> None:
    """Load triton (torch's GPU kernel compiler, pulled in lazily by torch.optim) before Mesa.

    Mesa's llvmpipe (EGL software rendering) and triton each bring their own LLVM; loading
    triton *after* an EGL context exists segfaults the process (seen with torch 2.15 / triton
    on Mesa 22, e.g. training a detector in a process that rendered). Loading it first is safe.
    """
    if importlib.util.find_spec("triton") is not None:
        import triton  # noqa: F401, PLC0415 (loaded first, so that its LLVM wins over Mesa's)
