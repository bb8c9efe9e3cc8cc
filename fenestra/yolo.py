"""YOLO label files, parsed once: ``class cx cy w h`` per line, normalised to the photo size.

    text = read_label_file(path, "YOLO label file")  # regular file, bounded (LIMITS) before reading
    boxes = parse_yolo(text, str(path))              # [YoloBox], DatasetError naming path:line
    yolo_boxes(text, W, H, (0,), str(path))          # (4,) x0 y0 x1 y1 px of the class-0 boxes

The bench's YOLO adapter (fenestra.bench.real.adapters.yolo) and the detectors' training on real
box photos (fenestra.training) read labels through these. Ground floor: imports nothing above
fenestra/.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fenestra.conventions import LIMITS
from fenestra.errors import DatasetError
from fenestra.masks import box_from_coco
from fenestra.userfiles import read_text


@dataclass(frozen=True)
class YoloBox:
    """One parsed YOLO line: class id and the box (cx, cy, w, h) normalised to the photo size."""

    line: int
    cls: int
    cx: float
    cy: float
    w: float
    h: float


def read_label_file(path: str | Path, what: str = "YOLO label file") -> str:
    """The text of a label file: a regular file of at most LIMITS.max_label_bytes and
    LIMITS.max_label_lines lines, both checked before its lines are parsed; DatasetError naming
    the file otherwise (never quoting its content)."""
    text = read_text(path, what, LIMITS.max_label_bytes, "max_label_bytes")
    n = text.count("\n") + (not text.endswith("\n"))
    if n > LIMITS.max_label_lines:
        raise DatasetError(f"{what} {path} has {n} lines, more than the {LIMITS.max_label_lines} limit "
                           "(fenestra.conventions.LIMITS.max_label_lines)")
    return text


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
            raise DatasetError(f"{where}:{k}: bad YOLO line {line.strip()[:80]!r}: need 'class cx cy w h' (5 numbers)")
        c, cx, cy, bw, bh = vals
        if not (math.isfinite(c) and c >= 0 and c.is_integer()):
            raise DatasetError(f"{where}:{k}: class {parts[0][:20]!r} is not a non-negative integer class id")
        if not all(math.isfinite(v) for v in (cx, cy, bw, bh)) or bw <= 0 or bh <= 0:
            raise DatasetError(f"{where}:{k}: box {parts[1:]} needs finite numbers with w, h > 0")
        out.append(YoloBox(k, int(c), cx, cy, bw, bh))
    return out


def yolo_boxes(text: str, width: int, height: int, classes: tuple[int, ...], where: str) -> list[np.ndarray]:
    """Boxes (4,) x0 y0 x1 y1 px (fenestra convention, not clipped) of the lines of
    :func:`parse_yolo` whose class is in ``classes``, for a ``width`` x ``height`` photo."""
    return [box_from_coco([(b.cx - b.w / 2) * width, (b.cy - b.h / 2) * height, b.w * width, b.h * height])
            for b in parse_yolo(text, where) if b.cls in classes]
