"""A user's dataset: paths stay inside it, label files bounded, stems unique (issue 37: 5-7, 9).

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fault_helpers import (_photo, _replace, _set, _sparse, _then, bench_case, coco_case, fenestra, one_line_error,
                           yolo_case)


# ---------------------------------------------------------------- 8. dataset paths, label bounds, names (issue 37: 6, 7, 9)

SECRET = "root:x:0:0:fenestra-secret-line"  # content of a file outside the dataset: never printed


def _outside_file(d: Path, name: str, content: bytes | None = None) -> Path:
    """A file beside the dataset folder ds/ (outside it): the target of a symlink leading out."""
    p = d / name
    if content is None:
        _photo(p)
    else:
        p.write_bytes(content)
    return p


def labelmap_case(d: Path) -> list:
    """A label-map folder: a 64x48 photo and its label map (a red window on blue)."""
    _photo(d / "ds" / "images" / "a.png")
    lab = np.zeros((48, 64, 3), np.uint8)
    lab[:] = (255, 0, 0)  # blue, written as BGR
    lab[10:20, 10:30] = (0, 0, 255)  # red
    (d / "ds" / "labels").mkdir(parents=True)
    cv2.imwrite(str(d / "ds" / "labels" / "a.png"), lab)
    return ["check-data", "ds", "--format", "labelmap"]


def _link_out(rel: str, target: str, content: bytes | None = None):
    """After building: ds/<rel> becomes a symlink to ``target`` beside ds/ (outside the dataset)."""
    def after(d: Path) -> None:
        (d / "ds" / rel).unlink()
        (d / "ds" / rel).symlink_to(_outside_file(d, target, content))
    return after


def _photos_also(*names: str):
    def after(d: Path) -> None:
        for n in names:
            _photo(d / "ds" / "images" / n)
    return after


def _many_windows(n: int):
    def edit(doc):
        doc["annotations"] = [{"id": i + 1, "image_id": 1, "category_id": 1, "bbox": [10, 10, 20, 15]} for i in range(n)]
    return edit


def _no_stated_size(seg):
    def edit(doc):
        del doc["images"][0]["width"], doc["images"][0]["height"]
        doc["annotations"][0]["segmentation"] = seg
    return edit


# (case, builder, needles of the one error line); every case fails before a label is parsed or a mask decoded
DATASET_FAULTS = [
    ("yolo label symlinked to a file outside", _then(yolo_case("0 0.5 0.5 0.2 0.2\n"),
                                                     _link_out("labels/a.txt", "passwd", (SECRET + "\n").encode())),
     ["YOLO label file", "a.txt", "leads outside the dataset folder"]),
    ("label map symlinked to a file outside", _then(labelmap_case, _link_out("labels/a.png", "other.png")),
     ["label map", "a.png", "leads outside the dataset folder"]),
    ("yolo label file of 5 MB", _then(yolo_case(""), _replace("labels/a.txt", _sparse(5 * 2**20))),
     ["a.txt is 5.0 MB, more than the 4 MB limit (fenestra.conventions.LIMITS.max_label_bytes)"]),
    ("yolo label file of 100001 lines", yolo_case("0 0.5 0.5 0.01 0.01\n" * 100_001),
     ["a.txt has 100001 lines, more than the 100000 limit (fenestra.conventions.LIMITS.max_label_lines)"]),
    ("yolo 1001 window boxes", yolo_case("0 0.5 0.5 0.01 0.01\n" * 1001),
     ["a.txt: 1001 window boxes, more than the 1000 per photo"]),
    ("yolo box 30 times the photo", yolo_case("0 0.5 0.5 30 30\n"),
     ["a.txt:1: box w 30, h 30 is larger than the 64x48 photo"]),
    ("yolo photos a.png and a.jpg", _then(yolo_case("0 0.5 0.5 0.2 0.2\n"), _photos_also("a.jpg")),
     ["photos 'a.jpg' and 'a.png' differ only by case or extension"]),
    ("yolo photos a.png and A.PNG", _then(yolo_case("0 0.5 0.5 0.2 0.2\n"), _photos_also("A.PNG")),
     ["photos 'A.PNG' and 'a.png' differ only by case or extension"]),
    ("labelmap photos a.png and a.jpeg", _then(labelmap_case, _photos_also("a.jpeg")),
     ["photos 'a.jpeg' and 'a.png' differ only by case or extension"]),
    ("coco photos a.png and A.png", coco_case(photos=("a.png", "A.png")),
     ["images[1] file_name 'A.png' has the name 'A' of images[0] 'a.png'"]),
    ("coco unknown category_id", coco_case(_set("annotations.0.category_id", 7)),
     ["annotations[0] (id 1): category_id 7 matches no category (the file's: [1])"]),
    ("bench on coco with an unknown category_id", bench_case(coco_case(_set("annotations.0.category_id", 7))),
     ["annotations[0] (id 1): category_id 7 matches no category"]),
    ("coco RLE of 40000 x 40000 px, no stated size", coco_case(_no_stated_size({"size": [40000, 40000],
                                                                                 "counts": [1_600_000_000]})),
     ["annotations.json: annotations[0] (id 1): RLE size [40000, 40000] is 1600 Mpx, over the limit of 150 Mpx"]),
    ("coco RLE of another size than its photo, no stated size",
     coco_case(_no_stated_size({"size": [10, 10], "counts": [5, 95]})),
     ["annotations.json: annotations[0] (id 1): RLE size [10, 10] != the photo's [height, width] [48, 64]"]),
    ("coco RLE counts not covering its size", coco_case(_set("annotations.0.segmentation",
                                                             {"size": [48, 64], "counts": [5, 95]})),
     ["annotations[0] (id 1): RLE counts cover 100 pixels, not the 48 x 64 = 3072 of its size"]),
    ("coco 1001 window annotations on one photo", coco_case(_many_windows(1001)),
     ["image 1 (a.png) has 1001 window annotations, more than the 1000 per photo"]),
]


@pytest.mark.parametrize("case, build, needles", DATASET_FAULTS, ids=[c for c, _, _ in DATASET_FAULTS])
def test_dataset_fault_is_one_line_error(case, build, needles, tmp_path):
    r = fenestra(*build(tmp_path), cwd=tmp_path, timeout=120)
    one_line_error(r, *needles)
    assert SECRET not in r.stderr + r.stdout
