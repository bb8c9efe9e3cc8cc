"""The pipeline: detect -> quad -> snap -> aspect -> pose -> walls -> export.

The documented Python API for one photo (the same data as ``fenestra reconstruct``'s windows.json)::

    from fenestra.pipeline import reconstruct_photo, PhotoOptions, Known

    doc = reconstruct_photo("street.jpg")                      # nothing written; a dict
    doc = reconstruct_photo("street.jpg", out="out/street",     # ... and the files
                            options=PhotoOptions(known=Known(window_height_m=1.4)))
    doc["K_source"]        # where the focal length came from, its interval, every source's value
    doc["walls"]           # one entry per façade plane: members, scale and its source ("assumed"?)
    doc["windows"]         # one per detection: quads, aspect, R, t, size, flags, failure, exported

See :func:`pipeline.photo.reconstruct_photo` for every argument. The names are loaded on first use
(importing a submodule of pipeline stays light). The lower-level stages: pipeline.reconstruct
(reconstruct, reconstruct_from_quads), pipeline.export (write_outputs).
"""
from __future__ import annotations

__all__ = ["Known", "PhotoOptions", "reconstruct_photo"]


def __getattr__(name: str):
    if name in ("PhotoOptions", "reconstruct_photo"):
        import fenestra.pipeline.photo as photo  # noqa: PLC0415

        return getattr(photo, name)
    if name == "Known":
        from fenestra.pipeline.facade_model import Known  # noqa: PLC0415

        return Known
    raise AttributeError(f"module 'pipeline' has no attribute {name!r}")
