"""Small, realistic user datasets for tests: the bundled curtain-wall photos (data/real/curtainwall,
CC BY 4.0) undistorted and shrunk 4x, their glass panes written in a user's format.

    panes = curtain_panes(2)                       # [(name, rgb (512, 384, 3), [Pane])]
    write_yolo(tmp / "y", panes)                   # images/*.jpg, labels/*.txt: windows 0, signboards 3, doors 5
    write_coco(tmp / "c", panes)                   # boxes, 4-vertex polygons, RLE (compressed and not), a door
    write_labelmap(tmp / "l", panes)               # labels/*.png: glass red, the rest blue

Pane truth comes from the dataset's own masks (read_curtainwall), so the numbers a test expects
are counted here, independently of the adapter under test.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from pycocotools import mask as mask_utils

ROOT = Path(__file__).resolve().parents[1]
CURTAIN = ROOT / "data" / "real" / "curtainwall"
SCALE = 4  # 1536 x 2048 -> 384 x 512


@dataclass(frozen=True)
class Pane:
    """One glass pane at the small size: mask (H, W) bool, bbox [x, y, w, h] (pixel edges),
    polygon: 4 vertices [x1, y1, ...] (pixel edges), partial: cut by the photo border."""

    mask: np.ndarray
    bbox: list[float]
    polygon: list[float]
    partial: bool


def _pane(mask: np.ndarray) -> Pane:
    ys, xs = np.nonzero(mask)
    x0, y0, x1, y1 = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
    cs, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    quad = cv2.boxPoints(cv2.minAreaRect(max(cs, key=cv2.contourArea)))  # (4, 2) around the pixel centres
    quad = np.clip(quad + 0.5, 0, [mask.shape[1], mask.shape[0]])  # pixel edges, inside the photo
    h, w = mask.shape
    partial = bool(x0 == 0 or y0 == 0 or x1 == w or y1 == h)
    return Pane(mask, [float(x0), float(y0), float(x1 - x0), float(y1 - y0)],
                [float(v) for v in quad.reshape(-1)], partial)


def curtain_panes(n: int = 2) -> list[tuple[str, np.ndarray, list[Pane]]]:
    """The first ``n`` curtain-wall photos, undistorted, 4x smaller, with their panes."""
    from fenestra.bench.real.adapters import read_curtainwall

    out = []
    for v in list(read_curtainwall(CURTAIN))[:n]:
        h, w = v.image.shape[0] // SCALE, v.image.shape[1] // SCALE
        rgb = cv2.resize(v.image, (w, h), interpolation=cv2.INTER_AREA)
        panes = []
        for win in v.windows:
            m = cv2.resize(win.mask.dense().astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)
            if m.sum() >= 50:
                panes.append(_pane(m))
        out.append((v.name, rgb, panes))
    return out


def write_photo(path: Path, rgb: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.ascontiguousarray(rgb[..., ::-1]))
    return path


def _yolo_line(cls: int, x: float, y: float, w: float, h: float, W: int, H: int) -> str:
    return f"{cls} {(x + w / 2) / W:.6f} {(y + h / 2) / H:.6f} {w / W:.6f} {h / H:.6f}"


def write_yolo(folder: Path, views) -> int:
    """A YOLO folder (windows class 0, a signboard 3 and a door 5 per photo); the window count."""
    n = 0
    for name, rgb, panes in views:
        H, W = rgb.shape[:2]
        write_photo(folder / "images" / f"{name}.jpg", rgb)
        lines = [_yolo_line(3, 20, 10, 120, 30, W, H), _yolo_line(5, 150, 400, 60, 110, W, H)]
        lines += [_yolo_line(0, *p.bbox, W, H) for p in panes]
        (folder / "labels").mkdir(parents=True, exist_ok=True)
        (folder / "labels" / f"{name}.txt").write_text("\n".join(lines) + "\n")
        n += len(panes)
    return n


def coco_doc(views, file_names: list[str]) -> dict:
    """COCO instances: per pane in turn a bbox only, a 4-vertex polygon (with size_m if whole), a
    compressed RLE, an uncompressed RLE; each with its bbox; plus one door (category 2) per photo."""
    doc = {"images": [], "categories": [{"id": 1, "name": "window"}, {"id": 2, "name": "door"}], "annotations": []}
    for k, ((_, rgb, panes), fname) in enumerate(zip(views, file_names)):
        img_id = 10 * (k + 1)
        doc["images"].append({"id": img_id, "file_name": fname, "width": rgb.shape[1], "height": rgb.shape[0]})
        for j, p in enumerate(panes):
            a = {"id": len(doc["annotations"]) + 1, "image_id": img_id, "category_id": 1, "bbox": p.bbox,
                 "iscrowd": 0, "area": float(p.mask.sum())}
            if j % 4 == 1:
                a["segmentation"] = [p.polygon]
                if not p.partial:
                    a["size_m"] = [0.0932, 0.1432]
            elif j % 4 == 2:
                rle = mask_utils.encode(np.asfortranarray(p.mask.astype(np.uint8)))
                a["segmentation"] = {"size": list(rle["size"]), "counts": rle["counts"].decode("ascii")}
            elif j % 4 == 3:
                flat = p.mask.T.reshape(-1).astype(np.int8)  # column-major run lengths, starting with 0s
                edges = np.flatnonzero(np.diff(np.r_[0, flat, 1 - flat[-1]]))
                a["segmentation"] = {"size": list(p.mask.shape), "counts": np.diff(np.r_[0, edges]).tolist()}
            doc["annotations"].append(a)
        doc["annotations"].append({"id": len(doc["annotations"]) + 1, "image_id": img_id, "category_id": 2,
                                   "bbox": [150, 400, 60, 110], "iscrowd": 0})
    return doc


def write_coco(folder: Path, views) -> int:
    """A COCO folder (images/ + annotations.json, see coco_doc); the window count."""
    names = [f"{name}.jpg" for name, _, _ in views]
    for (name, rgb, _), f in zip(views, names):
        write_photo(folder / "images" / f, rgb)
    (folder / "annotations.json").write_text(json.dumps(coco_doc(views, names)))
    return sum(len(p) for _, _, p in views)


def write_labelmap(folder: Path, views) -> int:
    """A label-map folder: labels/NAME.png RGB, glass (255, 0, 0), everything else (0, 0, 255)."""
    n = 0
    for name, rgb, panes in views:
        write_photo(folder / "images" / f"{name}.jpg", rgb)
        lab = np.zeros_like(rgb)
        lab[:] = (0, 0, 255)
        for p in panes:
            lab[p.mask] = (255, 0, 0)
        write_photo(folder / "labels" / f"{name}.png", lab)
        n += len(panes)
    return n
