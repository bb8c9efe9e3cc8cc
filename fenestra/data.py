"""The data contracts every stage shares, written once (docs/DESIGN.md, "Data contracts").

- **Files**: written atomically by :mod:`fenestra.files` (temporary name, then rename), read by
  :mod:`fenestra.images` (any photo -> (H, W, 3) uint8 RGB; 16-bit instance PNG -> (H, W) **int32**).
- **A rendered view** (``image.png``, ``instances.png``, optional ``ignore.png``, ``view.json``):
  :func:`write_view` (atomic, ``view.json`` last), :func:`write_ignore` (add ignore regions to a
  view written before), :func:`check_view` (can a cached view be reused?) and :func:`read_view` ->
  :class:`View`.
- **Masks**: :class:`SparseMask` (a mask stored as its bounding crop), :func:`instance_masks`
  (every id of an instance map), COCO compressed RLE from a full mask or a crop at an origin
  (:func:`rle_from_mask`, :func:`rle_from_crop`: one encoder) and back (:func:`rle_to_mask`,
  :func:`segmentation_to_rle` for polygons and uncompressed RLE).
- **Boxes**, one convention: ``(x0, y0, x1, y1)`` px on the pixel-edge outline with pixel centres
  at integers (fenestra.conventions), so a mask over columns c0..c1 spans x0 = c0 - 0.5 to
  x1 = c1 + 0.5 and x1 - x0 is its width in px (:func:`mask_box`). COCO's ``bbox`` puts pixel
  edges at integers: ``[x0 + 0.5, y0 + 0.5, x1 - x0, y1 - y0]`` (:func:`box_to_coco`,
  :func:`box_from_coco`).
- **COCO ground truth** (:func:`gt_annotation`, :func:`coco_ground_truth`): windows, and
  **ignore regions** (``iscrowd = 1``: curtain-wall glazing, glazed doors, or a dataset's own
  crowd regions): a detection lying there counts neither as a true nor as a false positive.
- **COCO scoring** (:func:`coco_scores`): pycocotools' COCOeval, bbox and segm, its 12 summary
  statistics plus ``R50``, every value a **fraction in [0, 1]** (never percent), keys
  ``"<bbox|segm>_<stat>"`` with stat in :data:`SCORE_NAMES`.

Nothing here imports scenes/, renders/, pipeline/ or bench/: every stage may import it.
"""
from __future__ import annotations

import contextlib
import io
import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fenestra.errors import DatasetError
from fenestra.files import write_image, write_json
from fenestra.images import decode_file, read_image, read_instances

VIEW_FILES = ("image.png", "instances.png")  # every view; ignore.png only where view.json lists ignore regions
VIEW_KEYS = ("K", "width", "height", "R", "t", "windows")  # view.json keys every reader relies on
CATEGORIES = [{"id": 1, "name": "window"}]
COCO_STATS = ("AP", "AP50", "AP75", "AP_small", "AP_medium", "AP_large",
              "AR1", "AR10", "AR100", "AR_small", "AR_medium", "AR_large")  # COCOeval.stats, in order
SCORE_NAMES = COCO_STATS + ("R50",)  # R50: recall at IoU 0.5, all areas, 100 detections per image
IOU_TYPES = ("bbox", "segm")


# ---------------------------------------------------------------- files

def _instances_png(instances: np.ndarray, name: str) -> np.ndarray:
    """An (H, W) integer map as the uint16 a 16-bit PNG stores; ValueError naming bad ids."""
    a = np.asarray(instances)
    if a.ndim != 2 or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{name} must be an (H, W) integer map, got shape {a.shape}, dtype {a.dtype}")
    if a.size and (a.min() < 0 or a.max() > 65535):
        raise ValueError(f"{name} ids must be in [0, 65535] (16-bit PNG), got [{a.min()}, {a.max()}]")
    return a.astype(np.uint16)


# ---------------------------------------------------------------- rendered views

@dataclass(frozen=True, eq=False)
class View:
    """One rendered view's files, as :func:`read_view` reads them: the file contract's record
    (renders/ builds coco.json from it; the bench turns it into its labelled view).

    image: (H, W, 3) uint8 RGB. instances: (H, W) int32, window ``instance_id`` per pixel, 0 = none.
    meta: the view.json dict (K, width, height, R, t, distortion, renderer, seed, windows, ...).
    ignore: (H, W) int32 ignore-region id per pixel (0 = none; ids listed in ``meta["ignore"]``:
    curtain-wall glazing, glazed doors: neither window nor background), or None when the view
    records no ignore region.
    """

    image: np.ndarray
    instances: np.ndarray
    meta: dict
    ignore: np.ndarray | None = None

    @property
    def K(self) -> np.ndarray:
        """(3, 3) float64 intrinsics, px."""
        return np.asarray(self.meta["K"], dtype=np.float64)

    @property
    def windows(self) -> list[dict]:
        """view.json's per-window ground truth (id, instance_id, corners_px, ...)."""
        return self.meta["windows"]

    @property
    def ignore_regions(self) -> list[dict]:
        """view.json's ignore regions ({"id", "instance_id" (its value in ignore.png), "kind"})."""
        return self.meta.get("ignore", [])


def write_view(view_dir: str | Path, image: np.ndarray, instances: np.ndarray, meta: dict,
               ignore: np.ndarray | None = None) -> None:
    """Write one view: image.png (from (H, W, 3) uint8 RGB), instances.png (16-bit), ignore.png
    (16-bit, only when ``ignore`` is given: then ``meta["ignore"]`` must list its ids) and
    view.json (``meta`` plus ``files``: each PNG's byte size).

    Every file goes to a temporary name first and is renamed into place; view.json, the view's
    completion marker, is removed first and written last. A failed write raises OSError naming
    the file; bad shapes or ids raise ValueError.
    """
    view_dir = Path(view_dir)
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError(f"image must be (H, W, 3) uint8 RGB, got shape {img.shape}, dtype {img.dtype}")
    pngs = {"image.png": img, "instances.png": _instances_png(instances, "instances")}
    if ignore is not None:
        pngs["ignore.png"] = _instances_png(ignore, "ignore")
        listed = {int(r["instance_id"]) for r in meta.get("ignore", [])}
        present = set(np.unique(pngs["ignore.png"]).tolist()) - {0}
        if not present <= listed:
            raise ValueError(f"ignore map ids {sorted(present - listed)} are not listed in meta['ignore']")
    for name, a in pngs.items():
        if a.shape[:2] != img.shape[:2]:
            raise ValueError(f"{name}: shape {a.shape[:2]} != image {img.shape[:2]}")
    view_dir.mkdir(parents=True, exist_ok=True)
    (view_dir / "view.json").unlink(missing_ok=True)  # not complete until rewritten last
    for name, a in pngs.items():
        write_image(view_dir / name, a)
    meta = {**meta, "files": {name: (view_dir / name).stat().st_size for name in pngs}}
    write_json(view_dir / "view.json", meta)


def write_ignore(view_dir: str | Path, ignore: np.ndarray | None, regions: Sequence[dict]) -> None:
    """Record the ignore regions of a view already written (one rendered before its renderer drew
    them): ignore.png (16-bit, only when ``regions`` lists any; ``ignore`` (H, W) holds their
    ``instance_id`` values) and view.json's ``ignore`` (= regions) and ``files``, each atomically,
    view.json last. ValueError for a shape other than the view's or an unlisted id."""
    view_dir = Path(view_dir)
    meta = read_meta(view_dir)
    meta["ignore"] = [dict(r) for r in regions]
    files = dict(meta.get("files", {}))
    if regions:
        a = _instances_png(ignore, "ignore")
        if a.shape != (meta["height"], meta["width"]):
            raise ValueError(f"ignore map {a.shape} != view {view_dir}'s {(meta['height'], meta['width'])}")
        present = set(np.unique(a).tolist()) - {0}
        listed = {int(r["instance_id"]) for r in regions}
        if not present <= listed:
            raise ValueError(f"ignore map ids {sorted(present - listed)} are not listed in regions")
        write_image(view_dir / "ignore.png", a)
        files["ignore.png"] = (view_dir / "ignore.png").stat().st_size
    else:
        files.pop("ignore.png", None)
    write_json(view_dir / "view.json", {**meta, "files": files})


def _view_pngs(meta: dict) -> tuple[str, ...]:
    return VIEW_FILES + (("ignore.png",) if meta.get("ignore") else ())


def check_view(view_dir: str | Path) -> str | None:
    """Why a cached view folder cannot be reused (None if it can): view.json missing or
    unreadable, a PNG missing, of another byte size than recorded, or not decodable at the
    recorded size."""
    view_dir = Path(view_dir)
    try:
        meta = json.loads((view_dir / "view.json").read_text())
    except FileNotFoundError:
        return "no view.json"
    except (OSError, ValueError) as e:
        return f"unreadable view.json ({e})"
    sizes = meta.get("files", {})
    for name in _view_pngs(meta):
        p = view_dir / name
        if not p.is_file():
            return f"{name} missing"
        if name in sizes and p.stat().st_size != sizes[name]:
            return f"{name} is {p.stat().st_size} bytes, view.json recorded {sizes[name]}"
        try:
            img = decode_file(p, cv2.IMREAD_COLOR if name == "image.png" else cv2.IMREAD_UNCHANGED, name)
        except DatasetError:
            img = None
        if img is None or img.shape[:2] != (meta.get("height"), meta.get("width")):
            return f"{name} does not decode to {meta.get('width')}x{meta.get('height')} px"
    return None


def read_meta(view_dir: str | Path) -> dict:
    """A view folder's view.json; DatasetError naming the folder or the missing keys."""
    p = Path(view_dir) / "view.json"
    try:
        meta = json.loads(p.read_text())
    except FileNotFoundError:
        raise DatasetError(f"{view_dir}: no view.json (not a rendered view folder)") from None
    except (OSError, ValueError) as e:
        raise DatasetError(f"{p}: unreadable ({e})") from e
    missing = [k for k in VIEW_KEYS if k not in meta]
    if missing:
        raise DatasetError(f"{p} lacks key(s) {missing}")
    return meta


def read_view(view_dir: str | Path) -> View:
    """The :class:`View` of a view folder (DESIGN.md data contract); DatasetError naming a
    missing or damaged file (delete the view to re-render it)."""
    d = Path(view_dir)
    meta = read_meta(d)
    image, instances = read_image(d / "image.png"), read_instances(d / "instances.png")
    ignore = read_instances(d / "ignore.png") if meta.get("ignore") else None
    for name, a in (("image.png", image), ("instances.png", instances), ("ignore.png", ignore)):
        if a is not None and a.shape[:2] != (meta["height"], meta["width"]):
            raise DatasetError(f"{d / name} is {a.shape[1]}x{a.shape[0]} px, view.json says "
                               f"{meta['width']}x{meta['height']}")
    return View(image, instances, meta, ignore)


# ---------------------------------------------------------------- boxes

def mask_box(mask: np.ndarray, origin: tuple[int, int] = (0, 0)) -> np.ndarray:
    """(4,) float64 x0, y0, x1, y1 px of a non-empty mask (non-zero = inside) on the pixel-edge
    outline (pixel centres at integers; x1 - x0 = width in px). origin (x0, y0): image pixel of
    the mask's [0, 0] when it is a crop. ValueError for an empty mask."""
    ys, xs = np.nonzero(np.asarray(mask))
    if xs.size == 0:
        raise ValueError("mask_box: empty mask")
    ox, oy = origin
    return np.array([xs.min() + ox - 0.5, ys.min() + oy - 0.5, xs.max() + ox + 0.5, ys.max() + oy + 0.5],
                    dtype=np.float64)


def box_to_coco(box) -> list[float]:
    """(x0, y0, x1, y1) px (pixel centres at integers) -> COCO bbox [x, y, w, h] (edges at integers)."""
    x0, y0, x1, y1 = (float(v) for v in box)
    return [x0 + 0.5, y0 + 0.5, x1 - x0, y1 - y0]


def box_from_coco(bbox) -> np.ndarray:
    """COCO / YOLO bbox [x, y, w, h] (pixel edges at integers) -> (4,) x0 y0 x1 y1 px (centres at integers)."""
    x, y, w, h = (float(v) for v in bbox)
    return np.array([x - 0.5, y - 0.5, x + w - 0.5, y + h - 0.5])


def yolo_boxes(text: str, width: int, height: int, classes: tuple[int, ...], where: str) -> list[np.ndarray]:
    """Boxes (4,) x0 y0 x1 y1 px (fenestra convention) of the lines ``class cx cy w h``
    (normalised to the image size) whose class is in ``classes``."""
    out = []
    for k, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        parts = line.split()
        try:
            c, cx, cy, bw, bh = int(float(parts[0])), *(float(v) for v in parts[1:5])
        except (ValueError, IndexError) as e:
            raise DatasetError(f"{where}:{k}: bad YOLO line {line!r}") from e
        if c in classes:
            out.append(box_from_coco([(cx - bw / 2) * width, (cy - bh / 2) * height, bw * width, bh * height]))
    return out


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


def rle_from_crop(crop: np.ndarray, origin: tuple[int, int], shape: tuple[int, int]) -> dict:
    """COCO compressed RLE ``{"size": [H, W], "counts": str}`` of the (H, W) image mask given as a
    crop (h, w) (non-zero = inside) whose pixel [0, 0] is image pixel origin (x0, y0).

    The one RLE encoder: runs in column-major order, starting with background, built from the
    crop's pixels without allocating the full image; identical to pycocotools' ``encode`` of the
    full mask. ValueError when a pixel of the mask falls outside the image.
    """
    from pycocotools import mask as mask_utils  # noqa: PLC0415

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
    from pycocotools import mask as mask_utils  # noqa: PLC0415

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
    from pycocotools import mask as mask_utils  # noqa: PLC0415

    return mask_utils.decode(_api(rle)).astype(bool)


def rle_area(rle: dict) -> int:
    """Pixels inside a compressed RLE."""
    from pycocotools import mask as mask_utils  # noqa: PLC0415

    return int(mask_utils.area(_api(rle)))


def rle_iou(a: Sequence[dict], b: Sequence[dict]) -> np.ndarray:
    """(len(a), len(b)) mask IoU of compressed RLEs (pycocotools ``iou``, no crowd)."""
    from pycocotools import mask as mask_utils  # noqa: PLC0415

    if not a or not b:
        return np.zeros((len(a), len(b)))
    return np.asarray(mask_utils.iou([_api(r) for r in a], [_api(r) for r in b], [0] * len(b)), dtype=np.float64)


# ---------------------------------------------------------------- COCO ground truth and results

def gt_annotation(image: str | int, rle: dict | None = None, box=None, area: float | None = None,
                  ignore: bool = False, **extra) -> dict:
    """One ground-truth object of image ``image`` (its key in :func:`coco_ground_truth`).

    A window, or with ``ignore=True`` an ignore region (COCO ``iscrowd = 1``: a detection inside
    it counts neither way). rle: its mask (compressed RLE) or None (box-only labels: no mask AP);
    box: (4,) x0 y0 x1 y1 px, pixel-edge outline (default: the RLE's); area: px (default: the
    RLE's pixel count, else the box's area). extra: more keys, kept as they are (e.g. window_id).
    """
    if rle is None and box is None:
        raise ValueError(f"ground-truth object of image {image!r} has neither mask nor box")
    if box is None:
        box = _rle_box(rle)
    bbox = box_to_coco(box)
    if area is None:
        area = rle_area(rle) if rle is not None else bbox[2] * bbox[3]
    out = {"image": image, "iscrowd": int(bool(ignore)), "bbox": bbox, "area": float(area)}
    if rle is not None:
        out["segmentation"] = rle
    return {**out, **extra}


def _rle_box(rle: dict) -> np.ndarray:
    from pycocotools import mask as mask_utils  # noqa: PLC0415

    if rle_area(rle) == 0:
        raise ValueError("ground-truth mask is empty")
    return box_from_coco(mask_utils.toBbox(_api(rle)))


def coco_ground_truth(images: Sequence[tuple[str, int, int]], annotations: Iterable[dict],
                      first_image_id: int = 1) -> dict:
    """A COCO ground-truth dict: ``{"images", "annotations", "categories"}``.

    images: (key, height, width) per image, in order: ids first_image_id, first_image_id + 1, ...,
    ``file_name`` = key. annotations: :func:`gt_annotation` dicts in order (ids 1, 2, ...; category
    1, "window"); their ``image`` key names the image. ValueError naming an unknown or duplicate key.
    """
    ids: dict[str, int] = {}
    imgs = []
    for key, h, w in images:
        if key in ids:
            raise ValueError(f"image key {key!r} given twice")
        ids[key] = first_image_id + len(imgs)
        imgs.append({"id": ids[key], "file_name": key, "height": int(h), "width": int(w)})
    anns = []
    for a in annotations:
        a = dict(a)
        key = a.pop("image")
        if key not in ids:
            raise ValueError(f"annotation of unknown image {key!r}")
        anns.append({"id": len(anns) + 1, "image_id": ids[key], "category_id": CATEGORIES[0]["id"], **a})
    return {"images": imgs, "annotations": anns, "categories": [dict(c) for c in CATEGORIES]}


def view_annotations(view: View, image: str | int, masks: Sequence[SparseMask] | None = None) -> list[dict]:
    """The ground truth of one rendered view for :func:`coco_ground_truth`, image key ``image``:
    a :func:`gt_annotation` per window with visible pixels (keys ``window_id`` and
    ``visible_fraction`` added), in view.json order, then one ignore region (``iscrowd``, keys
    ``ignore_id``, ``kind``) per listed id present in ignore.png.

    masks: the windows' masks, one per view.json window in order (:func:`instance_masks` of the
    view's instances), when the caller has them already.
    """
    wins = view.windows
    if masks is None:
        masks = instance_masks(view.instances, [int(w["instance_id"]) for w in wins])
    if len(masks) != len(wins):
        raise ValueError(f"{len(masks)} masks for {len(wins)} windows")
    out = [gt_annotation(image, m.rle(), m.box(), m.area, window_id=w["id"],
                         visible_fraction=w.get("visible_fraction"))
           for w, m in zip(wins, masks) if m.area]
    regions = view.ignore_regions
    if regions:
        for r, m in zip(regions, instance_masks(view.ignore, [int(r["instance_id"]) for r in regions])):
            if m.area:
                out.append(gt_annotation(image, m.rle(), m.box(), m.area, ignore=True, ignore_id=r["id"],
                                         kind=r.get("kind")))
    return out


def complete_coco(coco: dict) -> dict:
    """A COCO dict (e.g. a foreign coco.json) made safe for :func:`coco_scores`: annotation ids
    and ``iscrowd`` filled in, uncompressed RLE compressed, missing areas and bboxes computed."""
    sizes = {im["id"]: (im.get("height"), im.get("width")) for im in coco["images"]}
    anns = []
    for i, a in enumerate(coco.get("annotations", [])):
        a = {"id": i + 1, "iscrowd": 0, **a}
        seg = a.get("segmentation")
        if isinstance(seg, dict) and isinstance(seg.get("counts"), list):
            a["segmentation"] = segmentation_to_rle(seg, *sizes.get(a["image_id"], seg["size"]))
        if seg is not None and ("area" not in a or "bbox" not in a):
            rle = segmentation_to_rle(a["segmentation"], *sizes[a["image_id"]])
            a.setdefault("area", float(rle_area(rle)))
            a.setdefault("bbox", box_to_coco(_rle_box(rle)))
        anns.append(a)
    return {"images": coco["images"], "annotations": anns,
            "categories": coco.get("categories") or [dict(c) for c in CATEGORIES]}


def coco_result(image: str | int, score: float, box, rle: dict | None = None) -> dict:
    """One detection for :func:`coco_scores`: image (key or id of the ground truth's image),
    score, box (4,) x0 y0 x1 y1 px on the pixel-edge outline, rle (its mask) or None."""
    out = {"image": image, "score": float(score), "bbox": box_to_coco(box)}
    if rle is not None:
        out["segmentation"] = rle
    return out


def _nan_scores(iou_type: str) -> dict[str, float]:
    return {f"{iou_type}_{k}": float("nan") for k in SCORE_NAMES}


def coco_scores(gt: dict, results: Sequence[dict], iou_types: Sequence[str] = IOU_TYPES) -> dict[str, float]:
    """COCO evaluation (pycocotools COCOeval) of detections against a ground-truth dict.

    gt: :func:`coco_ground_truth` (or :func:`complete_coco`) dict; results: :func:`coco_result`
    dicts (``image`` an image key = file_name, or an image id). Returns ``{"<iou>_<stat>": v}`` for
    each iou type and stat in :data:`SCORE_NAMES` (the 12 COCOeval statistics and R50), every v a
    fraction in [0, 1]. NaN where a value is undefined: where COCOeval reports -1 (no window in an
    area range), every key when ``gt`` holds no window, segm keys when a window has no mask
    (box-only labels). 0.0 for every key when there are windows but no detections. Ignore regions
    (``iscrowd = 1``) follow COCO: a detection matched to one counts neither way.
    """
    from pycocotools.coco import COCO  # noqa: PLC0415
    from pycocotools.cocoeval import COCOeval  # noqa: PLC0415

    bad = [t for t in iou_types if t not in IOU_TYPES]
    if bad:
        raise ValueError(f"iou_types must be among {IOU_TYPES}, got {bad}")
    windows = [a for a in gt["annotations"] if not a.get("iscrowd", 0)]
    by_name = {im.get("file_name"): im["id"] for im in gt["images"]}
    cat = gt["categories"][0]["id"] if gt.get("categories") else CATEGORIES[0]["id"]
    res = []
    for r in results:
        key = r.get("image", r.get("image_id"))
        image_id = by_name.get(key) if isinstance(key, str) else key
        if image_id is None:
            raise ValueError(f"detection of unknown image {key!r}")
        res.append({"image_id": image_id, "category_id": cat, "score": r["score"], "bbox": list(r["bbox"]),
                    **({"segmentation": r["segmentation"]} if r.get("segmentation") is not None else {})})
    out: dict[str, float] = {}
    for iou_type in iou_types:
        if not windows or (iou_type == "segm" and any("segmentation" not in a for a in windows)):
            out.update(_nan_scores(iou_type))
            continue
        if not res:
            out.update({f"{iou_type}_{k}": 0.0 for k in SCORE_NAMES})
            continue
        anns = [a if "segmentation" in a else {**a, "segmentation": _box_polygon(a["bbox"])}
                for a in gt["annotations"]]  # a box-only ignore region: its box as the mask
        with contextlib.redirect_stdout(io.StringIO()):
            coco_gt = COCO()
            coco_gt.dataset = {"images": gt["images"], "annotations": anns, "categories": gt["categories"]}
            coco_gt.createIndex()
            coco_dt = coco_gt.loadRes([dict(r) for r in res])  # loadRes adds keys: give it copies
            ev = COCOeval(coco_gt, coco_dt, iou_type)
            ev.evaluate()
            ev.accumulate()
            ev.summarize()
        r50 = float(ev.eval["recall"][0, 0, 0, -1])  # [IoU 0.5, category, area all, maxDets 100]
        out.update({f"{iou_type}_{k}": (float(v) if v >= 0 else float("nan"))
                    for k, v in zip(SCORE_NAMES, [*np.asarray(ev.stats), r50])})
    return out


def _box_polygon(bbox) -> list[list[float]]:
    x, y, w, h = bbox
    return [[x, y, x, y + h, x + w, y + h, x + w, y]]
