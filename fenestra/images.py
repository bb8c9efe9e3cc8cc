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

Bounded before decoding: a file larger than ``LIMITS.max_image_bytes``, or whose header states
more than ``max_pixels`` pixels (default ``LIMITS.max_image_pixels``), is refused before a byte of
pixels is decoded (:func:`header_size` reads the header only, with PIL's parsers;
:func:`radiance_size` the Radiance HDR header PIL does not know). A file whose size neither can
read is refused, never decoded blind (a decompression bomb in a format the check does not know).

A missing, oversized or undecodable file raises :class:`fenestra.errors.DatasetError` (a
FenestraError and a ValueError) naming the file.
"""
from __future__ import annotations

import struct
from pathlib import Path

import cv2
import numpy as np

from fenestra.checks import INSTANCE_DTYPE
from fenestra.conventions import LIMITS
from fenestra.errors import DatasetError
from PIL import Image

JPEG_SOI, JPEG_EOI = b"\xff\xd8", b"\xff\xd9"  # a JPEG's start- and end-of-image markers


def header_size(path: str | Path) -> tuple[int, int] | None:
    """(W, H) px an image file's header states, read without decoding its pixels (PIL's format
    plugins, opened directly so that a huge size is reported, not refused as PIL's open does);
    None when no PIL plugin parses the header (cv2 may still decode the file)."""


    Image.init()
    bound, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None  # a plugin (WebP) checks PIL's own bound as it opens
    try:
        with open(path, "rb") as fp:
            prefix = fp.read(16)
            for fmt in Image.ID:
                factory, accept = Image.OPEN[fmt]
                fp.seek(0)
                try:
                    if accept is not None and not accept(prefix):
                        continue
                    im = factory(fp, str(path))
                except (SyntaxError, IndexError, TypeError, ValueError, OSError, EOFError, struct.error):
                    continue
                return int(im.size[0]), int(im.size[1])
    finally:
        Image.MAX_IMAGE_PIXELS = bound
    return None


RADIANCE_MAGIC = (b"#?RADIANCE", b"#?RGBE")


def radiance_size(path: str | Path) -> tuple[int, int] | None:
    """(W, H) px of a Radiance HDR file (which OpenCV decodes and PIL cannot parse), read from its
    text header (``#?RADIANCE``, lines, a blank line, then ``-Y H +X W`` or another axis order);
    None when the file is not one. DatasetError for one whose header states no size."""
    with open(path, "rb") as fp:
        head = fp.read(64 * 1024)
    if not head.startswith(RADIANCE_MAGIC):
        return None
    _, sep, rest = head.partition(b"\n\n")
    parts = rest.split(b"\n", 1)[0].split() if sep else []
    if len(parts) == 4 and parts[0][1:] in (b"Y", b"X") and parts[2][1:] in (b"X", b"Y") \
            and parts[1].isdigit() and parts[3].isdigit():
        a, b = int(parts[1]), int(parts[3])
        return (b, a) if parts[0][1:] == b"Y" else (a, b)
    raise DatasetError(f"cannot read {path}: a Radiance HDR file whose header states no size")


def webp_size(path: str | Path) -> tuple[int, int] | None:
    """(W, H) px a WebP file's first chunk states (VP8X canvas, VP8L or VP8 frame), read from its
    bytes (PIL's WebP reader refuses a size over its own bomb bound before reporting it); None when
    the file is not a WebP of one of these chunks."""
    with open(path, "rb") as fp:
        head = fp.read(30)
    if len(head) < 30 or head[:4] != b"RIFF" or head[8:12] != b"WEBP":
        return None
    kind, body = head[12:16], head[20:]
    if kind == b"VP8X":
        return 1 + int.from_bytes(body[4:7], "little"), 1 + int.from_bytes(body[7:10], "little")
    if kind == b"VP8L" and body[0] == 0x2F:
        bits = int.from_bytes(body[1:5], "little")
        return 1 + (bits & 0x3FFF), 1 + ((bits >> 14) & 0x3FFF)
    if kind == b"VP8 " and body[3:6] == b"\x9d\x01\x2a":
        return int.from_bytes(body[6:8], "little") & 0x3FFF, int.from_bytes(body[8:10], "little") & 0x3FFF
    return None


def check_size(path: str | Path, what: str = "image", max_pixels: int | None = None) -> None:
    """DatasetError naming the file when it is larger than LIMITS.max_image_bytes, or its header
    states more than ``max_pixels`` (default LIMITS.max_image_pixels) pixels; checked before decoding."""
    p = Path(path)
    max_pixels = LIMITS.max_image_pixels if max_pixels is None else int(max_pixels)
    if max_pixels <= 0:
        raise ValueError(f"max_pixels must be positive, got {max_pixels}")
    n_bytes = p.stat().st_size
    if n_bytes > LIMITS.max_image_bytes:
        raise DatasetError(f"{what} {p} is {n_bytes / 2**20:.0f} MiB, over the {LIMITS.max_image_bytes / 2**20:.0f} MiB "
                           "an image file may have (fenestra.conventions.LIMITS.max_image_bytes)")
    size = webp_size(p) or header_size(p) or radiance_size(p)
    if size is None:  # its size cannot be known before decoding: refused, never decoded blind
        raise DatasetError(f"cannot read {what} {p}: not an image format whose size Fenestra can read before "
                           "decoding (JPEG, PNG, TIFF, BMP, WebP, PNM, Radiance HDR, ...); convert it to PNG or JPEG")
    if size[0] * size[1] > max_pixels:
        raise DatasetError(f"{what} {p} is {size[0]}x{size[1]} = {size[0] * size[1] / 1e6:.0f} Mpx, over the limit of "
                           f"{max_pixels / 1e6:.0f} Mpx (--max-pixels raises it; decoding needs about "
                           f"{3 * size[0] * size[1] / 2**30:.1f} GiB)")


def decode_file(path: str | Path, flags: int, what: str = "image", max_pixels: int | None = None) -> np.ndarray:
    """``cv2.imdecode(bytes of path, flags)``; DatasetError naming ``what`` and the file when it is
    missing, not a regular file, over the size bounds (:func:`check_size`), unreadable, empty or
    not decodable."""
    p = Path(path)
    if not p.is_file():
        raise DatasetError(f"{what} {p} is not a regular file (a folder, FIFO or device)" if p.exists()
                           else f"{what} not found: {p}")
    check_size(p, what, max_pixels)
    try:
        buf = np.fromfile(p, dtype=np.uint8)
    except OSError as e:
        raise DatasetError(f"cannot read {what} {p}: {' '.join(str(e).split())}") from e
    img = decode_buffer(buf, flags)
    if img is None:
        raise DatasetError(f"cannot read {what} {p} (not an image cv2 can decode)")
    return img


def decode_buffer(buf: np.ndarray, flags: int) -> np.ndarray | None:
    """``cv2.imdecode(buf, flags)`` of an image file's bytes (a (N,) uint8 array), the EXIF
    orientation applied; None when they are not an image cv2 decodes (or decode empty)."""
    img = cv2.imdecode(buf, flags) if buf.size else None
    if img is None and buf[:2].tobytes() == JPEG_SOI:
        # a truncated JPEG: end it as libjpeg's file reader (cv2.imread) does, with an end-of-image
        # marker, so its missing part decodes grey as there (pipeline.io.photo_warnings tells)
        img = cv2.imdecode(np.concatenate([buf, np.frombuffer(JPEG_EOI, np.uint8)]), flags)
    return None if img is None or img.size == 0 else img


def image_from_bytes(data: bytes, what: str = "image") -> np.ndarray:
    """(H, W, 3) uint8 **RGB** from an image file's bytes in memory, decoded as :func:`read_image`
    decodes a file (EXIF orientation applied); DatasetError naming ``what`` when undecodable."""
    bgr = decode_buffer(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        raise DatasetError(f"cannot read {what} (not an image cv2 can decode)")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def read_image(path: str | Path, what: str = "image", max_pixels: int | None = None) -> np.ndarray:
    """(H, W, 3) uint8 **RGB** from any image file cv2 decodes, EXIF orientation applied;
    DatasetError naming ``what`` and the file when it is missing, too large (``max_pixels``,
    default LIMITS.max_image_pixels) or undecodable."""
    bgr = decode_file(path, cv2.IMREAD_COLOR, what, max_pixels)
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
