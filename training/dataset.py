"""Read rendered dataset folders (DESIGN.md data contract) for detector training and evaluation.

A dataset folder holds ``views/NNNNNN/image.png`` (RGB), ``views/NNNNNN/instances.png`` (uint16,
0 = no window, k = the window with ``instance_id`` k), ``views/NNNNNN/view.json`` and a
``coco.json`` with RLE masks (fenestra.data: the contract, its readers and the COCO builder).
Only the files are read: pipeline/ never imports renders/.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from fenestra.data import DatasetError


@dataclass(frozen=True)
class ViewFiles:
    """Paths of one rendered view."""

    name: str  # e.g. "000012"
    image: Path
    instances: Path
    view_json: Path


def list_views(dataset_dir: str | Path) -> list[ViewFiles]:
    """All views of a dataset folder, sorted by name; raises DatasetError if there are none."""
    root = Path(dataset_dir)
    views_dir = root / "views"
    if not views_dir.is_dir():
        raise DatasetError(f"{root} is not a dataset folder: no views/ directory inside")
    out = []
    for d in sorted(p for p in views_dir.iterdir() if p.is_dir()):
        img, inst = d / "image.png", d / "instances.png"
        if img.is_file() and inst.is_file():
            out.append(ViewFiles(d.name, img, inst, d / "view.json"))
    if not out:
        raise DatasetError(f"{views_dir} has no view folders with image.png and instances.png")
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
