"""Photo transforms of the K-free bench: what a photo goes through between a camera and a user
(re-saved, greyed, mirrored, cropped, stored turned with an EXIF orientation), as view transforms.

    enc = TRANSFORMS["jpeg"](view.image)     # Encoded: the bytes of the file a user would have
    photo = decode(enc)                      # Photo: its pixels as the CLI reads them, and its EXIF tags

A transform is a pure function image -> :class:`Encoded` (a file's bytes and suffix). The file is
never written: :func:`decode` reads the bytes as ``fenestra reconstruct`` reads a file
(fenestra.images.image_from_bytes: cv2's decoder, the EXIF orientation applied) and its EXIF tags
as pipeline.intrinsics.read_exif_tags does, and the session takes both (pipeline.session.PhotoSession's
``image`` and ``exif``).
"""
from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fenestra.bench.results import AS_IS
from PIL import Image
from fenestra.images import image_from_bytes
from fenestra.pipeline.intrinsics import read_exif_tags

CROP_PER_SIDE = 0.05  # 10 % of each dimension, centred (the principal point stays at the centre)
JPEG_QUALITY = 80  # the "re-saved JPEG" transform
EXIF_ORIENTATION_TAG = 0x0112


@dataclass(frozen=True)
class Encoded:
    """An image file's bytes and its suffix (".png", ".jpg")."""

    data: bytes
    suffix: str


@dataclass(frozen=True)
class Photo:
    """A photo as the session takes it: image (H, W, 3) uint8 RGB (EXIF orientation applied) and
    exif, its EXIF tags {tag id: value} ({} for none)."""

    image: np.ndarray
    exif: dict


def _pil(image: np.ndarray):

    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError(f"image must be (H, W, 3) uint8 RGB, got {img.shape} {img.dtype}")
    return Image.fromarray(img)


def _save(im, fmt: str, **kw) -> bytes:
    buf = io.BytesIO()
    im.save(buf, format=fmt, **kw)
    return buf.getvalue()


def png(image: np.ndarray) -> Encoded:
    """The image as it is (lossless PNG)."""
    return Encoded(_save(_pil(image), "PNG"), ".png")


def mirror_image(image: np.ndarray) -> np.ndarray:
    """Left-right mirror."""
    return np.ascontiguousarray(np.asarray(image)[:, ::-1])


def crop_image(image: np.ndarray, per_side: float = CROP_PER_SIDE) -> np.ndarray:
    """The centre of the image without ``per_side`` of each dimension on each side (round(W *
    per_side) columns left and right, round(H * per_side) rows top and bottom)."""
    if not 0 <= per_side < 0.5:
        raise ValueError(f"crop per side must be in [0, 0.5), got {per_side!r}")
    h, w = np.shape(image)[:2]
    dx, dy = round(w * per_side), round(h * per_side)
    return np.ascontiguousarray(np.asarray(image)[dy:h - dy, dx:w - dx])


def gray_image(image: np.ndarray) -> np.ndarray:
    """Grayscale (ITU-R 601 luma, as PIL's "L"), replicated to three channels."""
    return np.repeat(np.asarray(_pil(image).convert("L"))[..., None], 3, axis=2)


def jpeg(image: np.ndarray, quality: int = JPEG_QUALITY) -> Encoded:
    """The image re-saved as JPEG at ``quality``."""
    return Encoded(_save(_pil(image), "JPEG", quality=quality), ".jpg")


def exif_rotated(image: np.ndarray) -> Encoded:
    """The pixels turned 90 deg counter-clockwise and stored (lossless PNG) with EXIF orientation
    6, which tells a reader to turn them back: a reader that honours EXIF gets ``image``."""

    exif = Image.Exif()
    exif[EXIF_ORIENTATION_TAG] = 6
    return Encoded(_save(_pil(np.rot90(image, 1)), "PNG", exif=exif.tobytes()), ".png")


TRANSFORMS: dict[str, Callable[[np.ndarray], Encoded]] = {
    AS_IS: png,
    "gray": lambda im: png(gray_image(im)),
    "jpeg": jpeg,
    "exif_rot": exif_rotated,
    "mirror": lambda im: png(mirror_image(im)),
    "crop": lambda im: png(crop_image(im)),
}


def decode(enc: Encoded, what: str = "photo") -> Photo:
    """The :class:`Photo` a user's file of these bytes gives the session: its pixels decoded as
    ``fenestra reconstruct`` decodes a file (fenestra.images.image_from_bytes) and its EXIF tags
    (pipeline.intrinsics.read_exif_tags of the bytes); DatasetError naming ``what`` when undecodable."""

    return Photo(image_from_bytes(enc.data, what), read_exif_tags(io.BytesIO(enc.data)))


def transformed(image: np.ndarray, transform: str) -> Photo:
    """The photo ``image`` becomes under ``transform`` (a key of TRANSFORMS), as the session takes it."""
    return decode(TRANSFORMS[transform](image), f"the photo under {transform!r}")


__all__ = ["CROP_PER_SIDE", "Encoded", "JPEG_QUALITY", "Photo", "TRANSFORMS", "crop_image", "decode", "exif_rotated",
           "gray_image", "jpeg", "mirror_image", "png", "transformed"]
