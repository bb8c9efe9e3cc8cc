"""Masks, boxes and COCO RLE: one convention, one encoder (docs/DESIGN.md, "Data contracts").

- **Boxes**, one convention: ``(x0, y0, x1, y1)`` px on the pixel-edge outline with pixel centres
  at integers (fenestra.conventions), so a mask over columns c0..c1 spans x0 = c0 - 0.5 to
  x1 = c1 + 0.5 and x1 - x0 is its width in px (:func:`mask_box`). COCO's ``bbox`` puts pixel
  edges at integers: ``[x0 + 0.5, y0 + 0.5, x1 - x0, y1 - y0]`` (:func:`box_to_coco`,
  :func:`box_from_coco`).
- **Masks**: :class:`SparseMask` (a mask stored as its bounding crop), :func:`instance_masks`
  (every id of an instance map), COCO compressed RLE from a full mask or a crop at an origin
  (:func:`rle_from_mask`, :func:`rle_from_crop`: one encoder) and back (:func:`rle_to_mask`,
  :func:`segmentation_to_rle` for polygons and uncompressed RLE).

Ground floor: imports nothing above fenestra/.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from pycocotools import mask as mask_utils

# ---------------------------------------------------------------- boxes

def mask_extent(mask: np.ndarray) -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1): the first and last column and row (inclusive, px) holding a non-zero pixel
    of a 2-D mask; None when it has none. Memory: a row and a column of bools, never one index per
    pixel (a full-width mask of a 150 Mpx photo holds 150 million)."""
    m = np.asarray(mask)
    cols, rows = np.flatnonzero(m.any(axis=0)), np.flatnonzero(m.any(axis=1))
    if cols.size == 0:
        return None
    return int(cols[0]), int(rows[0]), int(cols[-1]), int(rows[-1])


def mask_box(mask: np.ndarray, origin: tuple[int, int] = (0, 0)) -> np.ndarray:
    """(4,) float64 x0, y0, x1, y1 px of a non-empty mask (non-zero = inside) on the pixel-edge
    outline (pixel centres at integers; x1 - x0 = width in px). origin (x0, y0): image pixel of
    the mask's [0, 0] when it is a crop. ValueError for an empty mask."""
    extent = mask_extent(mask)
    if extent is None:
        raise ValueError("mask_box: empty mask")
    (ox, oy), (x0, y0, x1, y1) = origin, extent
    return np.array([x0 + ox - 0.5, y0 + oy - 0.5, x1 + ox + 0.5, y1 + oy + 0.5], dtype=np.float64)


def box_to_coco(box) -> list[float]:
    """(x0, y0, x1, y1) px (pixel centres at integers) -> COCO bbox [x, y, w, h] (edges at integers)."""
    x0, y0, x1, y1 = (float(v) for v in box)
    return [x0 + 0.5, y0 + 0.5, x1 - x0, y1 - y0]


def box_from_coco(bbox) -> np.ndarray:
    """COCO / YOLO bbox [x, y, w, h] (pixel edges at integers) -> (4,) x0 y0 x1 y1 px (centres at integers)."""
    x, y, w, h = (float(v) for v in bbox)
    return np.array([x - 0.5, y - 0.5, x + w - 0.5, y + h - 0.5])

# ---------------------------------------------------------------- masks and RLE

@dataclass(frozen=True)
class SparseMask:
    """A bool mask of an (H, W) image stored as its bounding crop.

    crop: (r1 - r0, c1 - c0) bool, the mask's rows r0:r1 and columns c0:c1 (pixel indices);
    shape: (H, W) of the full image; area: number of True pixels. An empty mask has a (0, 0) crop.
    Memory and IoU cost grow with the mask's box, not with the image.
    """

    crop: np.ndarray
    r0: int
    c0: int
    shape: tuple[int, int]
    area: int

    @property
    def r1(self) -> int:
        return self.r0 + self.crop.shape[0]

    @property
    def c1(self) -> int:
        return self.c0 + self.crop.shape[1]

    @classmethod
    def from_dense(cls, mask: np.ndarray) -> "SparseMask":
        """The crop of a dense (H, W) mask (any dtype; non-zero = inside)."""
        m = np.asarray(mask)
        if m.ndim != 2:
            raise ValueError(f"mask must be (H, W), got shape {m.shape}")
        m = m.astype(bool, copy=False)
        rows = np.flatnonzero(m.any(axis=1))
        if rows.size == 0:
            return cls(np.zeros((0, 0), bool), 0, 0, tuple(m.shape), 0)
        cols = np.flatnonzero(m[rows[0]:rows[-1] + 1].any(axis=0))
        crop = m[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
        return cls(crop, int(rows[0]), int(cols[0]), tuple(m.shape), int(np.count_nonzero(crop)))

    @classmethod
    def from_crop(cls, crop: np.ndarray, origin: tuple[int, int], shape: tuple[int, int]) -> "SparseMask":
        """A mask given as a crop (h, w) whose pixel [0, 0] is image pixel origin (x0, y0) of an
        image of ``shape`` (H, W): a Detection's (mask, origin); a full mask has origin (0, 0).
        ValueError when its pixels do not fit the image."""
        s = cls.from_dense(crop)
        x0, y0 = int(origin[0]), int(origin[1])
        r0, c0 = s.r0 + y0, s.c0 + x0
        if s.area and (r0 < 0 or c0 < 0 or r0 + s.crop.shape[0] > shape[0] or c0 + s.crop.shape[1] > shape[1]):
            raise ValueError(f"mask crop {np.shape(crop)} at origin {tuple(origin)} does not fit an image "
                             f"of shape {tuple(shape)}")
        return cls(s.crop, r0, c0, tuple(int(v) for v in shape), s.area)

    def box(self) -> np.ndarray:
        """(4,) x0, y0, x1, y1 px on the pixel-edge outline (:func:`mask_box`); the crop is tight."""
        if not self.area:
            raise ValueError("box of an empty mask")
        return np.array([self.c0 - 0.5, self.r0 - 0.5, self.c1 - 0.5, self.r1 - 0.5])

    def rle(self) -> dict:
        """COCO compressed RLE of the full-image mask (:func:`rle_from_crop` of the crop)."""
        return rle_from_crop(self.crop, (self.c0, self.r0), self.shape)

    def dense(self) -> np.ndarray:
        """The full (H, W) bool mask (allocates H x W)."""
        out = np.zeros(self.shape, dtype=bool)
        out[self.r0:self.r1, self.c0:self.c1] = self.crop
        return out


def instance_masks(instances: np.ndarray, ids: Iterable[int]) -> list[SparseMask]:
    """SparseMask of each id of an instance map (H, W) int (0 = none), in the order of ``ids``.

    One pass over the map finds every id's box (scipy.ndimage.find_objects); each mask is then
    compared within its box only. An id absent from the map gives an empty mask.
    """
    from scipy.ndimage import find_objects  # noqa: PLC0415 (SciPy: imported when first used, not at the package's import)

    inst = np.asarray(instances)
    if inst.ndim != 2 or not np.issubdtype(inst.dtype, np.integer):
        raise ValueError(f"instances must be an (H, W) integer map, got shape {inst.shape}, dtype {inst.dtype}")
    ids = [int(i) for i in ids]
    if any(i < 1 for i in ids):
        raise ValueError(f"instance ids must be >= 1, got {sorted(i for i in ids if i < 1)}")
    wanted = [i for i in ids if i <= int(inst.max(initial=0))]
    boxes = find_objects(inst, max_label=max(wanted, default=0)) if wanted else []
    out = []
    for i in ids:
        box = boxes[i - 1] if i - 1 < len(boxes) else None
        if box is None:
            out.append(SparseMask(np.zeros((0, 0), bool), 0, 0, tuple(inst.shape), 0))
            continue
        crop = inst[box] == i
        out.append(SparseMask(crop, box[0].start, box[1].start, tuple(inst.shape),
                              int(np.count_nonzero(crop))))
    return out


def rle_from_crop(crop: np.ndarray, origin: tuple[int, int], shape: tuple[int, int]) -> dict:
    """COCO compressed RLE ``{"size": [H, W], "counts": str}`` of the (H, W) image mask given as a
    crop (h, w) (non-zero = inside) whose pixel [0, 0] is image pixel origin (x0, y0).

    The one RLE encoder: runs in column-major order, starting with background, built from the
    crop's pixels without allocating the full image; identical to pycocotools' ``encode`` of the
    full mask. ValueError when a pixel of the mask falls outside the image.
    """

    H, W = (int(v) for v in shape)
    c = np.asarray(crop)
    if c.ndim != 2:
        raise ValueError(f"mask crop must be (h, w), got shape {c.shape}")
    cols, rows = np.nonzero(c.T)  # column by column: ascending column-major index
    cols, rows = cols.astype(np.int64) + int(origin[0]), rows.astype(np.int64) + int(origin[1])
    if cols.size and (cols.min() < 0 or rows.min() < 0 or cols.max() >= W or rows.max() >= H):
        raise ValueError(f"mask crop {c.shape} at origin {tuple(origin)} does not fit an image of shape {(H, W)}")
    flat = cols * H + rows
    if flat.size == 0:
        counts = [H * W]
    else:
        brk = np.flatnonzero(np.diff(flat) != 1)
        starts = np.concatenate([flat[:1], flat[brk + 1]])
        ends = np.concatenate([flat[brk], flat[-1:]]) + 1
        gaps = starts - np.concatenate([[0], ends[:-1]])
        tail = H * W - int(ends[-1])
        counts = np.stack([gaps, ends - starts], axis=1).ravel().tolist() + ([tail] if tail else [])
    r = mask_utils.frPyObjects({"size": [H, W], "counts": counts}, H, W)
    return {"size": [H, W], "counts": r["counts"].decode("ascii")}


def rle_from_mask(mask: np.ndarray) -> dict:
    """COCO compressed RLE of a full (H, W) mask (non-zero = inside): :func:`rle_from_crop`."""
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must be (H, W), got shape {m.shape}")
    return rle_from_crop(m, (0, 0), m.shape)


def _api(rle: dict) -> dict:
    """A compressed RLE with the bytes counts pycocotools' C functions take."""
    c = rle["counts"]
    return {"size": list(rle["size"]), "counts": c.encode("ascii") if isinstance(c, str) else c}


def segmentation_to_rle(seg, height: int, width: int) -> dict:
    """Any COCO segmentation of an (height, width) image (polygons, uncompressed RLE with a list
    of counts, compressed RLE with str or bytes counts) -> compressed RLE with str counts."""

    if isinstance(seg, list):
        r = mask_utils.merge(mask_utils.frPyObjects(seg, height, width))
    elif isinstance(seg, dict) and isinstance(seg.get("counts"), list):
        r = mask_utils.frPyObjects(seg, *seg["size"])
    elif isinstance(seg, dict) and isinstance(seg.get("counts"), (str, bytes)):
        r = _api(seg)
    else:
        raise ValueError(f"unreadable COCO segmentation {str(seg)[:60]!r}")
    c = r["counts"]
    return {"size": [int(v) for v in r["size"]], "counts": c.decode("ascii") if isinstance(c, bytes) else c}


def rle_to_mask(rle: dict) -> np.ndarray:
    """(H, W) bool mask of a compressed RLE (str or bytes counts)."""

    return mask_utils.decode(_api(rle)).astype(bool)


def rle_area(rle: dict) -> int:
    """Pixels inside a compressed RLE."""

    return int(mask_utils.area(_api(rle)))


def rle_iou(a: Sequence[dict], b: Sequence[dict]) -> np.ndarray:
    """(len(a), len(b)) mask IoU of compressed RLEs (pycocotools ``iou``, no crowd)."""

    if not a or not b:
        return np.zeros((len(a), len(b)))
    return np.asarray(mask_utils.iou([_api(r) for r in a], [_api(r) for r in b], [0] * len(b)), dtype=np.float64)


def rle_box(rle: dict) -> np.ndarray:
    """(4,) x0 y0 x1 y1 px (pixel-edge outline) of a non-empty compressed RLE; ValueError if empty."""

    if rle_area(rle) == 0:
        raise ValueError("ground-truth mask is empty")
    return box_from_coco(mask_utils.toBbox(_api(rle)))
