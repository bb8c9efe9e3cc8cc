"""COCO instances JSON -> LabelledViews: validation (:func:`coco_problems`, every problem one line
naming file, entry and field) and reading (:func:`read_coco`)."""
from __future__ import annotations

import math
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from fenestra.bench.real.adapters.common import EDGE_TO_CENTRE, OUTSIDE_TOL_PX, view_name_key
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra.conventions import LIMITS
from fenestra.errors import DatasetError
from fenestra.images import read_image
from fenestra.masks import SparseMask, box_from_coco, rle_to_mask, segmentation_to_rle
from fenestra.pipeline.io import Camera, check_distortion, photo_orientation, undistort_photo
from fenestra.pipeline.quad import order_corners
from fenestra.userfiles import inside, read_json, regular_file


def quad_from_polygon(poly: list[float]) -> np.ndarray | None:
    """(4, 2) TL TR BR BL px (fenestra convention) of a 4-vertex COCO polygon [x1, y1, ...] (pixel
    edges at integers); None for any other vertex count (the quad is then missing, not fitted)."""
    p = np.asarray(poly, dtype=np.float64)
    if p.size != 8:
        return None
    return order_corners(p.reshape(4, 2) - EDGE_TO_CENTRE)


# ---------------------------------------------------------------- validation

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
    if sz[0] * sz[1] > LIMITS.max_image_pixels:
        return [f"{what}: RLE size {sz} is {sz[0] * sz[1] / 1e6:.0f} Mpx, over the limit of "
                f"{LIMITS.max_image_pixels / 1e6:.0f} Mpx (fenestra.conventions.LIMITS.max_image_pixels)"]
    if isinstance(counts, list) and sum(counts) != sz[0] * sz[1]:
        return [f"{what}: RLE counts cover {sum(counts)} pixels, not the {sz[0]} x {sz[1]} = {sz[0] * sz[1]} of its size"]
    return []


def _annotation_problems(a: dict, i: int, where: str, images: dict, categories: set | None) -> list[str]:
    """Problems of one COCO annotation: its image and category (``categories``: the file's
    category ids, None when it lists none) resolved, geometry well-formed, extension keys typed."""
    what = f"{where}: annotations[{i}] (id {a.get('id')!r})"
    if "image_id" not in a:
        return [f"{what} has no 'image_id'"]
    img = images.get(a["image_id"]) if _is_id(a["image_id"]) else None
    if img is None:
        return [f"{what}: image_id {a['image_id']!r} matches no image"]
    out = []
    if not _is_id(a.get("category_id")):
        out.append(f"{what}: 'category_id' must be an integer or string, got {a.get('category_id')!r}")
    elif categories is not None and a["category_id"] not in categories:
        out.append(f"{what}: category_id {a['category_id']!r} matches no category (the file's: "
                   f"{sorted(categories, key=str)})")
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
    top level an object; images with unique ids and safe file names whose names differ by more
    than case or extension; categories with ids; annotations resolving to an image and a category,
    with well-formed bbox/polygons/RLE (sizes within LIMITS.max_image_pixels, counts covering
    them) and extension keys; all before any photo or mask is decoded."""
    if not isinstance(doc, dict):
        return [f"{where}: the top level must be a JSON object with 'images' and 'annotations', "
                f"got {type(doc).__name__}"]
    problems: list[str] = []
    if isinstance(doc.get("images"), list) and len(doc["images"]) > LIMITS.max_dataset_photos:
        return [f"{where}: 'images' lists {len(doc['images'])} photos, more than the {LIMITS.max_dataset_photos} "
                "a dataset may have (fenestra.conventions.LIMITS.max_dataset_photos)"]
    imgs = _list_of_dicts(doc, "images", where, problems)
    cats = _list_of_dicts(doc, "categories", where, problems)
    anns = _list_of_dicts(doc, "annotations", where, problems)
    ids = _unique_ids(imgs, "images", where, problems)
    cat_ids = _unique_ids(cats, "categories", where, problems)
    _unique_ids(anns, "annotations", where, problems, required=False)
    stems: dict = {}  # a view is named by its photo's stem: two photos may not share one, in any case
    for i, img in enumerate(imgs):
        problems += _image_problems(img, i, where)
        n = img.get("file_name")
        if isinstance(n, str) and view_name_key(n) in stems:
            j = stems[view_name_key(n)]
            problems.append(f"{where}: images[{i}] file_name {n!r} has the name {Path(n).stem!r} of "
                            f"images[{j}] {imgs[j]['file_name']!r} (views are named by it; case and extension aside)")
        if isinstance(n, str):
            stems.setdefault(view_name_key(n), i)
    by_id = {img["id"]: img for img in imgs if "id" in img and img["id"] in ids}
    cat_ids = cat_ids if cats else None  # no categories listed: every category_id is a window's
    for i, a in enumerate(anns):
        problems += _annotation_problems(a, i, where, by_id, cat_ids)
    return problems


# ---------------------------------------------------------------- reading

def _coco_mask(seg, h: int, w: int, what: str) -> SparseMask | None:
    """The mask of a COCO segmentation (polygons, RLE or uncompressed RLE) of an (h, w) image;
    None if absent or empty. DatasetError naming ``what`` for an RLE of another size than the
    photo's, before it is decoded."""
    if not seg:
        return None
    if isinstance(seg, dict) and list(seg["size"]) != [h, w]:
        raise DatasetError(f"{what}: RLE size {seg['size']} != the photo's [height, width] {[h, w]}")
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
        return LabelledWindow(id=str(a.get("id")), quad=quad, mask=_coco_mask(seg, h, w, what), box=box,
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
    boxes and polygons must lie inside their photo; an annotation of a category the file does
    not list is an error, never dropped. ``refused``: unused (COCO refuses by error).
    """
    path = Path(path)
    doc, where = read_coco_doc(path, annotations)
    cats = _coco_categories(doc, category, where)
    by_image: dict = {}  # image id -> ([(index, window annotation)], [(index, crowd annotation)])
    for i, a in enumerate(doc.get("annotations", [])):
        if a.get("category_id") in cats:
            by_image.setdefault(a["image_id"], ([], []))[int(bool(a.get("iscrowd", 0)))].append((i, a))
    for img in sorted(doc.get("images", []), key=lambda i: i["file_name"]):
        anns, crowd = by_image.get(img["id"], ([], []))
        if len(anns) + len(crowd) > LIMITS.max_windows_per_photo:
            raise DatasetError(f"{where}: image {img['id']!r} ({img['file_name']}) has {len(anns) + len(crowd)} window "
                               f"annotations, more than the {LIMITS.max_windows_per_photo} per photo "
                               "(fenestra.conventions.LIMITS.max_windows_per_photo)")
        photo, _ = _coco_photo(path, images, img, where)
        h, w = photo.shape[:2]
        cam = _camera_of(img, where)
        if cam is not None and cam.has_distortion:
            photo = undistort_photo(photo, cam)
        win = [_coco_window(a, h, w, f"{where}: annotations[{i}] (id {a.get('id')!r})") for i, a in anns]
        ign = [_coco_window(a, h, w, f"{where}: annotations[{i}] (id {a.get('id')!r})") for i, a in crowd]
        yield LabelledView(dataset=dataset, name=Path(img["file_name"]).stem, image=photo,
                           windows=tuple(win), ignore=tuple(ign), K=None if cam is None else cam.K,
                           distortion_removed=None if cam is None or cam.distortion is None
                           else tuple(cam.distortion.tolist()), coplanar=bool(img.get("coplanar", False)))
