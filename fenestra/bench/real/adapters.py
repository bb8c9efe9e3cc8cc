"""Real-dataset adapters: a folder in a published format -> LabelledViews (bench.views).

    ADAPTERS: Registry("dataset format"): coco, yolo, labelmap, curtainwall (Adapter entries)
    views = list(ADAPTERS["coco"](Path("my_photos"), category="window"))

Every adapter takes the dataset folder and keyword options (the profile's ``options`` table) and
yields one LabelledView per photo, sorted by file name, with exactly the ground truth the format
carries (see each reader). Coordinates are converted from the format's pixel-edge convention
(pixel (0, 0) covers [0, 1]^2) to fenestra's (pixel centres at integers) by subtracting 0.5.

Ground truth is validated, never silently bent: a problem that makes the labels wrong (an
annotation of an unknown image, duplicate ids, a malformed polygon or RLE, a box outside its
photo, a stated size that is not the decoded photo's, a path leading outside the dataset
folder, a file that is not a regular file, JSON over LIMITS.max_json_bytes) is a DatasetError
naming the file, entry and field. A label that can be left out without changing the others (a
YOLO box entirely off its photo, a label file without a photo, a FIFO among the photos) is
dropped and recorded in the ``refused`` list an adapter takes (a stderr warning when None).
``check_dataset`` (``fenestra check-data DIR --format F``) reports both without raising.
"""
from __future__ import annotations

import math
import os
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage

from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra.conventions import LIMITS
from fenestra.registry import Registry
from fenestra.data import DatasetError, SparseMask, box_from_coco, rle_to_mask, segmentation_to_rle
from fenestra.images import decode_file, read_image
from fenestra.userfiles import inside, is_regular, read_json, regular_file
from fenestra.pipeline.io import Camera, check_distortion, photo_orientation, read_camera, undistort_photo
from fenestra.pipeline.quad import order_corners

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
EDGE_TO_CENTRE = 0.5  # format coordinates (pixel edges at integers) -> fenestra (centres at integers)
OUTSIDE_TOL_PX = 1.0  # a label may overhang the photo by this much (rounding); more is an error

# Glass Curtain Wall Installation Dataset (B. Johns et al. 2023): calibration for 1536 x 2048 px
# photos (user guide; OpenCV, pixel centres at integers) and the glass pane size.
CURTAIN_SIZE_PX = (1536, 2048)
CURTAIN_K = ((1821.04993399032, 0.0, 740.82871031754), (0.0, 1817.92066001349, 1018.94855509992),
             (0.0, 0.0, 1.0))
CURTAIN_DISTORTION = (-0.1552775701035, 0.0472686081157939, 0.0, 0.0, 0.0)
CURTAIN_PANE_M = (0.0932, 0.1432)  # glass pane width, height (m, 1:25 model)
CURTAIN_MIN_AREA_FRAC = 20000 / (1536 * 2048)  # smaller glass components are not panes


def _refuse(refused: list[str] | None, message: str) -> None:
    """Record a label or file left out (``refused`` list), or warn on stderr when nobody collects."""
    if refused is None:
        print(f"warning: {message}", file=sys.stderr)
    else:
        refused.append(message)


def _images(folder: Path, refused: list[str] | None = None) -> list[Path]:
    """Photos directly in ``folder`` (jpg/jpeg/png regular files inside it), sorted; a FIFO,
    device or symlink leading outside is refused (recorded). DatasetError for an empty folder."""
    if not folder.is_dir():
        raise FileNotFoundError(f"image folder not found: {folder}")
    out = []
    for p in sorted(q for q in folder.iterdir() if q.suffix.lower() in IMAGE_SUFFIXES):
        try:
            inside(folder, p.name, f"{folder}")
        except DatasetError as e:
            _refuse(refused, f"{p}: {e}; skipped")
            continue
        if is_regular(p):
            out.append(p)
        else:
            _refuse(refused, f"{p}: not a regular file (a folder, FIFO or device); skipped")
    if not out:
        raise DatasetError(f"no .jpg/.png photos in {folder}")
    return out


def touches_border(mask: np.ndarray) -> bool:
    """True if a bool mask (H, W) has a pixel in the first/last row or column."""
    m = np.asarray(mask, dtype=bool)
    return bool(m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any())


@dataclass(frozen=True, eq=False)
class Component:
    """One connected component as its bounding crop: rows r0:r0+crop.shape[0], columns
    c0:c0+crop.shape[1] of an (H, W) image (``shape``); crop: bool."""

    crop: np.ndarray
    r0: int
    c0: int
    shape: tuple[int, int]

    def sparse(self) -> SparseMask:
        """The component as a SparseMask (its crop: no full-frame mask is ever built)."""
        return SparseMask(crop=self.crop, r0=self.r0, c0=self.c0, shape=self.shape, area=int(self.crop.sum()))

    @property
    def touches_border(self) -> bool:
        h, w = self.crop.shape
        return bool((self.r0 == 0 and self.crop[0].any()) or (self.c0 == 0 and self.crop[:, 0].any())
                    or (self.r0 + h == self.shape[0] and self.crop[-1].any())
                    or (self.c0 + w == self.shape[1] and self.crop[:, -1].any()))


def components(binary: np.ndarray, min_area_px: float = 0.0, where: str = "label map",
               max_count: int | None = None) -> list[Component]:
    """4-connected components of a bool image (H, W) with at least ``min_area_px`` pixels, as
    bounding crops (scipy.ndimage.label + find_objects: memory grows with the components' boxes,
    never one full-frame mask each), ordered by their first pixel (row-major). More than
    ``max_count`` (default LIMITS.max_windows_per_photo) is a DatasetError, raised before any
    crop is built."""
    max_count = LIMITS.max_windows_per_photo if max_count is None else max_count
    b = np.asarray(binary, dtype=bool)
    lab, n = ndimage.label(b)  # 4-connectivity (the default structure)
    if n == 0:
        return []
    areas = np.bincount(lab.reshape(-1), minlength=n + 1)[1:]
    keep = np.flatnonzero(areas >= min_area_px) + 1
    if len(keep) > max_count:
        raise DatasetError(f"{where}: {len(keep)} window components, more than the {max_count} per photo "
                           "(fenestra.conventions.LIMITS.max_windows_per_photo)")
    slices = ndimage.find_objects(lab)
    out = []
    for i in keep:
        rs, cs = slices[i - 1]
        crop = lab[rs, cs] == i
        out.append(Component(crop, rs.start, cs.start, b.shape))
    # first pixel in row-major order: its row is r0; its column the first True in that crop row
    return sorted(out, key=lambda c: (c.r0, c.c0 + int(np.argmax(c.crop[0]))))


def quad_from_polygon(poly: list[float]) -> np.ndarray | None:
    """(4, 2) TL TR BR BL px (fenestra convention) of a 4-vertex COCO polygon [x1, y1, ...] (pixel
    edges at integers); None for any other vertex count (the quad is then missing, not fitted)."""
    p = np.asarray(poly, dtype=np.float64)
    if p.size != 8:
        return None
    return order_corners(p.reshape(4, 2) - EDGE_TO_CENTRE)


# ---------------------------------------------------------------- COCO: validation

def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _is_id(v) -> bool:
    return isinstance(v, (int, str)) and not isinstance(v, bool)


def _list_of_dicts(doc: dict, key: str, where: str, problems: list[str]) -> list[dict]:
    """doc[key] if a list of objects (missing: []); a problem per bad entry (those are skipped)."""
    v = doc.get(key, [])
    if not isinstance(v, list):
        problems.append(f"{where}: '{key}' must be a list, got {type(v).__name__}")
        return []
    out = []
    for i, x in enumerate(v):
        if isinstance(x, dict):
            out.append(x)
        else:
            problems.append(f"{where}: {key}[{i}] must be an object, got {type(x).__name__}")
    return out


def _unique_ids(items: list[dict], key: str, where: str, problems: list[str], required: bool = True) -> set:
    """The ids of ``items``; a problem per missing/ill-typed or duplicate id."""
    seen: dict = {}
    for i, x in enumerate(items):
        if "id" not in x:
            if required:
                problems.append(f"{where}: {key}[{i}] has no 'id'")
            continue
        if not _is_id(x["id"]):
            problems.append(f"{where}: {key}[{i}] 'id' must be an integer or string, got {x['id']!r}")
        elif x["id"] in seen:
            problems.append(f"{where}: {key}[{i}] 'id' {x['id']!r} duplicates {key}[{seen[x['id']]}]")
        else:
            seen[x["id"]] = i
    return set(seen)


def _image_problems(img: dict, i: int, where: str) -> list[str]:
    """Problems of one COCO image entry (file_name a safe relative path; width/height positive ints)."""
    out = []
    name = img.get("file_name")
    if not isinstance(name, str) or not name:
        out.append(f"{where}: images[{i}] needs a 'file_name' string, got {name!r}")
    elif os.path.isabs(name) or ".." in Path(name).parts:
        out.append(f"{where}: images[{i}] file_name {name!r} must be a path inside the dataset folder "
                   "(relative, no '..')")
    for k in ("width", "height"):
        v = img.get(k)
        if v is not None and not (isinstance(v, int) and not isinstance(v, bool) and v > 0):
            out.append(f"{where}: images[{i}] '{k}' must be a positive integer (px), got {v!r}")
    return out


def _polygon_problems(seg: list, what: str) -> list[str]:
    """Problems of a COCO polygon list [[x1, y1, x2, y2, ...], ...]."""
    out = []
    for j, poly in enumerate(seg):
        if not isinstance(poly, list) or not all(_is_num(v) for v in poly):
            out.append(f"{what}: segmentation[{j}] must be a list of finite numbers")
        elif len(poly) % 2:
            out.append(f"{what}: segmentation[{j}] has an odd number of coordinates ({len(poly)})")
        elif len(poly) < 6:
            out.append(f"{what}: segmentation[{j}] has {len(poly) // 2} point(s); a polygon needs at least 3")
    return out


def _segmentation_problems(seg, what: str, size: tuple | None) -> list[str]:
    """Problems of a COCO segmentation (polygons or RLE); size: the image's stated (H, W) or None."""
    if seg is None or seg == []:
        return []
    if isinstance(seg, list):
        return _polygon_problems(seg, what)
    if not isinstance(seg, dict):
        return [f"{what}: segmentation must be polygons (a list) or RLE (an object), got {type(seg).__name__}"]
    sz, counts = seg.get("size"), seg.get("counts")
    if not (isinstance(sz, list) and len(sz) == 2 and all(isinstance(v, int) and not isinstance(v, bool) and v > 0
                                                         for v in sz)):
        return [f"{what}: RLE 'size' must be [height, width] positive integers, got {sz!r}"]
    if not (isinstance(counts, str) or (isinstance(counts, list) and all(isinstance(v, int) and v >= 0 for v in counts))):
        return [f"{what}: RLE 'counts' must be a string or a list of non-negative integers"]
    if size is not None and tuple(sz) != tuple(size):
        return [f"{what}: RLE size {sz} != the image's stated [height, width] {list(size)}"]
    return []


def _annotation_problems(a: dict, i: int, where: str, images: dict) -> list[str]:
    """Problems of one COCO annotation: its image resolved, geometry well-formed, extension keys typed."""
    what = f"{where}: annotations[{i}] (id {a.get('id')!r})"
    if "image_id" not in a:
        return [f"{what} has no 'image_id'"]
    img = images.get(a["image_id"]) if _is_id(a["image_id"]) else None
    if img is None:
        return [f"{what}: image_id {a['image_id']!r} matches no image"]
    out = []
    if not _is_id(a.get("category_id")):
        out.append(f"{what}: 'category_id' must be an integer or string, got {a.get('category_id')!r}")
    bbox = a.get("bbox") or None  # [] as absent
    if bbox is not None and not (isinstance(bbox, list) and len(bbox) == 4 and all(_is_num(v) for v in bbox)
                                 and bbox[2] > 0 and bbox[3] > 0):
        out.append(f"{what}: bbox must be [x, y, w, h] finite with w, h > 0, got {bbox!r}")
    stated = (img.get("height"), img.get("width"))
    out += _segmentation_problems(a.get("segmentation"), what, stated if all(_is_num(v) for v in stated) else None)
    if bbox is None and not a.get("segmentation"):
        out.append(f"{what} has neither 'bbox' nor 'segmentation'")
    size = a.get("size_m")
    if size is not None and not (isinstance(size, list) and len(size) == 2 and all(_is_num(v) and v > 0 for v in size)):
        out.append(f"{what}: size_m must be [width, height] positive metres, got {size!r}")
    aspect = a.get("aspect")
    if aspect is not None and not (_is_num(aspect) and aspect > 0):
        out.append(f"{what}: aspect must be a positive number (width / height), got {aspect!r}")
    for k in ("partial", "iscrowd"):
        if a.get(k) not in (None, True, False, 0, 1):
            out.append(f"{what}: '{k}' must be true/false or 0/1, got {a[k]!r}")
    return out


def coco_problems(doc, where: str) -> list[str]:
    """Every structural problem of a parsed COCO instances file, one line each (file, entry, field):
    top level an object; images with unique ids and safe file names; categories with ids;
    annotations resolving to an image, with well-formed bbox/polygons/RLE and extension keys."""
    if not isinstance(doc, dict):
        return [f"{where}: the top level must be a JSON object with 'images' and 'annotations', "
                f"got {type(doc).__name__}"]
    problems: list[str] = []
    imgs = _list_of_dicts(doc, "images", where, problems)
    cats = _list_of_dicts(doc, "categories", where, problems)
    anns = _list_of_dicts(doc, "annotations", where, problems)
    ids = _unique_ids(imgs, "images", where, problems)
    _unique_ids(cats, "categories", where, problems)
    _unique_ids(anns, "annotations", where, problems, required=False)
    stems: dict = {}  # a view is named by its photo's stem: two photos may not share one
    for i, img in enumerate(imgs):
        problems += _image_problems(img, i, where)
        n = img.get("file_name")
        if isinstance(n, str) and Path(n).stem in stems:
            problems.append(f"{where}: images[{i}] file_name {n!r} has the name {Path(n).stem!r} of "
                            f"images[{stems[Path(n).stem]}] (views are named by it)")
        if isinstance(n, str):
            stems.setdefault(Path(n).stem, i)
    by_id = {img["id"]: img for img in imgs if "id" in img and img["id"] in ids}
    for i, a in enumerate(anns):
        problems += _annotation_problems(a, i, where, by_id)
    return problems


# ---------------------------------------------------------------- COCO: reading

def _coco_mask(seg, h: int, w: int) -> SparseMask | None:
    """The mask of a COCO segmentation (polygons, RLE or uncompressed RLE) of an (h, w) image;
    None if absent or empty."""
    if not seg:
        return None
    m = rle_to_mask(segmentation_to_rle(seg, h, w))
    return SparseMask.from_dense(m) if m.any() else None


def _check_inside(box: np.ndarray, w: int, h: int, what: str) -> None:
    """DatasetError if a box (x0, y0, x1, y1) px (fenestra convention) leaves the w x h photo
    (spanning [-0.5, w - 0.5]) by more than OUTSIDE_TOL_PX."""
    lo, hi = -0.5 - OUTSIDE_TOL_PX, np.array([w, h, w, h]) - 0.5 + OUTSIDE_TOL_PX
    if np.any(box < lo) or np.any(box > hi):
        raise DatasetError(f"{what} lies outside the {w}x{h} photo: x {box[0] + 0.5:g}..{box[2] + 0.5:g}, "
                           f"y {box[1] + 0.5:g}..{box[3] + 0.5:g} (pixel edges)")


def _coco_window(a: dict, h: int, w: int, what: str) -> LabelledWindow:
    """One validated COCO annotation -> LabelledWindow (quad only from a single 4-vertex polygon)."""
    seg = a.get("segmentation")
    quad = quad_from_polygon(seg[0]) if isinstance(seg, list) and len(seg) == 1 else None
    box = box_from_coco(a["bbox"]) if a.get("bbox") else None
    if box is not None:
        _check_inside(box, w, h, f"{what}: bbox")
    if isinstance(seg, list) and seg:
        pts = np.concatenate([np.asarray(poly, np.float64).reshape(-1, 2) for poly in seg]) - EDGE_TO_CENTRE
        _check_inside(np.concatenate([pts.min(axis=0), pts.max(axis=0)]), w, h, f"{what}: polygon")
    size = a.get("size_m")
    aspect = a.get("aspect", size[0] / size[1] if size else None)
    try:
        return LabelledWindow(id=str(a.get("id")), quad=quad, mask=_coco_mask(seg, h, w), box=box,
                              aspect=None if aspect is None else float(aspect),
                              size_m=None if size is None else (float(size[0]), float(size[1])),
                              partial=bool(a.get("partial", False)))
    except ValueError as e:
        raise DatasetError(f"{what}: {e}") from e


def _coco_categories(doc: dict, category, where: str) -> set:
    """Category ids counted as windows: ``category`` (name, id or list of them), default
    every category named 'window', else every category."""
    cats = doc.get("categories") or []
    if category is None:
        ids = {c["id"] for c in cats if str(c.get("name", "")).lower() == "window"}
        return ids or {c["id"] for c in cats} or {a.get("category_id") for a in doc.get("annotations", [])}
    wanted = category if isinstance(category, list) else [category]
    ids = {c["id"] for c in cats if c["id"] in wanted or c.get("name") in wanted}
    if not ids:
        raise DatasetError(f"{where}: no category matches {category!r}; have "
                           f"{[(c['id'], c.get('name')) for c in cats]}")
    return ids


def _camera_of(img: dict, where: str) -> Camera | None:
    """Per-image intrinsics (COCO extension keys ``K`` 3x3 and optional ``distortion``)."""
    if img.get("K") is None:
        return None
    try:
        from fenestra.checks import check_K  # noqa: PLC0415

        return Camera(K=check_K(np.asarray(img["K"], dtype=np.float64)),
                      distortion=check_distortion(img.get("distortion")))
    except Exception as e:  # noqa: BLE001 - re-raised naming the image
        raise DatasetError(f"{where}: image {img.get('file_name')!r}: bad K/distortion: {e}") from e


def read_coco_doc(path: Path, annotations: str = "annotations.json") -> tuple[dict, str]:
    """(the validated COCO document, its path as text); DatasetError with the first problem
    (``fenestra check-data`` lists them all) or for a file that is too large or not JSON."""
    js = inside(path, annotations, "COCO annotations")
    doc = read_json(js, "COCO annotations")
    problems = coco_problems(doc, str(js))
    if problems:
        more = f" (and {len(problems) - 1} more problem(s): fenestra check-data lists them)" if len(problems) > 1 else ""
        raise DatasetError(problems[0] + more)
    return doc, str(js)


def _coco_photo(path: Path, images: str | None, img: dict, where: str) -> tuple[np.ndarray, Path]:
    """(RGB photo, its file) of one COCO image entry: the file inside the dataset folder, a
    regular file, decoding (EXIF orientation applied) to the stated width x height."""
    name = img["file_name"]
    sub = images if images is not None else ("images" if os.path.lexists(Path(path) / "images" / name) else ".")
    p = inside(path, str(Path(sub) / name), f"{where}: image {img['id']!r} file_name")
    photo = read_image(regular_file(p, "photo"))
    h, w = photo.shape[:2]
    sw, sh = img.get("width"), img.get("height")
    if (sw is not None and sw != w) or (sh is not None and sh != h):
        o = photo_orientation(p)
        turned = f" (EXIF orientation {o} applied)" if o != 1 else ""
        raise DatasetError(f"{where}: image {img['id']!r} ({name}) states width {sw}, height {sh} but the photo "
                           f"decodes to {w}x{h}{turned}; give the size of the photo as displayed")
    return photo, p


def read_coco(path: Path, annotations: str = "annotations.json", images: str | None = None,
              category=None, dataset: str = "coco", refused: list[str] | None = None) -> Iterator[LabelledView]:
    """COCO instances JSON: ``path/annotations`` with each ``file_name`` under ``path/images``
    (default: ``path/images`` if the photo is there, else ``path``).

    Per annotation: bbox -> box; segmentation (polygons, RLE) -> mask, and a single 4-vertex
    polygon -> quad; optional extension keys ``aspect`` (w/h), ``size_m`` [w, h], ``partial``.
    Per image: optional ``K`` (3x3) and ``distortion`` (labels then in the undistorted frame:
    the photo is undistorted here). iscrowd annotations are ignore regions (LabelledView.ignore):
    neither windows nor background; detection AP counts detections there neither way.
    The file is validated first (coco_problems: DatasetError naming file, entry and field);
    photos must lie inside ``path``, be regular files and decode to the stated width/height;
    boxes and polygons must lie inside their photo. ``refused``: unused (COCO refuses by error).
    """
    path = Path(path)
    doc, where = read_coco_doc(path, annotations)
    cats = _coco_categories(doc, category, where)
    by_image: dict = {}  # image id -> ([(index, window annotation)], [(index, crowd annotation)])
    for i, a in enumerate(doc.get("annotations", [])):
        if a.get("category_id") in cats:
            by_image.setdefault(a["image_id"], ([], []))[int(bool(a.get("iscrowd", 0)))].append((i, a))
    for img in sorted(doc.get("images", []), key=lambda i: i["file_name"]):
        photo, _ = _coco_photo(path, images, img, where)
        h, w = photo.shape[:2]
        cam = _camera_of(img, where)
        if cam is not None and cam.has_distortion:
            photo = undistort_photo(photo, cam)
        anns, crowd = by_image.get(img["id"], ([], []))
        win = [_coco_window(a, h, w, f"{where}: annotations[{i}] (id {a.get('id')!r})") for i, a in anns]
        ign = [_coco_window(a, h, w, f"{where}: annotations[{i}] (id {a.get('id')!r})") for i, a in crowd]
        yield LabelledView(dataset=dataset, name=Path(img["file_name"]).stem, image=photo,
                           windows=tuple(win), ignore=tuple(ign), K=None if cam is None else cam.K,
                           distortion_removed=None if cam is None or cam.distortion is None
                           else tuple(cam.distortion.tolist()), coplanar=bool(img.get("coplanar", False)))


# ---------------------------------------------------------------- YOLO

@dataclass(frozen=True)
class YoloBox:
    """One parsed YOLO line: class id and the box (cx, cy, w, h) normalised to the photo size."""

    line: int
    cls: int
    cx: float
    cy: float
    w: float
    h: float


def parse_yolo(text: str, where: str) -> list[YoloBox]:
    """Every ``class cx cy w h`` line of a YOLO label file (blank lines skipped); DatasetError
    naming ``where:line`` for a line without 5 fields, a class that is not a finite integer, or
    a non-finite coordinate or non-positive size."""
    out = []
    for k, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        try:
            vals = [float(v) for v in parts]
        except ValueError:
            vals = None
        if vals is None or len(parts) != 5:
            raise DatasetError(f"{where}:{k}: bad YOLO line {line.strip()!r}: need 'class cx cy w h' (5 numbers)")
        c, cx, cy, bw, bh = vals
        if not (math.isfinite(c) and c >= 0 and c.is_integer()):
            raise DatasetError(f"{where}:{k}: class {parts[0]!r} is not a non-negative integer class id")
        if not all(math.isfinite(v) for v in (cx, cy, bw, bh)) or bw <= 0 or bh <= 0:
            raise DatasetError(f"{where}:{k}: box {parts[1:]} needs finite numbers with w, h > 0")
        out.append(YoloBox(k, int(c), cx, cy, bw, bh))
    return out


def yolo_window_box(b: YoloBox, width: int, height: int) -> np.ndarray | None:
    """(4,) x0 y0 x1 y1 px (fenestra convention) of a YOLO box clipped to the photo; None when
    the box lies entirely outside it (no overlap)."""
    x0, x1 = max(b.cx - b.w / 2, 0.0), min(b.cx + b.w / 2, 1.0)
    y0, y1 = max(b.cy - b.h / 2, 0.0), min(b.cy + b.h / 2, 1.0)
    if x1 <= x0 or y1 <= y0:
        return None
    return box_from_coco([x0 * width, y0 * height, (x1 - x0) * width, (y1 - y0) * height])


def _classes(classes) -> tuple[int, ...]:
    """The ``classes`` option as a tuple of non-negative ints; DatasetError naming a bad value."""
    cs = classes if isinstance(classes, (list, tuple)) else [classes]
    if not cs or not all(isinstance(c, int) and not isinstance(c, bool) and c >= 0 for c in cs):
        raise DatasetError(f"YOLO option classes must be non-negative integer class ids, got {classes!r}")
    return tuple(cs)


def _label_text(lab: Path, where: str) -> str:
    """A label file's text ('' if absent); DatasetError for a FIFO/device or undecodable text."""
    if not lab.exists():
        return ""
    try:
        return regular_file(lab, "label file").read_text()
    except UnicodeDecodeError as e:
        raise DatasetError(f"{where}: label file is not text: {e}") from e


def read_yolo(path: Path, images: str = "images", labels: str = "labels", classes=(0,),
              dataset: str = "yolo", refused: list[str] | None = None, every: int = 1) -> Iterator[LabelledView]:
    """YOLO txt boxes: ``path/images/NAME.jpg`` with ``path/labels/NAME.txt``; windows are the
    boxes of ``classes`` (ids). Boxes only: quad, mask, aspect and K are missing. A photo without
    a label file has no windows. A box partly outside the photo is clipped to it; one entirely
    outside is dropped and recorded in ``refused`` (never an evaluable window); label files
    without a photo are recorded too. every > 1: only the photos with a label file whose index
    in name order is a multiple of ``every`` (the held-out "val" part of training.dataset.real_box_photos)."""
    classes = _classes(classes)
    if not (isinstance(every, int) and not isinstance(every, bool) and every >= 1):
        raise DatasetError(f"YOLO option every must be an integer >= 1, got {every!r}")
    root = Path(path)
    photos = _images(inside(root, images, "YOLO images folder"), refused)
    lab_dir = inside(root, labels, "YOLO labels folder")
    stems = {p.stem for p in photos}
    if lab_dir.is_dir():
        for orphan in sorted(q for q in lab_dir.glob("*.txt") if q.stem not in stems):
            _refuse(refused, f"{orphan}: no photo {orphan.stem}.* in {root / images}; skipped")
    if every > 1:
        photos = [p for p in photos if (lab_dir / (p.stem + ".txt")).is_file()][::every]
    for p in photos:
        photo = read_image(p)
        lab = lab_dir / (p.stem + ".txt")
        wins = []
        for b in parse_yolo(_label_text(lab, str(lab)), str(lab)):
            if b.cls not in classes:
                continue
            box = yolo_window_box(b, photo.shape[1], photo.shape[0])
            if box is None:
                _refuse(refused, f"{lab}:{b.line}: box (cx {b.cx:g}, cy {b.cy:g}, w {b.w:g}, h {b.h:g}) lies "
                                 "entirely outside the photo; dropped")
                continue
            wins.append(LabelledWindow(id=f"{p.stem}:{len(wins)}", box=box))
        yield LabelledView(dataset=dataset, name=p.stem, image=photo, windows=tuple(wins))


# ---------------------------------------------------------------- label maps

def window_pixels(label: np.ndarray, value, where: str) -> np.ndarray:
    """(H, W) bool: pixels of the window class in a label map. value: an int class id (for a
    single-channel map) or an [r, g, b] colour (for an RGB map, as read into RGB order)."""
    if isinstance(value, (list, tuple)):
        if label.ndim != 3 or len(value) != 3:
            raise DatasetError(f"{where}: colour {value!r} needs an RGB label map, got shape {label.shape}")
        if not all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255 for v in value):
            raise DatasetError(f"{where}: window colour must be three integers 0-255, got {value!r}")
        return np.all(label[..., :3] == np.asarray(value, dtype=label.dtype), axis=-1)
    if label.ndim != 2:
        raise DatasetError(f"{where}: class id {value!r} needs a single-channel label map, got shape {label.shape}")
    if not (isinstance(value, int) and not isinstance(value, bool)):
        raise DatasetError(f"{where}: window class id must be an integer, got {value!r}")
    return label == value


def _read_label(p: Path) -> np.ndarray:
    m = decode_file(regular_file(p, "label map"), cv2.IMREAD_UNCHANGED, "label map")
    return m if m.ndim == 2 else cv2.cvtColor(m[..., :3], cv2.COLOR_BGR2RGB)


def read_labelmap(path: Path, images: str = "images", labels: str = "labels", window=(255, 0, 0),
                  min_area_px: float = 0.0, dataset: str = "labelmap",
                  refused: list[str] | None = None) -> Iterator[LabelledView]:
    """Semantic label maps: ``path/labels/NAME.png`` beside ``path/images/NAME.jpg``; the window
    class is ``window`` (an [r, g, b] colour or an integer id); instances are its 4-connected
    components of at least ``min_area_px`` px (at most LIMITS.max_windows_per_photo, checked
    before any mask is built). Masks only; components touching the border are ``partial``."""
    root = Path(path)
    lab_dir = inside(root, labels, "label-map folder")
    for p in _images(inside(root, images, "label-map images folder"), refused):
        photo = read_image(p)
        lab_path = lab_dir / (p.stem + ".png")
        lab = _read_label(lab_path)
        if lab.shape[:2] != photo.shape[:2]:
            raise DatasetError(f"{lab_path}: label map {lab.shape[1]}x{lab.shape[0]} != photo "
                               f"{photo.shape[1]}x{photo.shape[0]}")
        comps = components(window_pixels(lab, window, str(lab_path)), min_area_px, str(lab_path))
        wins = tuple(LabelledWindow(id=f"{p.stem}:{i}", mask=c.sparse(), partial=c.touches_border)
                     for i, c in enumerate(comps))
        yield LabelledView(dataset=dataset, name=p.stem, image=photo, windows=wins)


# ---------------------------------------------------------------- curtain wall

def curtain_glass(rgba: np.ndarray) -> np.ndarray:
    """(H, W) bool glass label of a curtain-wall mask (BGRA as cv2 reads it: pure blue, alpha >= 128)."""
    if rgba is None or rgba.ndim != 3 or rgba.shape[2] != 4:
        raise ValueError(f"curtain-wall mask must be RGBA, got shape {None if rgba is None else rgba.shape}")
    b, g, r, a = (rgba[..., i] for i in range(4))
    return (b == 255) & (g == 0) & (r == 0) & (a >= 128)


def curtain_camera(folder: Path, width: int, height: int) -> Camera:
    """``folder/K.json`` (K + distortion) if present, else the dataset's calibration scaled to
    width x height (pixel centres at integers: f' = s f, c' = (c + 0.5) s - 0.5)."""
    if (folder / "K.json").exists():
        read_json(folder / "K.json", "intrinsics file")  # regular file, size limit (before parsing)
        return read_camera(folder / "K.json")
    s = width / CURTAIN_SIZE_PX[0]
    if abs(height / CURTAIN_SIZE_PX[1] - s) > 1e-3:
        raise ValueError(f"{folder}: photo {width}x{height} is not a scaled 1536x2048 curtain-wall photo; add K.json")
    K = np.array(CURTAIN_K, dtype=np.float64)
    K[:2, :2] *= s
    K[:2, 2] = (K[:2, 2] + 0.5) * s - 0.5
    return Camera(K=K, distortion=check_distortion(list(CURTAIN_DISTORTION)))


def read_curtainwall(path: Path, min_area_frac: float = CURTAIN_MIN_AREA_FRAC,
                     dataset: str = "curtainwall", refused: list[str] | None = None) -> Iterator[LabelledView]:
    """Glass Curtain Wall Installation Dataset layout: ``images/imgNNN.(png|jpg)`` as taken (lens
    distortion in them), ``masks/maskNNN.png`` (RGBA, in the undistorted frame: glass = blue),
    optional ``K.json``. The photo is undistorted; panes are the 4-connected glass components
    covering at least ``min_area_frac`` of the photo; whole panes have aspect 93.2/143.2 and size
    (0.0932, 0.1432) m, panes cut by the border are partial (aspect unknown). All coplanar."""
    folder = Path(path)
    for p in _images(folder / "images", refused):
        photo = read_image(p)
        h, w = photo.shape[:2]
        mpath = folder / "masks" / (p.stem.replace("img", "mask") + ".png")
        rgba = decode_file(mpath, cv2.IMREAD_UNCHANGED, "curtain-wall mask") if is_regular(mpath) else None
        if rgba is None:
            raise FileNotFoundError(f"curtain-wall mask not found: {mpath}")
        if rgba.shape[:2] != (h, w):
            raise ValueError(f"{mpath}: mask {rgba.shape[1]}x{rgba.shape[0]} != photo {w}x{h}")
        cam = curtain_camera(folder, w, h)
        wins = []
        for i, c in enumerate(components(curtain_glass(rgba), min_area_frac * w * h, str(mpath))):
            cut = c.touches_border
            wins.append(LabelledWindow(id=f"{p.stem}:{i}", mask=c.sparse(), partial=cut,
                                       aspect=None if cut else CURTAIN_PANE_M[0] / CURTAIN_PANE_M[1],
                                       size_m=None if cut else CURTAIN_PANE_M))
        yield LabelledView(dataset=dataset, name=p.stem, image=undistort_photo(photo, cam), windows=tuple(wins),
                           K=cam.K, distortion_removed=None if cam.distortion is None else tuple(cam.distortion.tolist()),
                           coplanar=True)


@dataclass(frozen=True)
class Adapter:
    """A registered dataset format: ``read(folder, **options) -> Iterator[LabelledView]``; calling the
    entry calls its reader. description: one line for CLI help."""

    name: str
    read: Callable[..., Iterator[LabelledView]]
    description: str

    def __call__(self, folder: Path, **options) -> Iterator[LabelledView]:
        return self.read(folder, **options)


ADAPTERS: Registry[Adapter] = Registry("dataset format", [
    Adapter("coco", read_coco, "COCO instances JSON: boxes, polygon or RLE masks, 4-vertex polygons as quads"),
    Adapter("yolo", read_yolo, "YOLO txt: window boxes of the given class ids"),
    Adapter("labelmap", read_labelmap, "semantic label-map PNGs: window instances as components of one colour or id"),
    Adapter("curtainwall", read_curtainwall, "the bundled curtain-wall photos: pane masks, known pane size, calibration"),
])


# ---------------------------------------------------------------- checking a dataset

@dataclass(frozen=True)
class DataCheck:
    """What ``fenestra check-data`` found in a dataset folder.

    views: one line per photo read (name and its windows by kind of truth); refused: labels or
    files left out, with the reason; problems: errors that stop the dataset from being used
    (COCO lists every structural one; otherwise the first error met)."""

    folder: str
    format: str
    views: tuple[str, ...] = ()
    n_windows: int = 0
    refused: tuple[str, ...] = ()
    problems: tuple[str, ...] = ()


def _view_line(v: LabelledView) -> str:
    """'NAME WxH: n windows (q quads, m masks, b boxes, k with aspect, p partial)'."""
    ws = v.windows
    kinds = [f"{sum(getattr(w, k) is not None for w in ws)} {k}" for k in ("quad", "mask", "box", "aspect")]
    return (f"{v.name} {v.image.shape[1]}x{v.image.shape[0]}: {len(ws)} windows ({', '.join(kinds)}, "
            f"{sum(w.partial for w in ws)} partial), {len(v.ignore)} ignore regions")


def check_dataset(folder: str | Path, fmt: str, **options) -> DataCheck:
    """Read a dataset with its adapter and report (never raise for the data's own problems)."""
    if fmt not in ADAPTERS:
        raise DatasetError(f"--format {fmt!r} unknown; choose from {sorted(ADAPTERS)}")
    folder = Path(folder)
    if not folder.is_dir():
        raise DatasetError(f"dataset folder not found: {folder}")
    refused: list[str] = []
    if fmt == "coco":  # every structural problem, not only the first
        try:
            doc = read_json(inside(folder, options.get("annotations", "annotations.json"), "COCO annotations"),
                            "COCO annotations")
        except DatasetError as e:
            return DataCheck(str(folder), fmt, problems=(str(e),))
        problems = coco_problems(doc, str(folder / options.get("annotations", "annotations.json")))
        if problems:
            return DataCheck(str(folder), fmt, problems=tuple(problems))
    views = []
    n = 0
    try:
        for v in ADAPTERS[fmt](folder, refused=refused, **options):
            views.append(_view_line(v))
            n += len(v.windows)
    except (DatasetError, ValueError, OSError) as e:
        return DataCheck(str(folder), fmt, tuple(views), n, tuple(refused), (str(e),))
    return DataCheck(str(folder), fmt, tuple(views), n, tuple(refused))
