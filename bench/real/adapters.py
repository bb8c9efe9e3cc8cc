"""Real-dataset adapters: a folder in a published format -> RealViews (bench.real.contract).

    ADAPTERS: Registry("dataset format"): coco, yolo, labelmap, curtainwall (Adapter entries)
    views = list(ADAPTERS["coco"](Path("my_photos"), category="window"))

Every adapter takes the dataset folder and keyword options (the profile's ``options`` table) and
yields one RealView per photo, sorted by file name, with exactly the ground truth the format
carries (see each reader). Coordinates are converted from the format's pixel-edge convention
(pixel (0, 0) covers [0, 1]^2) to fenestra's (pixel centres at integers) by subtracting 0.5.
Errors name the file and the bad value.
"""
from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from bench.real.contract import RealView, RealWindow
from fenestra.registry import Registry
from fenestra.data import box_from_coco, read_image, rle_to_mask, segmentation_to_rle, yolo_boxes
from pipeline.io import Camera, check_distortion, read_camera, undistort_photo
from pipeline.quad import order_corners

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
EDGE_TO_CENTRE = 0.5  # format coordinates (pixel edges at integers) -> fenestra (centres at integers)

# Glass Curtain Wall Installation Dataset (B. Johns et al. 2023): calibration for 1536 x 2048 px
# photos (user guide; OpenCV, pixel centres at integers) and the glass pane size.
CURTAIN_SIZE_PX = (1536, 2048)
CURTAIN_K = ((1821.04993399032, 0.0, 740.82871031754), (0.0, 1817.92066001349, 1018.94855509992),
             (0.0, 0.0, 1.0))
CURTAIN_DISTORTION = (-0.1552775701035, 0.0472686081157939, 0.0, 0.0, 0.0)
CURTAIN_PANE_M = (0.0932, 0.1432)  # glass pane width, height (m, 1:25 model)
CURTAIN_MIN_AREA_FRAC = 20000 / (1536 * 2048)  # smaller glass components are not panes


def _images(folder: Path) -> list[Path]:
    """Photos directly in ``folder`` (jpg/jpeg/png), sorted; ValueError naming an empty folder."""
    if not folder.is_dir():
        raise FileNotFoundError(f"image folder not found: {folder}")
    out = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    if not out:
        raise ValueError(f"no .jpg/.png photos in {folder}")
    return out


def touches_border(mask: np.ndarray) -> bool:
    """True if a bool mask (H, W) has a pixel in the first/last row or column."""
    m = np.asarray(mask, dtype=bool)
    return bool(m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any())


def components(binary: np.ndarray, min_area_px: float = 0.0) -> list[np.ndarray]:
    """4-connected components of a bool image (H, W) with at least ``min_area_px`` pixels, as bool
    masks ordered by their top-left-most pixel (row-major)."""
    n, lab, st, _ = cv2.connectedComponentsWithStats(np.asarray(binary, np.uint8), connectivity=4)
    keep = [i for i in range(1, n) if st[i, cv2.CC_STAT_AREA] >= min_area_px]
    first = {i: int(np.flatnonzero(lab.reshape(-1) == i)[0]) for i in keep}
    return [lab == i for i in sorted(keep, key=first.get)]


def quad_from_polygon(poly: list[float]) -> np.ndarray | None:
    """(4, 2) TL TR BR BL px (fenestra convention) of a 4-vertex COCO polygon [x1, y1, ...] (pixel
    edges at integers); None for any other vertex count (the quad is then missing, not fitted)."""
    p = np.asarray(poly, dtype=np.float64)
    if p.size != 8:
        return None
    return order_corners(p.reshape(4, 2) - EDGE_TO_CENTRE)


# ---------------------------------------------------------------- COCO

def _coco_mask(seg, h: int, w: int) -> np.ndarray | None:
    """(H, W) bool of a COCO segmentation (polygons, RLE or uncompressed RLE); None if absent or empty."""
    if not seg:
        return None
    m = rle_to_mask(segmentation_to_rle(seg, h, w))
    return m if m.any() else None


def _coco_window(a: dict, h: int, w: int, where: str) -> RealWindow:
    """One COCO annotation -> RealWindow (quad only from a single 4-vertex polygon)."""
    seg = a.get("segmentation")
    quad = quad_from_polygon(seg[0]) if isinstance(seg, list) and len(seg) == 1 else None
    size = a.get("size_m")
    aspect = a.get("aspect", size[0] / size[1] if size else None)
    try:
        return RealWindow(id=str(a.get("id")), quad=quad, mask=_coco_mask(seg, h, w),
                          box=box_from_coco(a["bbox"]) if a.get("bbox") else None,
                          aspect=None if aspect is None else float(aspect),
                          size_m=None if size is None else (float(size[0]), float(size[1])),
                          partial=bool(a.get("partial", False)))
    except (ValueError, TypeError, KeyError) as e:
        raise ValueError(f"{where}: annotation {a.get('id')!r}: {e}") from e


def _coco_categories(doc: dict, category, where: str) -> set[int]:
    """Category ids counted as windows: ``category`` (name, id or list of them), default
    every category named 'window', else every category."""
    cats = doc.get("categories") or []
    if category is None:
        ids = {c["id"] for c in cats if str(c.get("name", "")).lower() == "window"}
        return ids or {c["id"] for c in cats} or {a.get("category_id") for a in doc.get("annotations", [])}
    wanted = category if isinstance(category, list) else [category]
    ids = {c["id"] for c in cats if c["id"] in wanted or c.get("name") in wanted}
    if not ids:
        raise ValueError(f"{where}: no category matches {category!r}; have "
                         f"{[(c['id'], c.get('name')) for c in cats]}")
    return ids


def _camera_of(img: dict, where: str) -> Camera | None:
    """Per-image intrinsics (COCO extension keys ``K`` 3x3 and optional ``distortion``)."""
    if img.get("K") is None:
        return None
    try:
        from fenestra.conventions import check_K  # noqa: PLC0415

        return Camera(K=check_K(np.asarray(img["K"], dtype=np.float64)),
                      distortion=check_distortion(img.get("distortion")))
    except Exception as e:  # noqa: BLE001 - re-raised naming the image
        raise ValueError(f"{where}: image {img.get('file_name')!r}: bad K/distortion: {e}") from e


def read_coco(path: Path, annotations: str = "annotations.json", images: str | None = None,
              category=None, dataset: str = "coco") -> Iterator[RealView]:
    """COCO instances JSON: ``path/annotations`` with each ``file_name`` under ``path/images``
    (default: ``path/images`` if the photo is there, else ``path``).

    Per annotation: bbox -> box; segmentation (polygons, RLE) -> mask, and a single 4-vertex
    polygon -> quad; optional extension keys ``aspect`` (w/h), ``size_m`` [w, h], ``partial``.
    Per image: optional ``K`` (3x3) and ``distortion`` (labels then in the undistorted frame:
    the photo is undistorted here). iscrowd annotations are ignore regions (RealView.ignore):
    neither windows nor background; detection AP counts detections there neither way.
    """
    js = Path(path) / annotations
    if not js.is_file():
        raise FileNotFoundError(f"COCO annotations not found: {js}")
    doc = json.loads(js.read_text())
    cats = _coco_categories(doc, category, str(js))
    by_image: dict = {}  # image id -> ([window annotations], [crowd annotations])
    for a in doc.get("annotations", []):
        if a.get("category_id") in cats:
            by_image.setdefault(a["image_id"], ([], []))[int(bool(a.get("iscrowd", 0)))].append(a)
    for img in sorted(doc.get("images", []), key=lambda i: i["file_name"]):
        sub = images if images is not None else (
            "images" if (Path(path) / "images" / img["file_name"]).is_file() else ".")
        photo = read_image(Path(path) / sub / img["file_name"])
        h, w = photo.shape[:2]
        cam = _camera_of(img, str(js))
        if cam is not None and cam.has_distortion:
            photo = undistort_photo(photo, cam)
        anns, crowd = by_image.get(img["id"], ([], []))
        yield RealView(dataset=dataset, name=Path(img["file_name"]).stem, image=photo,
                       windows=tuple(_coco_window(a, h, w, str(js)) for a in anns),
                       ignore=tuple(_coco_window(a, h, w, str(js)) for a in crowd),
                       K=None if cam is None else cam.K,
                       distortion_removed=None if cam is None or cam.distortion is None
                       else tuple(cam.distortion.tolist()), coplanar=bool(img.get("coplanar", False)))


# ---------------------------------------------------------------- YOLO

def read_yolo(path: Path, images: str = "images", labels: str = "labels", classes=(0,),
              dataset: str = "yolo") -> Iterator[RealView]:
    """YOLO txt boxes: ``path/images/NAME.jpg`` with ``path/labels/NAME.txt``; windows are the
    boxes of ``classes`` (ids). Boxes only: quad, mask, aspect and K are missing. A photo without
    a label file has no windows."""
    classes = tuple(int(c) for c in (classes if isinstance(classes, (list, tuple)) else [classes]))
    for p in _images(Path(path) / images):
        photo = read_image(p)
        lab = Path(path) / labels / (p.stem + ".txt")
        text = lab.read_text() if lab.is_file() else ""
        boxes = yolo_boxes(text, photo.shape[1], photo.shape[0], classes, str(lab))
        wins = tuple(RealWindow(id=f"{p.stem}:{i}", box=b) for i, b in enumerate(boxes))
        yield RealView(dataset=dataset, name=p.stem, image=photo, windows=wins)


# ---------------------------------------------------------------- label maps

def window_pixels(label: np.ndarray, value, where: str) -> np.ndarray:
    """(H, W) bool: pixels of the window class in a label map. value: an int class id (for a
    single-channel map) or an [r, g, b] colour (for an RGB map, as read into RGB order)."""
    if isinstance(value, (list, tuple)):
        if label.ndim != 3 or len(value) != 3:
            raise ValueError(f"{where}: colour {value!r} needs an RGB label map, got shape {label.shape}")
        return np.all(label[..., :3] == np.asarray(value, dtype=label.dtype), axis=-1)
    if label.ndim != 2:
        raise ValueError(f"{where}: class id {value!r} needs a single-channel label map, got shape {label.shape}")
    return label == int(value)


def _read_label(p: Path) -> np.ndarray:
    m = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if m is None:
        raise FileNotFoundError(f"cannot read label map {p}")
    return m if m.ndim == 2 else cv2.cvtColor(m[..., :3], cv2.COLOR_BGR2RGB)


def read_labelmap(path: Path, images: str = "images", labels: str = "labels", window=(255, 0, 0),
                  min_area_px: float = 0.0, dataset: str = "labelmap") -> Iterator[RealView]:
    """Semantic label maps: ``path/labels/NAME.png`` beside ``path/images/NAME.jpg``; the window
    class is ``window`` (an [r, g, b] colour or an integer id); instances are its 4-connected
    components of at least ``min_area_px`` px. Masks only; components touching the border are
    ``partial``."""
    for p in _images(Path(path) / images):
        photo = read_image(p)
        lab_path = Path(path) / labels / (p.stem + ".png")
        lab = _read_label(lab_path)
        if lab.shape[:2] != photo.shape[:2]:
            raise ValueError(f"{lab_path}: label map {lab.shape[1]}x{lab.shape[0]} != photo "
                             f"{photo.shape[1]}x{photo.shape[0]}")
        masks = components(window_pixels(lab, window, str(lab_path)), min_area_px)
        wins = tuple(RealWindow(id=f"{p.stem}:{i}", mask=m, partial=touches_border(m))
                     for i, m in enumerate(masks))
        yield RealView(dataset=dataset, name=p.stem, image=photo, windows=wins)


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
    if (folder / "K.json").is_file():
        return read_camera(folder / "K.json")
    s = width / CURTAIN_SIZE_PX[0]
    if abs(height / CURTAIN_SIZE_PX[1] - s) > 1e-3:
        raise ValueError(f"{folder}: photo {width}x{height} is not a scaled 1536x2048 curtain-wall photo; add K.json")
    K = np.array(CURTAIN_K, dtype=np.float64)
    K[:2, :2] *= s
    K[:2, 2] = (K[:2, 2] + 0.5) * s - 0.5
    return Camera(K=K, distortion=check_distortion(list(CURTAIN_DISTORTION)))


def read_curtainwall(path: Path, min_area_frac: float = CURTAIN_MIN_AREA_FRAC,
                     dataset: str = "curtainwall") -> Iterator[RealView]:
    """Glass Curtain Wall Installation Dataset layout: ``images/imgNNN.(png|jpg)`` as taken (lens
    distortion in them), ``masks/maskNNN.png`` (RGBA, in the undistorted frame: glass = blue),
    optional ``K.json``. The photo is undistorted; panes are the 4-connected glass components
    covering at least ``min_area_frac`` of the photo; whole panes have aspect 93.2/143.2 and size
    (0.0932, 0.1432) m, panes cut by the border are partial (aspect unknown). All coplanar."""
    folder = Path(path)
    for p in _images(folder / "images"):
        photo = read_image(p)
        h, w = photo.shape[:2]
        mpath = folder / "masks" / (p.stem.replace("img", "mask") + ".png")
        rgba = cv2.imread(str(mpath), cv2.IMREAD_UNCHANGED)
        if rgba is None:
            raise FileNotFoundError(f"curtain-wall mask not found: {mpath}")
        if rgba.shape[:2] != (h, w):
            raise ValueError(f"{mpath}: mask {rgba.shape[1]}x{rgba.shape[0]} != photo {w}x{h}")
        cam = curtain_camera(folder, w, h)
        wins = []
        for i, m in enumerate(components(curtain_glass(rgba), min_area_frac * w * h)):
            cut = touches_border(m)
            wins.append(RealWindow(id=f"{p.stem}:{i}", mask=m, partial=cut,
                                   aspect=None if cut else CURTAIN_PANE_M[0] / CURTAIN_PANE_M[1],
                                   size_m=None if cut else CURTAIN_PANE_M))
        yield RealView(dataset=dataset, name=p.stem, image=undistort_photo(photo, cam), windows=tuple(wins),
                       K=cam.K, distortion_removed=None if cam.distortion is None else tuple(cam.distortion.tolist()),
                       coplanar=True)


@dataclass(frozen=True)
class Adapter:
    """A registered dataset format: ``read(folder, **options) -> Iterator[RealView]``; calling the
    entry calls its reader. description: one line for CLI help."""

    name: str
    read: Callable[..., Iterator[RealView]]
    description: str

    def __call__(self, folder: Path, **options) -> Iterator[RealView]:
        return self.read(folder, **options)


ADAPTERS: Registry[Adapter] = Registry("dataset format", [
    Adapter("coco", read_coco, "COCO instances JSON: boxes, polygon or RLE masks, 4-vertex polygons as quads"),
    Adapter("yolo", read_yolo, "YOLO txt: window boxes of the given class ids"),
    Adapter("labelmap", read_labelmap, "semantic label-map PNGs: window instances as components of one colour or id"),
    Adapter("curtainwall", read_curtainwall, "the bundled curtain-wall photos: pane masks, known pane size, calibration"),
])
