"""One-to-one matching of detections to ground-truth windows by mask IoU (Hungarian).

A detection and a ground-truth window match when the assignment that maximises the total IoU
pairs them and their IoU is at least ``TOL.match_iou``. Ground-truth windows left unmatched are
"missed"; detections left unmatched are false positives.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from fenestra.conventions import TOL


@dataclass(frozen=True)
class Matching:
    """Result of :func:`match`.

    pairs: (det_index, gt_index, iou) for each accepted match, sorted by gt_index.
    missed_gt: indices of ground-truth windows without a detection.
    false_positives: indices of detections without a ground-truth window.
    """

    pairs: tuple[tuple[int, int, float], ...]
    missed_gt: tuple[int, ...]
    false_positives: tuple[int, ...]

    def det_for_gt(self) -> dict[int, tuple[int, float]]:
        """{gt_index: (det_index, iou)} of the accepted matches."""
        return {g: (d, iou) for d, g, iou in self.pairs}


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
        image of ``shape`` (H, W): a Detection's (mask, origin); a full mask has origin (0, 0)."""
        s = cls.from_dense(crop)
        x0, y0 = int(origin[0]), int(origin[1])
        r0, c0 = s.r0 + y0, s.c0 + x0
        if s.area and (r0 < 0 or c0 < 0 or r0 + s.crop.shape[0] > shape[0] or c0 + s.crop.shape[1] > shape[1]):
            raise ValueError(f"mask crop {crop.shape} at origin {origin} does not fit an image of shape {tuple(shape)}")
        return cls(s.crop, r0, c0, tuple(shape), s.area)

    def rle(self) -> dict:
        """COCO RLE of the full-image mask ({"size": [H, W], "counts": str}), built from the crop
        without allocating the full image: runs in column-major order, starting with background."""
        from pycocotools import mask as mask_utils  # noqa: PLC0415

        H, W = self.shape
        cols, rows = np.nonzero(self.crop.T)  # column by column: ascending column-major index
        flat = (cols + self.c0).astype(np.int64) * H + rows + self.r0
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

    def dense(self) -> np.ndarray:
        """The full (H, W) bool mask (allocates H x W: for export and RLE only)."""
        out = np.zeros(self.shape, dtype=bool)
        out[self.r0:self.r1, self.c0:self.c1] = self.crop
        return out


def instance_masks(instances: np.ndarray, ids: list[int] | np.ndarray) -> list[SparseMask]:
    """SparseMask of each id of an instance map (H, W) int (0 = none), in the order of ``ids``.

    One pass over the map finds every id's box (scipy.ndimage.find_objects); each mask is then
    compared within its box only. An id absent from the map gives an empty mask.
    """
    from scipy.ndimage import find_objects  # noqa: PLC0415

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


def _sparse(masks: list) -> list[SparseMask]:
    return [m if isinstance(m, SparseMask) else SparseMask.from_dense(m) for m in masks]


def iou_matrix(det_masks: list, gt_masks: list) -> np.ndarray:
    """Mask IoU of every detection with every ground-truth window.

    det_masks: D masks, gt_masks: G masks, each an (H, W) bool array or a :class:`SparseMask`, all
    of one image shape. Returns (D, G) float64 in [0, 1] (the ratio rounded to float32 first).
    Only pairs whose boxes overlap are compared, on the overlap of their crops: the cost grows with
    the windows in view, not with image area x window count.
    """
    if not det_masks or not gt_masks:
        return np.zeros((len(det_masks), len(gt_masks)))
    dets, gts = _sparse(det_masks), _sparse(gt_masks)
    shape = gts[0].shape
    for name, masks in (("det_masks", dets), ("gt_masks", gts)):
        for i, m in enumerate(masks):
            if m.shape != shape:
                raise ValueError(f"{name}[{i}] has shape {m.shape}, expected {shape}")
    db = np.array([(d.r0, d.r1, d.c0, d.c1) for d in dets]).reshape(-1, 4)
    gb = np.array([(g.r0, g.r1, g.c0, g.c1) for g in gts]).reshape(-1, 4)
    overlap = ((np.maximum(db[:, None, 0], gb[None, :, 0]) < np.minimum(db[:, None, 1], gb[None, :, 1]))
               & (np.maximum(db[:, None, 2], gb[None, :, 2]) < np.minimum(db[:, None, 3], gb[None, :, 3])))
    inter = np.zeros((len(dets), len(gts)), dtype=np.int64)
    for i, j in zip(*np.nonzero(overlap)):
        d, g = dets[i], gts[j]
        r0, r1 = max(d.r0, g.r0), min(d.r1, g.r1)
        c0, c1 = max(d.c0, g.c0), min(d.c1, g.c1)
        inter[i, j] = np.count_nonzero(d.crop[r0 - d.r0:r1 - d.r0, c0 - d.c0:c1 - d.c0]
                                       & g.crop[r0 - g.r0:r1 - g.r0, c0 - g.c0:c1 - g.c0])
    union = (np.array([d.area for d in dets])[:, None] + np.array([g.area for g in gts])[None, :]
             - inter)
    # float32 ratio: the figures of the dense float32 implementation this replaced, bit for bit
    ratio = inter.astype(np.float32) / np.maximum(union, 1).astype(np.float32)
    return np.where(union > 0, ratio, np.float32(0.0)).astype(np.float64)


def match(iou: np.ndarray, min_iou: float = TOL.match_iou) -> Matching:
    """Hungarian one-to-one assignment on an IoU matrix (D, G); keep pairs with IoU >= min_iou."""
    iou = np.asarray(iou, dtype=np.float64)
    if iou.ndim != 2:
        raise ValueError(f"iou must be a 2-D (detections, gt) matrix, got shape {iou.shape}")
    if not 0.0 < min_iou <= 1.0:
        raise ValueError(f"min_iou must be in (0, 1], got {min_iou}")
    D, G = iou.shape
    pairs = []
    if D and G:
        rows, cols = linear_sum_assignment(-iou)
        pairs = [(int(r), int(c), float(iou[r, c])) for r, c in zip(rows, cols)
                 if iou[r, c] >= min_iou]
    pairs.sort(key=lambda p: p[1])
    used_d = {p[0] for p in pairs}
    used_g = {p[1] for p in pairs}
    return Matching(pairs=tuple(pairs),
                    missed_gt=tuple(g for g in range(G) if g not in used_g),
                    false_positives=tuple(d for d in range(D) if d not in used_d))


def match_masks(det_masks: list, gt_masks: list,
                min_iou: float = TOL.match_iou) -> Matching:
    """:func:`match` on :func:`iou_matrix` of the given masks."""
    return match(iou_matrix(det_masks, gt_masks), min_iou)
