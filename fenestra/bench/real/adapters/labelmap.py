"""Semantic label maps -> LabelledViews (:func:`read_labelmap`): window instances as the connected
components of one colour or class id."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from fenestra.bench.real.adapters.common import components, dataset_file, dataset_photos
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra.errors import DatasetError
from fenestra.images import decode_file, read_image
from fenestra.userfiles import inside


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
    """A label map as (H, W) ids or (H, W, 3) RGB; ``p`` already resolved (common.dataset_file)."""
    m = decode_file(p, cv2.IMREAD_UNCHANGED, "label map")
    return m if m.ndim == 2 else cv2.cvtColor(m[..., :3], cv2.COLOR_BGR2RGB)


def read_labelmap(path: Path, images: str = "images", labels: str = "labels", window=(255, 0, 0),
                  min_area_px: float = 0.0, dataset: str = "labelmap",
                  refused: list[str] | None = None) -> Iterator[LabelledView]:
    """Semantic label maps: ``path/labels/NAME.png`` beside ``path/images/NAME.jpg``; the window
    class is ``window`` (an [r, g, b] colour or an integer id); instances are its 4-connected
    components of at least ``min_area_px`` px (at most LIMITS.max_windows_per_photo, checked
    before any mask is built). Masks only; components touching the border are ``partial``. A
    label map must lie inside ``path`` once resolved and be a regular file (common.dataset_file);
    its pixels are bounded like a photo's (fenestra.images)."""
    root = Path(path)
    inside(root, labels, "label-map folder")
    for p in dataset_photos(inside(root, images, "label-map images folder"), refused):
        lab_path = dataset_file(root, str(Path(labels) / (p.stem + ".png")), "label map")
        photo = read_image(p)
        lab = _read_label(lab_path)
        if lab.shape[:2] != photo.shape[:2]:
            raise DatasetError(f"{lab_path}: label map {lab.shape[1]}x{lab.shape[0]} != photo "
                               f"{photo.shape[1]}x{photo.shape[0]}")
        comps = components(window_pixels(lab, window, str(lab_path)), min_area_px, str(lab_path))
        wins = tuple(LabelledWindow(id=f"{p.stem}:{i}", mask=c.sparse(), partial=c.touches_border)
                     for i, c in enumerate(comps))
        yield LabelledView(dataset=dataset, name=p.stem, image=photo, windows=wins)
