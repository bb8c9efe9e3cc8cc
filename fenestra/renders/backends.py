"""Renderer registry: one interface, ``make_renderer(name, scene, settings) -> Renderer``.

A Renderer has ``render(camera) -> RenderOutput`` (rgb uint8, instances uint16, depth float32 m,
per-window ground truth) and ``close()``; both backends share the exact instance-map definition.
Each registry entry (:class:`RendererEntry`) declares what it offers beyond that: a description
(CLI help) and its visibility test (what the view sampler uses to reject views whose target
windows are hidden). A backend without one cannot render a dataset whose sampler needs it: an
error, never a silent skip.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable, Protocol

from fenestra.registry import Registry
from fenestra.renders.base import RenderOutput, RenderSettings
from fenestra.renders.camera import Camera
from fenestra.renders.gt import WindowView
from fenestra.scenes.model import Scene
from fenestra.renders.raster import RasterRenderer
from fenestra.renders.photoreal import PhotorealRenderer


class Renderer(Protocol):
    name: str

    def render(self, camera: Camera) -> RenderOutput: ...

    def close(self) -> None: ...


Visibility = Callable[[Renderer, Camera], tuple[WindowView, ...]]


@dataclass(frozen=True)
class RendererEntry:
    """A registered backend. build(scene, settings) -> Renderer; with ``shares``, also
    build(scene, settings, like): a renderer that shares the look-free parts of ``like`` (one of the
    same scene and backend in another look: :func:`make_renderer`); description: one line for CLI help;
    visibility(renderer, camera) -> per-window ground truth (``WindowView.visible_fraction`` is what
    the sampler reads) of a renderer this entry built, or None when the backend has no visibility test."""

    name: str
    build: Callable[..., Renderer]
    description: str
    visibility: Visibility | None
    shares: bool = False


def _pyrender(scene: Scene, settings: RenderSettings, like: Renderer | None = None) -> Renderer:

    return RasterRenderer(scene, settings, like)


def _mitsuba(scene: Scene, settings: RenderSettings, like: Renderer | None = None) -> Renderer:

    return PhotorealRenderer(scene, settings, like)


def occluder_visibility(renderer: Renderer, camera: Camera) -> tuple[WindowView, ...]:
    """Per-window ground truth from a backend's exact occluder pass (``renderer.occluders``, a
    renders.raster.OccluderPass: depth + element ids, no antialiasing), the one both backends share.
    The pass's ground truth is kept for ``renderer.render(camera)`` of the view if it is accepted
    (OccluderPass.truth): one occluder pass per view."""
    return renderer.occluders.truth(camera, keep=True)[2]


def raster_visibility(renderer: Renderer, camera: Camera) -> tuple[WindowView, ...]:
    """occluder_visibility of the raster backend, which also issues the candidate's RGB pass while
    the ground truth is computed (renders.raster.RasterRenderer.visibility)."""
    return renderer.visibility(camera)


RENDERERS: Registry[RendererEntry] = Registry("renderer", [
    RendererEntry("pyrender", _pyrender, "OpenGL raster, fast (FXAA, sun shadows)", raster_visibility, shares=True),
    RendererEntry("mitsuba", _mitsuba, "mitsuba path tracing, photoreal (optional OIDN denoising)",
                  occluder_visibility, shares=True),
])


def renderer_entry(name: str) -> RendererEntry:
    """The registry entry ``name``; ValueError (fenestra.registry.UnknownName) naming it and the registered ones."""
    return RENDERERS[name]


def make_renderer(name: str, scene: Scene, settings: RenderSettings = RenderSettings(),
                  like: Renderer | None = None) -> Renderer:
    """Build the renderer ``name`` (a key of RENDERERS) for a scene; close() it when done. like: a
    renderer ``name`` of the same scene (another look): a backend that ``shares`` takes its look-free
    parts (materials.SceneGeometry: glass panes, planar coordinates; the occluder pass where the
    triangles match), the images are the same; another backend ignores it."""
    entry = renderer_entry(name)
    return entry.build(scene, settings, like) if like is not None and entry.shares else entry.build(scene, settings)


def visibility_function(name: str, renderer: Renderer) -> Callable[[Camera], tuple[WindowView, ...]]:
    """``camera -> per-window WindowViews`` of ``renderer`` (built as ``name``): its entry's declared
    visibility test; ValueError when the backend declares none."""
    entry = renderer_entry(name)
    if entry.visibility is None:
        raise ValueError(f"renderer {name!r} declares no visibility test (RENDERERS[{name!r}].visibility is None), "
                         "which the view sampler needs to reject hidden windows (sampler.min_visible_fraction > 0)")
    return functools.partial(entry.visibility, renderer)
