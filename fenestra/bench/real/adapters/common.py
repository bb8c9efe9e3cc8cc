"""What every dataset adapter shares: the photos of a folder, the files a dataset names, refusals,
the format-to-fenestra pixel convention and connected components of a label image.

    photos = dataset_photos(folder / "images", refused)   # regular files inside, names unique
    lab = dataset_file(root, "labels/a.txt", "YOLO label file")  # inside root, a regular file
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from fenestra.conventions import LIMITS
from fenestra.errors import DatasetError
from fenestra.masks import SparseMask
from fenestra.userfiles import inside, is_regular, regular_file

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
EDGE_TO_CENTRE = 0.5  # format coordinates (pixel edges at integers) -> fenestra (centres at integers)
OUTSIDE_TOL_PX = 1.0  # a label may overhang the photo by this much (rounding); more is an error


def refuse(refused: list[str] | None, message: str) -> None:
    """Record a label or file left out (``refused`` list), or warn on stderr when nobody collects."""
    if refused is None:
        print(f"warning: {message}", file=sys.stderr)
    else:
        refused.append(message)


def view_name_key(name: str) -> str:
    """The key two photos may not share: a view is named by its photo's stem, and a label file
    (NAME.txt, NAME.png) belongs to that stem, on file systems that ignore case too."""
    return Path(name).stem.casefold()


def dataset_photos(folder: Path, refused: list[str] | None = None) -> list[Path]:
    """Photos directly in ``folder`` (jpg/jpeg/png regular files inside it), sorted; a FIFO,
    device or symlink leading outside is refused (recorded). DatasetError for an empty folder
    or for two photos whose names differ only by case or extension (a.jpg, a.JPG, A.png): their
    views and label files would be one."""
    if not folder.is_dir():
        raise FileNotFoundError(f"image folder not found: {folder}")
    out = []
    for p in sorted(_photo_names(folder)):
        try:
            inside(folder, p.name, f"{folder}")
        except DatasetError as e:
            refuse(refused, f"{p}: {e}; skipped")
            continue
        if is_regular(p):
            out.append(p)
        else:
            refuse(refused, f"{p}: not a regular file (a folder, FIFO or device); skipped")
    if not out:
        raise DatasetError(f"no .jpg/.png photos in {folder}")
    seen: dict[str, Path] = {}
    for p in out:
        other = seen.setdefault(view_name_key(p.name), p)
        if other is not p:
            raise DatasetError(f"{folder}: photos {other.name!r} and {p.name!r} differ only by case or extension "
                               "(one view name, one label file); rename one")
    return out


def _photo_names(folder: Path) -> list[Path]:
    """The .jpg/.jpeg/.png entries of ``folder``, unsorted; DatasetError as soon as there are more than
    LIMITS.max_dataset_photos (the listing stops there)."""
    names = []
    for q in folder.iterdir():
        if q.suffix.lower() in IMAGE_SUFFIXES:
            names.append(q)
            if len(names) > LIMITS.max_dataset_photos:
                raise DatasetError(f"{folder}: more than the {LIMITS.max_dataset_photos} photos a dataset may have "
                                   "(fenestra.conventions.LIMITS.max_dataset_photos)")
    return names


def dataset_file(root: Path, name: str, what: str) -> Path:
    """``root / name``, a file the dataset names (a label, a mask, K.json): DatasetError naming it
    when it leads outside ``root`` once resolved (``..``, a symlink out) or is not a regular
    file (a FIFO, a device, a folder), before a byte of it is read."""
    return regular_file(inside(root, name, f"{what} {Path(root) / name}"), what)


def dataset_file_or_none(root: Path, name: str, what: str) -> Path | None:
    """:func:`dataset_file`, or None when nothing (not even a dangling link) is at ``root / name``."""
    return dataset_file(root, name, what) if os.path.lexists(Path(root) / name) else None


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
