"""Compatibility shims for unmaintained dependencies, applied in one place.

pyrender 0.1.45 (last release 2021) still uses ``np.infty``, removed in NumPy 2, and must run
headless through EGL. Import :func:`import_pyrender` instead of ``import pyrender``.
"""
from __future__ import annotations

import os

import numpy as np


def import_pyrender():
    """Import pyrender headless (EGL) with the NumPy 2 alias it needs; return the module."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    if not hasattr(np, "infty"):
        np.infty = np.inf  # pyrender.Scene.bounds and others
    import pyrender  # noqa: PLC0415

    return pyrender
