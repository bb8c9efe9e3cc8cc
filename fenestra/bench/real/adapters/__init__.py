"""Real-dataset adapters: a folder in a published format -> LabelledViews (bench.views), one
module per format (coco.py, yolo.py, labelmap.py, curtainwall.py; common.py: what they share;
check.py: ``fenestra check-data``).

    ADAPTERS: Registry("dataset format"): coco, yolo, labelmap, curtainwall (Adapter entries)
    views = list(ADAPTERS["coco"](Path("my_photos"), category="window"))

Every adapter takes the dataset folder and keyword options (the profile's ``options`` table) and
yields one LabelledView per photo, sorted by file name, with exactly the ground truth the format
carries (see each reader). Coordinates are converted from the format's pixel-edge convention
(pixel (0, 0) covers [0, 1]^2) to fenestra's (pixel centres at integers) by subtracting 0.5.

Ground truth is validated, never silently bent: a problem that makes the labels wrong (an
annotation of an unknown image or category, duplicate ids, two photos whose names differ only
by case or extension, a malformed polygon or RLE, a box outside or larger than its photo, a
stated size that is not the decoded photo's, a file the dataset names (photo, label, label map,
mask, K.json) leading outside the dataset folder or not a regular file, a JSON or label file
over its fenestra.conventions.LIMITS) is a DatasetError naming the file, entry and field, never
quoting a file's content. A label that can be left out without changing the others (a YOLO box
entirely off its photo, a label file without a photo, a FIFO among the photos) is dropped and
recorded in the ``refused`` list an adapter takes (a stderr warning when None).
``check_dataset`` (check.py) reports both without raising.
"""
from __future__ import annotations

import inspect
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from fenestra.bench.real.adapters.coco import read_coco
from fenestra.bench.real.adapters.curtainwall import CURTAIN_K, read_curtainwall
from fenestra.bench.real.adapters.labelmap import read_labelmap
from fenestra.bench.real.adapters.yolo import read_yolo
from fenestra.bench.views import LabelledView
from fenestra.errors import DatasetError
from fenestra.registry import Registry

__all__ = ["ADAPTERS", "Adapter", "CURTAIN_K", "read_coco", "read_curtainwall", "read_labelmap", "read_yolo"]


@dataclass(frozen=True)
class Adapter:
    """A registered dataset format: ``read(folder, **options) -> Iterator[LabelledView]``; calling the
    entry calls its reader. description: one line for CLI help."""

    name: str
    read: Callable[..., Iterator[LabelledView]]
    description: str

    def __call__(self, folder: Path, **options) -> Iterator[LabelledView]:
        """The reader's views; DatasetError naming an option the reader does not take (and those it
        does), before anything is read."""
        params = list(inspect.signature(self.read).parameters.values())[1:]  # after the folder
        known = [p.name for p in params if p.name != "refused"]
        unknown = sorted(set(options) - set(known) - {"refused"})
        if unknown and not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params):
            raise DatasetError(f"dataset format {self.name!r} has no option {', '.join(map(repr, unknown))}; "
                               f"its options: {', '.join(known)}")
        return self.read(folder, **options)


ADAPTERS: Registry[Adapter] = Registry("dataset format", [
    Adapter("coco", read_coco, "COCO instances JSON: boxes, polygon or RLE masks, 4-vertex polygons as quads"),
    Adapter("yolo", read_yolo, "YOLO txt: window boxes of the given class ids"),
    Adapter("labelmap", read_labelmap, "semantic label-map PNGs: window instances as components of one colour or id"),
    Adapter("curtainwall", read_curtainwall, "the bundled curtain-wall photos: pane masks, known pane size, calibration"),
])
