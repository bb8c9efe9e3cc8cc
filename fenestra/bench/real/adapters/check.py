"""``fenestra check-data DIR --format F``: read a dataset with its adapter and report what it
holds and what it refuses, without raising for the data's own problems (:func:`check_dataset`)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fenestra.bench.real.adapters import ADAPTERS
from fenestra.bench.real.adapters.coco import coco_problems
from fenestra.bench.views import LabelledView
from fenestra.errors import DatasetError
from fenestra.userfiles import inside, read_json


@dataclass(frozen=True)
class DataCheck:
    """What ``fenestra check-data`` found in a dataset folder.

    views: one line per photo read (name and its windows by kind of truth); refused: labels or
    files left out, with the reason; problems: errors that stop the dataset from being used
    (COCO lists every structural one; otherwise the first error met)."""

    folder: str
    format: str
    views: tuple[str, ...] = ()
    n_windows: int = 0
    refused: tuple[str, ...] = ()
    problems: tuple[str, ...] = ()


def _view_line(v: LabelledView) -> str:
    """'NAME WxH: n windows (q quads, m masks, b boxes, k with aspect, p partial)'."""
    ws = v.windows
    kinds = [f"{sum(getattr(w, k) is not None for w in ws)} {k}" for k in ("quad", "mask", "box", "aspect")]
    return (f"{v.name} {v.image.shape[1]}x{v.image.shape[0]}: {len(ws)} windows ({', '.join(kinds)}, "
            f"{sum(w.partial for w in ws)} partial), {len(v.ignore)} ignore regions")


def check_dataset(folder: str | Path, fmt: str, **options) -> DataCheck:
    """Read a dataset with its adapter and report (never raise for the data's own problems)."""
    if fmt not in ADAPTERS:
        raise DatasetError(f"--format {fmt!r} unknown; choose from {sorted(ADAPTERS)}")
    folder = Path(folder)
    if not folder.is_dir():
        raise DatasetError(f"dataset folder not found: {folder}")
    refused: list[str] = []
    if fmt == "coco":  # every structural problem, not only the first
        try:
            doc = read_json(inside(folder, options.get("annotations", "annotations.json"), "COCO annotations"),
                            "COCO annotations")
        except DatasetError as e:
            return DataCheck(str(folder), fmt, problems=(str(e),))
        problems = coco_problems(doc, str(folder / options.get("annotations", "annotations.json")))
        if problems:
            return DataCheck(str(folder), fmt, problems=tuple(problems))
    views = []
    n = 0
    try:
        for v in ADAPTERS[fmt](folder, refused=refused, **options):
            views.append(_view_line(v))
            n += len(v.windows)
    except (DatasetError, ValueError, OSError) as e:
        return DataCheck(str(folder), fmt, tuple(views), n, tuple(refused), (str(e),))
    return DataCheck(str(folder), fmt, tuple(views), n, tuple(refused))
