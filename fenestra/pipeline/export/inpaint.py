"""The photo with every detected window void inpainted (OpenCV Telea): the wall texture."""
from __future__ import annotations

import cv2
import numpy as np

from fenestra.checks import check_image
from fenestra.conventions import LIMITS
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


def scaled_K(K: np.ndarray, photo_size: tuple[int, int], size: tuple[int, int]) -> np.ndarray:
    """K of the photo (W, H) resized to ``size`` (W', H'), keeping the pixel-centre convention:
    u' = (u + 0.5) W' / W - 0.5 (likewise v); the identity scaling returns K unchanged."""
    sx, sy = size[0] / photo_size[0], size[1] / photo_size[1]
    S = np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])
    return S @ np.asarray(K, dtype=np.float64)


def capped_size(photo_size: tuple[int, int], texture_size: tuple[int, int], max_px: int) -> tuple[int, int]:
    """The photo size (W', H') at which its padded texture (texture_size (Wt, Ht) at the photo's
    size) is at most ``max_px`` along its longer side, padding included: the photo (W, H) itself
    when it already is, else both scaled by one factor and floored (so that the padding, which
    scales with it and is rounded up by at most 1 px per side, keeps the texture within max_px)."""
    W, H = int(photo_size[0]), int(photo_size[1])
    longest = max(int(texture_size[0]), int(texture_size[1]))
    if longest <= max_px:
        return W, H
    k = (max_px - 2) / longest
    return max(1, int(np.floor(W * k))), max(1, int(np.floor(H * k)))


def inpaint_voids(image: np.ndarray, results: list[WindowResult], dilate_px: int = 4,
                  radius_px: float = 5.0, size: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(inpainted image (H, W, 3) uint8, mask (H, W) uint8) with every detected void filled.

    Every result with a quad is inpainted, failed reconstructions included: the void is still in
    the photo. ``dilate_px`` grows the mask to cover the frame's edge and mask-fit error.
    ``size`` (W', H'): inpaint the photo resized to that size (INTER_AREA; the quads mapped with
    :func:`scaled_K`'s convention; ``dilate_px`` and ``radius_px`` in its pixels), so that a huge
    photo costs what its export needs (:func:`capped_size`), not what its pixels would; the
    returned image and mask have that size. None: the photo's size. The fill itself is computed
    at most LIMITS.inpaint_max_side_px along the long side (:func:`inpaint_bounded`).
    """
    image = check_image(image)
    quads = [q for q in (result_quad(r) for r in results) if q is not None]
    H, W = image.shape[:2]
    if size is not None and (int(size[0]), int(size[1])) != (W, H):
        sx, sy = int(size[0]) / W, int(size[1]) / H
        image = check_image(cv2.resize(image, (int(size[0]), int(size[1])), interpolation=cv2.INTER_AREA))
        quads = [(q + 0.5) * np.array([sx, sy]) - 0.5 for q in quads]
    mask = void_mask(image.shape, quads, dilate_px)
    if not mask.any():
        return image.copy(), mask
    return inpaint_bounded(image, mask, radius_px, LIMITS.inpaint_max_side_px), mask


def inpaint_bounded(image: np.ndarray, mask: np.ndarray, radius_px: float, max_side_px: int) -> np.ndarray:
    """Telea inpainting of image (H, W, 3) uint8 where mask (H, W) uint8 is non-zero, computed on a
    copy with its long side at most ``max_side_px`` (INTER_AREA; a small pixel touching the mask is
    filled; radius_px in its pixels), the fill upsampled (bilinear) into the masked pixels only:
    the pixels outside the mask are the image's, unchanged. An image that already fits is
    inpainted as it is (cv2.inpaint). Cost: Telea's grows with the masked pixels, so a 12 Mpx
    texture's voids cost what a 1 Mpx one's do."""
    H, W = mask.shape[:2]
    k = max_side_px / max(H, W)
    if k >= 1.0:
        return cv2.inpaint(image, mask, float(radius_px), cv2.INPAINT_TELEA)
    size = (max(1, round(W * k)), max(1, round(H * k)))
    small = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    small_mask = (cv2.resize(mask, size, interpolation=cv2.INTER_AREA) > 0).astype(np.uint8) * 255
    fill = cv2.resize(cv2.inpaint(small, small_mask, float(radius_px), cv2.INPAINT_TELEA), (W, H),
                      interpolation=cv2.INTER_LINEAR)
    out = image.copy()
    inside = mask > 0
    out[inside] = fill[inside]
    return out
