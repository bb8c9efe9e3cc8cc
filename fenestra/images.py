"""The one reader of images and instance maps, for every stage (a photo, a render, a dataset's
image, an instance map given with ``--masks``).

Files are read as bytes (``np.fromfile``) and decoded from the buffer (``cv2.imdecode``), so a
file name cv2.imread cannot take (non-UTF-8, odd characters) reads like any other. As
``cv2.imread`` does, the decoder applies a JPEG's EXIF orientation: an image comes out as it is
displayed, and a truncated JPEG decodes with its missing part grey.

- :func:`read_image`: any image file cv2 decodes -> (H, W, 3) **uint8 RGB** (alpha dropped,
  grey expanded).
- :func:`read_instances`: a single-channel 8- or 16-bit PNG -> (H, W) **int32** instance map
  (0 = none, k = instance k): :data:`fenestra.checks.INSTANCE_DTYPE`, the one dtype an instance map
  has in memory (differences and a -1 sentinel are safe, every 16-bit id stays exact). The file
  stores uint16 (:func:`fenestra.data.write_view`).

A missing or undecodable file raises :class:`fenestra.errors.DatasetError` (a FenestraError and a
ValueError) naming the file.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from fenestra.checks import INSTANCE_DTYPE
from fenestra.errors import DatasetError

JPEG_SOI, JPEG_EOI = b"\xff\xd8", b"\xff\xd9"  # a JPEG's start- and end-of-image markers


def decode_file(path: str | Path, flags: int, what: str = "image") -> np.ndarray:
    """``cv2.imdecode(bytes of path, flags)``; DatasetError naming ``what`` and the file when it is
    missing, unreadable, empty or not decodable."""
    p = Path(path)
    if not p.is_file():
        raise DatasetError(f"{what} not found: {p}")
    try:
        buf = np.fromfile(p, dtype=np.uint8)
    except OSError as e:
        raise DatasetError(f"cannot read {what} {p}: {' '.join(str(e).split())}") from e
    img = cv2.imdecode(buf, flags) if buf.size else None
    if img is None and buf[:2].tobytes() == JPEG_SOI:
        # a truncated JPEG: end it as libjpeg's file reader (cv2.imread) does, with an end-of-image
        # marker, so its missing part decodes grey as there (pipeline.io.photo_warnings tells)
        img = cv2.imdecode(np.concatenate([buf, np.frombuffer(JPEG_EOI, np.uint8)]), flags)
    if img is None or img.size == 0:
        raise DatasetError(f"cannot read {what} {p} (not an image cv2 can decode)")
    return img


def read_image(path: str | Path, what: str = "image") -> np.ndarray:
    """(H, W, 3) uint8 **RGB** from any image file cv2 decodes, EXIF orientation applied;
    DatasetError naming ``what`` and the file when it is missing or undecodable."""
    bgr = decode_file(path, cv2.IMREAD_COLOR, what)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def read_instances(path: str | Path, image_size: tuple[int, int] | None = None,
                   what: str = "instance map") -> np.ndarray:
    """(H, W) **int32** instance map (0 = none, k = instance k) from a single-channel 8/16-bit PNG.

    image_size: (W, H) px the map must have (the photo's), or None. DatasetError naming the file
    when it is missing, undecodable, not single-channel 8/16-bit, or of another size.
    """
    raw = decode_file(path, cv2.IMREAD_UNCHANGED, what)
    if raw.ndim != 2 or raw.dtype not in (np.uint8, np.uint16):
        raise DatasetError(f"{what} {path} must be a single-channel 8/16-bit PNG, "
                           f"got shape {raw.shape}, dtype {raw.dtype}")
    if image_size is not None and (raw.shape[1], raw.shape[0]) != tuple(image_size):
        raise DatasetError(f"{what} {path} is {raw.shape[1]}x{raw.shape[0]} but the photo is "
                           f"{image_size[0]}x{image_size[1]}")
    return raw.astype(INSTANCE_DTYPE)
