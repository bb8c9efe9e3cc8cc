"""Fenestra: single-photo façade window reconstruction, measured against exact IFC ground truth.

``__version__``: the installed package's version (package metadata, i.e. pyproject.toml's
``version``); "0+unknown" when the package is not installed (a bare source tree).
"""
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("fenestra")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"
