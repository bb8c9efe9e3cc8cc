"""Read rendered dataset folders (DESIGN.md data contract) for detector training and evaluation.

A dataset folder holds ``views/NNNNNN/image.png`` (RGB), ``views/NNNNNN/instances.png`` (uint16,
0 = no window, k = the window with ``instance_id`` k), ``views/NNNNNN/view.json`` and a
``coco.json`` with RLE masks (fenestra.rendered_view: the view contract and its one reader; fenestra.coco: the COCO builder).
Only the files are read: pipeline/ never imports renders/.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fenestra.rendered_view import ViewFiles
from fenestra.yolo import read_label_file, yolo_boxes
from fenestra.errors import DatasetError
from fenestra.images import read_image
from fenestra.pipeline.quad import order_corners


def list_views(dataset_dir: str | Path) -> list[ViewFiles]:
    """The complete views of a dataset folder (fenestra.rendered_view.ViewFiles: view.json, written
    last, and both PNGs present), sorted by name; read each with fenestra.rendered_view.read_view.
    DatasetError if there are none."""
    root = Path(dataset_dir)
    views_dir = root / "views"
    if not views_dir.is_dir():
        raise DatasetError(f"{root} is not a dataset folder: no views/ directory inside")
    out = [v for v in (ViewFiles(d) for d in sorted(p for p in views_dir.iterdir() if p.is_dir())) if v.complete()]
    if not out:
        raise DatasetError(f"{views_dir} has no complete view folder (view.json, image.png, instances.png)")
    return out


def find_datasets(paths) -> list[Path]:
    """Dataset folders (those with a views/ directory) among ``paths`` and up to 2 levels below.

    Lets a config name a root such as ``out/detector-data/train`` holding many rendered datasets.
    Raises DatasetError naming a path that is missing or holds no dataset.
    """
    found: list[Path] = []
    for p in (Path(x) for x in paths):
        if not p.is_dir():
            raise DatasetError(f"dataset path {p} does not exist")
        if (p / "views").is_dir():
            found.append(p)
            continue
        below = sorted({v.parent for v in list(p.glob("*/views")) + list(p.glob("*/*/views")) if v.is_dir()})
        if not below:
            raise DatasetError(f"{p} holds no dataset folder (no views/ inside it or below it)")
        found += below
    return found


def load_coco(dataset_dir: str | Path) -> dict:
    """The dataset's coco.json as a dict; raises DatasetError if missing."""
    p = Path(dataset_dir) / "coco.json"
    if not p.is_file():
        raise DatasetError(f"{dataset_dir} has no coco.json")
    return json.loads(p.read_text())


def coco_image_path(dataset_dir: str | Path, image_entry: dict) -> Path:
    """Path of a coco.json image entry's file (file_name relative to the dataset folder)."""
    root = Path(dataset_dir)
    p = root / image_entry["file_name"]
    if not p.is_file():
        raise DatasetError(f"coco.json image {image_entry.get('id')} file {p} does not exist")
    return p


def view_corners(meta: dict) -> np.ndarray:
    """(N, 4, 2) float32 px: the corners of every window facing the camera in a view.json dict
    (fenestra.rendered_view.View.meta), ordered
    TL TR BR BL in the image (pipeline.quad.order_corners); a corner the renderer marks unseen
    (occluded or outside the image: ``corner_visible``) is NaN. (0, 4, 2) without windows. A view
    without ``visible_fraction`` / ``corner_visible`` (hand-made data) counts every corner seen."""

    out = []
    for w in meta.get("windows", []):
        if w.get("visible_fraction", 1.0) <= 0.0:
            continue
        q = np.asarray(w["corners_px"], dtype=np.float64)
        seen = np.asarray(w.get("corner_visible", [True] * 4), dtype=bool)
        o = order_corners(q)
        idx = [int(np.argmin(np.abs(q - p).sum(axis=1))) for p in o]  # where each ordered corner came from
        o[~seen[idx]] = np.nan
        out.append(o)
    return np.asarray(out, dtype=np.float32).reshape(-1, 4, 2)


@dataclass(frozen=True, eq=False)
class WindowQuads:
    """Every window's whole quad in one training image, for the quad head (detector v8).

    ids: (N,) int, each window's value in the image's instance map; corners: (N, 4, 2) float64 px,
    TL TR BR BL in image order (pipeline.quad.order_corners), also where a corner is occluded or
    outside the image (the exact projection of the opening's outline on the wall's exterior face).
    exact: the corners are the truth's (renders), not a box's (real photos' labels).
    """

    ids: np.ndarray
    corners: np.ndarray
    exact: bool = True


def view_quads(meta: dict) -> WindowQuads:
    """The WindowQuads of a view.json dict: every window with a visible fraction above 0 (or none
    stated) and finite corners, its ``instance_id`` and ``corners_px`` ordered."""

    ids, quads = [], []
    for w in meta.get("windows", []):
        q = np.asarray(w["corners_px"], dtype=np.float64)
        if w.get("visible_fraction", 1.0) <= 0.0 or q.shape != (4, 2) or not np.all(np.isfinite(q)):
            continue
        ids.append(int(w["instance_id"]))
        quads.append(order_corners(q))
    return WindowQuads(np.asarray(ids, dtype=np.int64), np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2))


def box_photo_quads(photo: Path, shape: tuple[int, int], classes: tuple[int, ...] = (0,)) -> WindowQuads:
    """The WindowQuads of a YOLO photo of (H, W) = shape px: box k (read_box_photo's id k + 1) as
    the quad (x0, y0), (x1, y0), (x1, y1), (x0, y1); not exact (a box, not the window's corners)."""
    text, where = photo_labels(photo)
    boxes = yolo_boxes(text, shape[1], shape[0], classes, where)
    quads = [[[b[0], b[1]], [b[2], b[1]], [b[2], b[3]], [b[0], b[3]]] for b in boxes]
    return WindowQuads(np.arange(1, len(boxes) + 1), np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2), exact=False)


def box_instances(boxes: list[np.ndarray], shape: tuple[int, int]) -> np.ndarray:
    """(H, W) int32 instance map painted from boxes (4,) x0 y0 x1 y1 px (pixel-edge outline,
    centres at integers): id k + 1 covers the pixel centres inside box k; larger boxes are painted
    first, so a small box on a big one stays visible."""
    H, W = shape
    inst = np.zeros((H, W), dtype=np.int32)
    for k in sorted(range(len(boxes)), key=lambda k: -float((boxes[k][2] - boxes[k][0]) * (boxes[k][3] - boxes[k][1]))):
        x0, y0, x1, y1 = boxes[k]
        c0, c1 = max(0, int(np.ceil(x0))), min(W, int(np.ceil(x1)))
        r0, r1 = max(0, int(np.ceil(y0))), min(H, int(np.ceil(y1)))
        inst[r0:r1, c0:c1] = k + 1
    return inst


def real_box_photos(root: str | Path, part: str, holdout_every: int = 5) -> list[Path]:
    """Photos of a YOLO folder (``root/images/*.jpg``, ``root/labels/*.txt``), split by sorted
    name: ``part`` "val" is every ``holdout_every``-th photo (index % n == 0), "train" the rest,
    "all" every photo. Photos without a label file are left out (not known to hold no window)."""
    if part not in ("train", "val", "all"):
        raise ValueError(f"part must be train, val or all, got {part!r}")
    if holdout_every < 2:
        raise ValueError(f"holdout_every must be >= 2, got {holdout_every}")
    images = Path(root) / "images"
    if not images.is_dir():
        raise DatasetError(f"{root}: no images/ folder (a YOLO dataset has images/ and labels/)")
    photos = sorted((p for p in images.iterdir() if p.suffix.lower() in (".jpg", ".jpeg", ".png")),
                    key=lambda p: p.name)
    photos = [p for p in photos if (Path(root) / "labels" / f"{p.stem}.txt").is_file()]
    if not photos:
        raise DatasetError(f"{images} has no photo with a label file in {Path(root) / 'labels'}")
    keep = {"all": lambda i: True, "val": lambda i: i % holdout_every == 0,
            "train": lambda i: i % holdout_every != 0}[part]
    return [p for i, p in enumerate(photos) if keep(i)]


def photo_labels(photo: Path) -> tuple[str, str]:
    """(text, path as text) of the YOLO label file of a photo of a YOLO folder (``labels/NAME.txt``
    beside ``images/NAME.jpg``), bounded before it is read (fenestra.yolo.read_label_file)."""
    lab = photo.parent.parent / "labels" / f"{photo.stem}.txt"
    return read_label_file(lab), str(lab)


def read_box_photo(photo: Path, classes: tuple[int, ...] = (0,)) -> tuple[np.ndarray, np.ndarray, None]:
    """(image (H, W, 3) uint8, box instance map (H, W) int32, None: no corners) of a YOLO photo."""
    image = read_image(photo)
    text, where = photo_labels(photo)
    boxes = yolo_boxes(text, image.shape[1], image.shape[0], classes, where)
    return image, box_instances(boxes, image.shape[:2]), None
