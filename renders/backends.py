"""Renderer registry: one interface, ``make_renderer(name, scene, settings) -> Renderer``.

A Renderer has ``render(camera) -> RenderOutput`` (rgb uint8, instances uint16, depth float32 m,
per-window ground truth) and ``close()``; both backends share the exact instance-map definition.
"""
from __future__ import annotations

from typing import Callable, Protocol

from renders.base import RenderOutput, RenderSettings
from renders.camera import Camera
from scenes.model import Scene


class Renderer(Protocol):
    name: str

    def render(self, camera: Camera) -> RenderOutput: ...

    def close(self) -> None: ...


def _pyrender(scene: Scene, settings: RenderSettings) -> Renderer:
    from renders.raster import RasterRenderer

    return RasterRenderer(scene, settings)


def _mitsuba(scene: Scene, settings: RenderSettings) -> Renderer:
    from renders.photoreal import PhotorealRenderer

    return PhotorealRenderer(scene, settings)


RENDERERS: dict[str, Callable[[Scene, RenderSettings], Renderer]] = {"pyrender": _pyrender, "mitsuba": _mitsuba}


def make_renderer(name: str, scene: Scene, settings: RenderSettings = RenderSettings()) -> Renderer:
    """Build the renderer ``name`` ("pyrender" | "mitsuba") for a scene; close() it when done."""
    if name not in RENDERERS:
        raise ValueError(f"unknown renderer {name!r}; choose one of {sorted(RENDERERS)}")
    return RENDERERS[name](scene, settings)
