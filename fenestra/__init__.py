"""Fenestra: single-photo façade window reconstruction, measured against exact IFC ground truth.

The public API (typed; ``to_json()`` is ``fenestra reconstruct``'s windows.json)::

    from fenestra import reconstruct_photo, PhotoOptions, Known
    doc = reconstruct_photo("street.jpg", out="out/street").to_json()

The names are loaded on first use: importing a ground-floor module (``fenestra.conventions``)
stays light. ``__version__``: the installed package's version (package metadata, i.e.
pyproject.toml's ``version``); "0+unknown" when the package is not installed (a bare source tree).

The package's floors follow the data (docs/DESIGN.md): this ground floor (conventions, tolerances,
checks, the data contracts) imports nothing above it; then ``fenestra.scenes`` -> ``renders`` ->
``pipeline`` (what a user runs on a photo) -> ``bench`` -> ``reports``; ``training`` is the
detectors' lab; ``app`` the command line.
"""
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("fenestra")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["Known", "PhotoOptions", "PhotoSession", "UserCamera", "reconstruct_photo", "__version__"]


def __getattr__(name: str):
    """The public API, imported on first use (the pipeline pulls in OpenCV and torch)."""
    if name in ("Known", "PhotoOptions", "PhotoSession", "UserCamera", "reconstruct_photo"):
        import fenestra.pipeline as pipeline  # noqa: PLC0415  (the one upward import: the API facade)

        return getattr(pipeline, name)
    raise AttributeError(f"module 'fenestra' has no attribute {name!r}")
