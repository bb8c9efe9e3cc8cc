"""Fenestra: single-photo façade window reconstruction, measured against exact IFC ground truth.

The public API (typed; ``to_json()`` is ``fenestra reconstruct``'s windows.json)::

    from fenestra import reconstruct_photo, PhotoOptions, Known
    doc = reconstruct_photo("street.jpg", out="out/street").to_json()

The names (and ``__version__``) are loaded on first use: importing a ground-floor module
(``fenestra.conventions``) stays light. ``__version__``: the installed package's version (package metadata, i.e.
pyproject.toml's ``version``); "0+unknown" when the package is not installed (a bare source tree).

The package's floors follow the data (docs/DESIGN.md): this ground floor (conventions, tolerances,
checks, the data contracts) imports nothing above it; then ``fenestra.scenes`` -> ``renders`` ->
``pipeline`` (what a user runs on a photo) -> ``bench`` -> ``reports``; ``training`` is the
detectors' lab; ``app`` the command line.
"""
__all__ = ["Known", "PhotoOptions", "PhotoSession", "UserCamera", "reconstruct_photo", "__version__"]


def _version() -> str:
    """The installed package's version; "0+unknown" for a source tree that was never installed."""
    from importlib.metadata import PackageNotFoundError, version  # noqa: PLC0415  (~30 ms: on first use)

    try:
        return version("fenestra")
    except PackageNotFoundError:
        return "0+unknown"


def __getattr__(name: str):
    """The public API and ``__version__``, made on first use (the pipeline pulls in OpenCV and torch)."""
    if name == "__version__":
        globals()["__version__"] = v = _version()
        return v
    if name in ("Known", "PhotoOptions", "PhotoSession", "UserCamera", "reconstruct_photo"):
        import fenestra.pipeline as pipeline  # noqa: PLC0415  (the one upward import: the API facade)

        return getattr(pipeline, name)
    raise AttributeError(f"module 'fenestra' has no attribute {name!r}")
