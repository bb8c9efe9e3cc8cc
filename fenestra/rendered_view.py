"""A rendered view's files, read and written in one place (docs/DESIGN.md, "Data contracts").

A view folder holds ``image.png``, ``instances.png``, optional ``ignore.png`` and ``view.json``
(:class:`ViewFiles` names them). :func:`write_view` (atomic, ``view.json`` last),
:func:`write_ignore` (add ignore regions to a view written before), :func:`check_view` (can a
cached view be reused?), :func:`read_meta` (view.json alone) and :func:`read_view` -> :class:`View`,
the one reader: the renderer's COCO file (:func:`view_annotations`), the bench's labelled view
(fenestra.bench.render_adapter) and the detectors' training (fenestra.training.dataset) all read
a view through it.

Files are written atomically by :mod:`fenestra.files` and decoded by :mod:`fenestra.images`
(any photo -> (H, W, 3) uint8 RGB; 16-bit instance PNG -> (H, W) **int32**).
Ground floor: imports nothing above fenestra/.
"""
from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fenestra.coco import gt_annotation
from fenestra.errors import DatasetError
from fenestra.files import write_image, write_json
from fenestra.images import decode_file, read_image, read_instances
from fenestra.masks import SparseMask, instance_masks

VIEW_FILES = ("image.png", "instances.png")  # every view; ignore.png only where view.json lists ignore regions
VIEW_KEYS = ("K", "width", "height", "R", "t", "windows")  # view.json keys every reader relies on


def _instances_png(instances: np.ndarray, name: str) -> np.ndarray:
    """An (H, W) integer map as the uint16 a 16-bit PNG stores; ValueError naming bad ids."""
    a = np.asarray(instances)
    if a.ndim != 2 or not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{name} must be an (H, W) integer map, got shape {a.shape}, dtype {a.dtype}")
    if a.size and (a.min() < 0 or a.max() > 65535):
        raise ValueError(f"{name} ids must be in [0, 65535] (16-bit PNG), got [{a.min()}, {a.max()}]")
    return a.astype(np.uint16)


@dataclass(frozen=True)
class ViewFiles:
    """The files of one rendered view folder ``dir`` (named, not read): image.png, instances.png,
    ignore.png (present only when view.json lists ignore regions) and view.json."""

    dir: Path

    @property
    def name(self) -> str:
        """The folder's name, e.g. "000012"."""
        return self.dir.name

    @property
    def image(self) -> Path:
        return self.dir / "image.png"

    @property
    def instances(self) -> Path:
        return self.dir / "instances.png"

    @property
    def ignore(self) -> Path:
        return self.dir / "ignore.png"

    @property
    def view_json(self) -> Path:
        return self.dir / "view.json"

    def complete(self) -> bool:
        """True when view.json, written last, and the two PNGs every view has are files."""
        return all(p.is_file() for p in (self.view_json, self.image, self.instances))


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

    def window_masks(self) -> list[SparseMask]:
        """One SparseMask per view.json window, in order, from instances.png (empty when hidden)."""
        return instance_masks(self.instances, [int(w["instance_id"]) for w in self.windows])

    def ignore_masks(self) -> list[tuple[dict, SparseMask]]:
        """(region, its mask from ignore.png) of every listed ignore region present in the view."""
        regions = self.ignore_regions
        if not regions:
            return []
        masks = instance_masks(self.ignore, [int(r["instance_id"]) for r in regions])
        return [(r, m) for r, m in zip(regions, masks) if m.area]


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
    p = ViewFiles(Path(view_dir)).view_json
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
    f = ViewFiles(Path(view_dir))
    meta = read_meta(f.dir)
    image, instances = read_image(f.image), read_instances(f.instances)
    ignore = read_instances(f.ignore) if meta.get("ignore") else None
    for p, a in ((f.image, image), (f.instances, instances), (f.ignore, ignore)):
        if a is not None and a.shape[:2] != (meta["height"], meta["width"]):
            raise DatasetError(f"{p} is {a.shape[1]}x{a.shape[0]} px, view.json says "
                               f"{meta['width']}x{meta['height']}")
    return View(image, instances, meta, ignore)


def view_annotations(view: View, image: str | int, masks: Sequence[SparseMask] | None = None) -> list[dict]:
    """The ground truth of one rendered view for :func:`coco_ground_truth`, image key ``image``:
    a :func:`gt_annotation` per window with visible pixels (keys ``window_id`` and
    ``visible_fraction`` added), in view.json order, then one ignore region (``iscrowd``, keys
    ``ignore_id``, ``kind``) per listed id present in ignore.png.

    masks: the windows' masks, one per view.json window in order (:meth:`View.window_masks`), when
    the caller has them already.
    """
    wins = view.windows
    masks = view.window_masks() if masks is None else masks
    if len(masks) != len(wins):
        raise ValueError(f"{len(masks)} masks for {len(wins)} windows")
    out = [gt_annotation(image, m.rle(), m.box(), m.area, window_id=w["id"],
                         visible_fraction=w.get("visible_fraction"))
           for w, m in zip(wins, masks) if m.area]
    return out + [gt_annotation(image, m.rle(), m.box(), m.area, ignore=True, ignore_id=r["id"], kind=r.get("kind"))
                  for r, m in view.ignore_masks()]

