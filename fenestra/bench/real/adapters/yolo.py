"""YOLO txt boxes -> LabelledViews (:func:`read_yolo`); lines parsed by fenestra.yolo."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from fenestra.bench.real.adapters.common import OUTSIDE_TOL_PX, dataset_file_or_none, dataset_photos, refuse
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra.conventions import LIMITS
from fenestra.errors import DatasetError
from fenestra.images import read_image
from fenestra.masks import box_from_coco
from fenestra.userfiles import inside
from fenestra.yolo import YoloBox, parse_yolo, read_label_file


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


def _too_large(b: YoloBox, width: int, height: int) -> bool:
    """True for a box wider or taller than the photo (beyond OUTSIDE_TOL_PX of rounding each side):
    YOLO sizes are fractions of the photo, so such a box is a wrong label, never a window to clip."""
    return b.w * width > width + 2 * OUTSIDE_TOL_PX or b.h * height > height + 2 * OUTSIDE_TOL_PX


def read_yolo(path: Path, images: str = "images", labels: str = "labels", classes=(0,),
              dataset: str = "yolo", refused: list[str] | None = None, every: int = 1) -> Iterator[LabelledView]:
    """YOLO txt boxes: ``path/images/NAME.jpg`` with ``path/labels/NAME.txt``; windows are the
    boxes of ``classes`` (ids). Boxes only: quad, mask, aspect and K are missing. A photo without
    a label file has no windows. A box partly outside the photo is clipped to it; one entirely
    outside is dropped and recorded in ``refused`` (never an evaluable window); one larger than
    the photo is an error; label files without a photo are recorded too. A label file must lie
    inside ``path`` once resolved and be a regular file within LIMITS.max_label_bytes and
    max_label_lines (fenestra.yolo.read_label_file), checked before it is parsed. every > 1: only the photos with a label file whose index
    in name order is a multiple of ``every`` (the held-out "val" part of training.dataset.real_box_photos)."""
    classes = _classes(classes)
    if not (isinstance(every, int) and not isinstance(every, bool) and every >= 1):
        raise DatasetError(f"YOLO option every must be an integer >= 1, got {every!r}")
    root = Path(path)
    photos = dataset_photos(inside(root, images, "YOLO images folder"), refused)
    lab_dir = inside(root, labels, "YOLO labels folder")
    stems = {p.stem for p in photos}
    if lab_dir.is_dir():
        for orphan in sorted(q for q in lab_dir.glob("*.txt") if q.stem not in stems):
            refuse(refused, f"{orphan}: no photo {orphan.stem}.* in {root / images}; skipped")
    if every > 1:
        photos = [p for p in photos if (lab_dir / (p.stem + ".txt")).is_file()][::every]
    for p in photos:
        lab = dataset_file_or_none(root, str(Path(labels) / (p.stem + ".txt")), "YOLO label file")
        boxes = [b for b in ([] if lab is None else parse_yolo(read_label_file(lab), str(lab))) if b.cls in classes]
        if len(boxes) > LIMITS.max_windows_per_photo:
            raise DatasetError(f"{lab}: {len(boxes)} window boxes, more than the {LIMITS.max_windows_per_photo} per "
                               "photo (fenestra.conventions.LIMITS.max_windows_per_photo)")
        photo = read_image(p)
        wins = []
        for b in boxes:
            if _too_large(b, photo.shape[1], photo.shape[0]):
                raise DatasetError(f"{lab}:{b.line}: box w {b.w:g}, h {b.h:g} is larger than the "
                                   f"{photo.shape[1]}x{photo.shape[0]} photo (YOLO sizes are fractions of it)")
            box = yolo_window_box(b, photo.shape[1], photo.shape[0])
            if box is None:
                refuse(refused, f"{lab}:{b.line}: box (cx {b.cx:g}, cy {b.cy:g}, w {b.w:g}, h {b.h:g}) lies "
                                 "entirely outside the photo; dropped")
                continue
            wins.append(LabelledWindow(id=f"{p.stem}:{len(wins)}", box=box))
        yield LabelledView(dataset=dataset, name=p.stem, image=photo, windows=tuple(wins))
