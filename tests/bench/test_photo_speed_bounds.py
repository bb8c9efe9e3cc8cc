"""The bounds that keep `fenestra reconstruct` of a large photo within its CPU budget (issue 35,
item 6): whole-image segments on a bounded copy, the façade segments capped at the longest, the
void inpainting on a bounded copy. tools/photo_speed.py measures the time; these check the results."""
from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from fenestra.conventions import LIMITS
from fenestra.pipeline.export.inpaint import inpaint_bounded
from fenestra.pipeline.segments import SegmentCache, longest_segments, whole_image_segments


def _segments(lengths: list[float]) -> np.ndarray:
    """Horizontal segments (M, 2, 2) px of the given lengths, one per row y = index."""
    return np.array([[[0.0, y], [length, y]] for y, length in enumerate(lengths)])


def test_longest_segments_keeps_the_longest_in_their_order():
    s = _segments([5, 40, 12, 40, 3, 25])
    kept = longest_segments(s, 3)
    np.testing.assert_array_equal(kept, s[[1, 3, 5]])  # 40, 40, 25, in the given order
    np.testing.assert_array_equal(longest_segments(s, 6), s)
    np.testing.assert_array_equal(longest_segments(s, 10), s)
    assert longest_segments(s, 0).shape == (0, 2, 2)
    np.testing.assert_array_equal(longest_segments(_segments([7, 9, 9, 9]), 2), _segments([7, 9, 9, 9])[[1, 2]])  # ties: earlier
    with pytest.raises(ValueError, match="n must be"):
        longest_segments(s, -1)


def _line_image(shape: tuple[int, int]) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """A gray image (H, W) uint8 with three long straight edges (a horizontal, a vertical and an
    oblique one, anti-aliased polygons' sides) and each edge's true line (point, unit direction,
    length px) in pixel-centre coordinates."""
    H, W = shape
    img = np.full(shape, 50, np.uint8)
    cv2.fillPoly(img, [np.round(np.array([[300, 400], [2600, 400], [2600, 800], [300, 800]]) * 16 - 8).astype(np.int32)],
                 210, cv2.LINE_AA, shift=4)  # corners at (x - 0.5, y - 0.5): edges on pixel boundaries
    tri = np.array([[600.0, 1100.0], [2400.0, 1900.0], [600.0, 1900.0]])
    cv2.fillPoly(img, [np.round(tri * 16).astype(np.int32)], 160, cv2.LINE_AA, shift=4)
    hyp = np.linalg.norm(tri[1] - tri[0])
    lines = [(np.array([1000.0, 399.5]), np.array([1.0, 0.0]), 2300.0),  # the rectangle's top edge
             (np.array([2599.5, 600.0]), np.array([0.0, 1.0]), 400.0),  # its right edge
             (tri[0], (tri[1] - tri[0]) / hyp, hyp)]  # the triangle's hypotenuse
    return img, lines


def _distance_to_line(points: np.ndarray, point: np.ndarray, direction: np.ndarray) -> np.ndarray:
    d = points - point
    return np.abs(d[:, 0] * direction[1] - d[:, 1] * direction[0])


def _longest_along(seg: np.ndarray, point: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The longest of segments (M, 2, 2) px parallel to a line whose both ends lie within 1 px of it."""
    length = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    on = np.all(_distance_to_line(seg.reshape(-1, 2), point, direction).reshape(-1, 2) < 1.0, axis=1)
    on &= np.abs((seg[:, 1] - seg[:, 0]) @ direction) > 0.999 * length
    assert np.any(on), (point, direction)
    return seg[np.argmax(np.where(on, length, -1.0))]


def test_segments_of_a_downscaled_photo_map_back_to_full_resolution():
    """A 3000 x 2000 image (6 Mpx, above LIMITS.lsd_max_pixels) is searched on a bounded copy: the
    longest segment along each known edge lies on it within 1 px at full resolution, within 0.3 px
    of the line of the full-resolution search's segment, and spans at least 90 % of the edge."""
    img, lines = _line_image((2000, 3000))
    assert img.size > LIMITS.lsd_max_pixels  # the default bound has work to do
    bounded, full = whole_image_segments(img, 0.8), whole_image_segments(img, 0.8, max_pixels=img.size)
    for point, direction, edge_px in lines:
        b, f = _longest_along(bounded, point, direction), _longest_along(full, point, direction)
        assert np.linalg.norm(b[1] - b[0]) > 0.9 * edge_px
        f_dir = (f[1] - f[0]) / np.linalg.norm(f[1] - f[0])
        assert _distance_to_line(b, f[0], f_dir).max() < 0.3, (b, f)


def test_photo_segments_keep_at_most_the_limit(monkeypatch):
    """The walls' façade segments are the LIMITS.max_facade_segments longest of the photo's."""
    from fenestra.pipeline.walls import WallParams
    from fenestra.pipeline.walls import lines as wall_lines

    img, _ = _line_image((1000, 1500))
    rng = np.random.default_rng(0)
    for _ in range(60):  # short strokes of several lengths
        x, y = rng.uniform(50, 1400), rng.uniform(900, 980)
        cv2.line(img, (int(x), int(y)), (int(x + rng.uniform(25, 90)), int(y)), 255, 2)
    params = WallParams(lines=True)
    every = wall_lines.photo_segments(SegmentCache(img), params, img.shape)
    assert len(every) > 12
    monkeypatch.setattr(wall_lines, "LIMITS", dataclasses.replace(LIMITS, max_facade_segments=12))
    capped = wall_lines.photo_segments(SegmentCache(img), params, img.shape)
    np.testing.assert_array_equal(np.asarray(capped), longest_segments(np.asarray(every), 12))


def test_bounded_inpainting_fills_the_voids_and_keeps_every_other_pixel():
    rng = np.random.default_rng(1)
    H, W = 1500, 2000
    wall = np.clip(120 + rng.normal(0, 6, (H, W, 3)), 0, 255).astype(np.uint8)
    image = wall.copy()
    mask = np.zeros((H, W), np.uint8)
    for x0, y0 in ((200, 300), (900, 300), (1500, 900)):
        image[y0:y0 + 300, x0:x0 + 200] = (20, 30, 200)  # a dark blue void
        mask[y0 - 4:y0 + 304, x0 - 4:x0 + 204] = 255
    out = inpaint_bounded(image, mask, 5.0, 500)  # a 500 x 375 copy
    assert out.shape == image.shape and out.dtype == np.uint8
    np.testing.assert_array_equal(out[mask == 0], image[mask == 0])
    inside = out[mask > 0].astype(float)
    assert np.abs(inside.mean(axis=0) - 120).max() < 8  # filled with the wall, not the void's blue
    np.testing.assert_array_equal(inpaint_bounded(image[:300, :400], mask[:300, :400], 5.0, 500),
                                  cv2.inpaint(image[:300, :400], mask[:300, :400], 5.0, cv2.INPAINT_TELEA))


def test_glb_png_texture_is_lossless_at_the_fast_level(tmp_path):
    """png_image: the PNG trimesh writes keeps every pixel, at LIMITS.glb_png_compress_level (a
    level-1 stream is larger than level 9's on a noisy texture: the level was applied)."""
    import io

    from PIL import Image

    from fenestra.pipeline.export.mesh import png_image

    rgb = np.random.default_rng(2).integers(0, 64, (200, 300, 3), dtype=np.uint8)
    sizes = {}
    for level in (1, 9):
        buf = io.BytesIO()
        png_image(rgb, level).save(buf, format="png")
        sizes[level] = len(buf.getvalue())
        np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB")), rgb)
    assert sizes[1] > sizes[9]
    buf = io.BytesIO()
    png_image(rgb, 1).save(buf, format="png", compress_level=9)  # a stated level wins
    assert len(buf.getvalue()) == sizes[9]
