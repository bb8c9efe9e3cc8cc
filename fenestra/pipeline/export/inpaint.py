"""The photo with every detected window void inpainted (OpenCV Telea): the wall texture."""
from __future__ import annotations

import cv2
import numpy as np

from fenestra.checks import check_image
from fenestra.pipeline.types import WindowResult


def result_quad(result: WindowResult) -> np.ndarray | None:
    """The best available image quad (4, 2) px of a result: snapped, else mask-fit, else None."""
    for q in (result.quad_snapped, result.quad_mask):
        if q is not None:
            q = np.asarray(q, dtype=np.float64)
            if q.shape == (4, 2) and np.all(np.isfinite(q)):
                return q
    return None


def void_mask(shape: tuple[int, int], quads: list[np.ndarray], dilate_px: int = 4) -> np.ndarray:
    """(H, W) uint8 mask (255 inside) of the filled quads (each (4, 2) px), dilated by ``dilate_px``."""
    if dilate_px < 0:
        raise ValueError(f"dilate_px must be >= 0, got {dilate_px}")
    mask = np.zeros(shape[:2], dtype=np.uint8)
    for q in quads:
        pts = np.round(np.asarray(q, dtype=np.float64) * 16).astype(np.int32)  # 4 fractional bits
        cv2.fillPoly(mask, [pts], 255, lineType=cv2.LINE_8, shift=4)
    if dilate_px:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * dilate_px + 1, 2 * dilate_px + 1))
        mask = cv2.dilate(mask, k)
    return mask


def inpaint_voids(image: np.ndarray, results: list[WindowResult], dilate_px: int = 4,
                  radius_px: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """(inpainted image (H, W, 3) uint8, mask (H, W) uint8) with every detected void filled.

    Every result with a quad is inpainted, failed reconstructions included: the void is still in
    the photo. ``dilate_px`` grows the mask to cover the frame's edge and mask-fit error.
    """
    image = check_image(image)
    quads = [q for q in (result_quad(r) for r in results) if q is not None]
    mask = void_mask(image.shape, quads, dilate_px)
    if not mask.any():
        return image.copy(), mask
    return cv2.inpaint(image, mask, float(radius_px), cv2.INPAINT_TELEA), mask
