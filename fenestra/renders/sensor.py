"""Optional sensor realism applied to rendered images only (never to ground truth).

Order: exposure -> blur -> noise -> JPEG, each drawn from a per-view numpy Generator.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class SensorConfig:
    """Ranges (low, high) of each effect; (0, 0) or 1.0 switches an effect off.

    exposure_stops: multiply linear-ish intensity by 2**stops; blur_sigma_px: Gaussian blur;
    noise_sigma: Gaussian noise std in 8-bit levels; jpeg_quality: 0 = no JPEG, else (low, high).
    """

    exposure_stops: tuple[float, float] = (0.0, 0.0)
    blur_sigma_px: tuple[float, float] = (0.0, 0.0)
    noise_sigma: tuple[float, float] = (0.0, 0.0)
    jpeg_quality: tuple[int, int] = (0, 0)

    def __post_init__(self) -> None:
        for name in ("exposure_stops", "blur_sigma_px", "noise_sigma", "jpeg_quality"):
            lo, hi = getattr(self, name)
            if hi < lo:
                raise ValueError(f"{name} must be (low, high) with low <= high, got {(lo, hi)}")
        if self.blur_sigma_px[0] < 0 or self.noise_sigma[0] < 0:
            raise ValueError(f"blur and noise must be >= 0, got {self.blur_sigma_px}, {self.noise_sigma}")
        if self.jpeg_quality != (0, 0) and not (1 <= self.jpeg_quality[0] <= self.jpeg_quality[1] <= 100):
            raise ValueError(f"jpeg_quality must be (0, 0) or within [1, 100], got {self.jpeg_quality}")

    @property
    def active(self) -> bool:
        return any(v != (0, 0) for v in (self.exposure_stops, self.blur_sigma_px, self.noise_sigma, self.jpeg_quality))


REALISTIC = SensorConfig(exposure_stops=(-0.5, 0.5), blur_sigma_px=(0.0, 0.8), noise_sigma=(0.5, 3.0),
                         jpeg_quality=(70, 95))


def apply_sensor(rgb: np.ndarray, cfg: SensorConfig, rng: np.random.Generator) -> np.ndarray:
    """(H, W, 3) uint8 -> (H, W, 3) uint8 with the configured effects (input unchanged)."""
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"apply_sensor needs an (H, W, 3) uint8 image, got {rgb.dtype} {rgb.shape}")
    img = rgb.astype(np.float32)
    stops = rng.uniform(*cfg.exposure_stops)
    if stops:
        img = 255.0 * ((img / 255.0) ** 2.2 * 2.0 ** stops) ** (1 / 2.2)
    sigma = rng.uniform(*cfg.blur_sigma_px)
    if sigma > 0.05:
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    noise = rng.uniform(*cfg.noise_sigma)
    if noise > 0:
        img = img + rng.normal(0.0, noise, img.shape).astype(np.float32)
    out = np.clip(img + 0.5, 0, 255).astype(np.uint8)
    if cfg.jpeg_quality != (0, 0):
        q = int(rng.integers(cfg.jpeg_quality[0], cfg.jpeg_quality[1] + 1))
        ok, buf = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, q])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].copy()
    return out
