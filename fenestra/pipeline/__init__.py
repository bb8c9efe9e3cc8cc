"""The pipeline: detect -> quad -> snap -> aspect -> pose -> walls -> façade model -> export.

The documented Python API for one photo (typed; ``to_json()`` is ``fenestra reconstruct``'s
windows.json), also importable from the package itself (``from fenestra import reconstruct_photo``)::

    from fenestra import reconstruct_photo, PhotoOptions, Known

    res = reconstruct_photo("street.jpg")                      # nothing written; a PhotoResult
    res = reconstruct_photo("street.jpg", out="out/street",     # ... and the files (res.export: what was written)
                            options=PhotoOptions(known=Known(window_height_m=1.4)))
    res.reconstruction     # typed: each window's stages (fit, measured, placed, regularized, export), K, walls
    doc = res.to_json()    # windows.json's data:
    doc["K_source"]        # where the focal length came from, its interval, every source's value
    doc["walls"]           # one entry per façade plane: members, scale and its source ("assumed"?)
    doc["windows"]         # one per detection: quads, aspect, R, t, size, flags, failure, exported

Several methods on one photo, typed, without files (what the bench does)::

    from fenestra import PhotoSession
    from fenestra.methods import Method
    session = PhotoSession(image_rgb)                           # K-free; camera=UserCamera(K, how) for a known K
    rec = session.run(Method("default", "refine", "wall+lines"))
    rec.windows, rec.resolved.source, rec.model.walls, rec.exported

See :func:`fenestra.pipeline.photo.reconstruct_photo` and :mod:`fenestra.pipeline.session`. The
names are loaded on first use (importing a submodule of the pipeline stays light).
"""
from __future__ import annotations

__all__ = ["Known", "PhotoOptions", "PhotoSession", "UserCamera", "reconstruct_photo"]


def __getattr__(name: str):
    if name in ("PhotoOptions", "reconstruct_photo"):
        import fenestra.pipeline.photo as photo  # noqa: PLC0415 (a cycle: fenestra.pipeline.photo imports this module)

        return getattr(photo, name)
    if name in ("PhotoSession", "UserCamera"):
        import fenestra.pipeline.session as session  # noqa: PLC0415 (a cycle: fenestra.pipeline.session imports this module)

        return getattr(session, name)
    if name == "Known":
        from fenestra.pipeline.facade_model import Known  # noqa: PLC0415 (a cycle: fenestra.pipeline.facade_model imports this module)

        return Known
    raise AttributeError(f"module 'fenestra.pipeline' has no attribute {name!r}")
