"""What every renderer backend takes and returns (the renders/ backend contract)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fenestra.renders.camera import Camera
from fenestra.renders.gt import WindowView

DENOISERS = ("none", "oidn", "oidn-aov")
LOOKS = ("classic", "wide")  # renders.materials.sample_look styles
LOOK_PER = ("set", "view")  # RenderSettings.look_per: one look per render set, or one per view


@dataclass(frozen=True)
class RenderSettings:
    """Backend settings. seed picks the look (palette, sun, sky); spp/max_depth/variant/denoise are
    for mitsuba. denoise: "none" (the raw path-traced estimate), "oidn" (Intel Open Image Denoise,
    RT filter on the linear HDR radiance) or "oidn-aov" (the same guided by albedo and normal AOVs of
    the same samples: a little closer to the converged image, ~2x the path-tracing cost)."""

    seed: int = 0
    shadows: bool = True
    spp: int = 16
    max_depth: int = 3
    variant: str = "auto"  # mitsuba: "auto" (llvm_ad_rgb if available, else scalar_rgb) or a name
    denoise: str = "none"  # mitsuba: "none" | "oidn" | "oidn-aov" (see the class docstring, fenestra/renders/photoreal.py)
    look: str = "classic"  # renders.materials.LOOKS: "classic" (the original palette), "wide" (broader)
    antialias: str = "fxaa"  # raster: "fxaa" (post filter, fast), "msaa4" (4x multisampling, ~2.5x slower), "none"
    # "set": one look (palette, textures, sun, sky) drawn from the seed for every view of a render set (as
    # always; folders unchanged); "view": each view of a dataset draws its own look from its own random
    # stream (renders.dataset.view_settings), so no figure rests on one random look per house
    look_per: str = "set"

    def __post_init__(self) -> None:
        if self.spp < 1:
            raise ValueError(f"spp must be >= 1, got {self.spp}")
        if self.antialias not in ("fxaa", "msaa4", "none"):
            raise ValueError(f"antialias must be 'fxaa', 'msaa4' or 'none', got {self.antialias!r}")
        if self.denoise not in DENOISERS:
            raise ValueError(f"denoise must be one of {DENOISERS}, got {self.denoise!r}")
        if self.look not in LOOKS:
            raise ValueError(f"look must be one of {LOOKS}, got {self.look!r}")
        if self.look_per not in LOOK_PER:
            raise ValueError(f"look_per must be one of {LOOK_PER}, got {self.look_per!r}")
        if self.max_depth < 1:
            raise ValueError(f"max_depth must be >= 1, got {self.max_depth}")


@dataclass(frozen=True, eq=False)
class RenderOutput:
    """One rendered view. rgb (H, W, 3) uint8; instances (H, W) uint16 (0 = none, i+1 = window i);
    depth (H, W) float32 camera z in m (0 = sky); windows: per-window ground truth.
    ignore: (H, W) uint16 ignore-region map (0 = none, renders.gt.ignore_map) or None when no
    region is in view; ignore_regions: its view.json ``ignore`` entries (id, instance_id, kind, visible_px)."""

    camera: Camera
    rgb: np.ndarray
    instances: np.ndarray
    depth: np.ndarray
    windows: tuple[WindowView, ...]
    ignore: np.ndarray | None = None
    ignore_regions: tuple[dict, ...] = ()
