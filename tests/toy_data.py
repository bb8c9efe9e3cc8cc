"""A tiny synthetic dataset in the rendered-dataset format, for tests only.

Textured "walls" with dark quadrilateral "voids" drawn by OpenCV. The shipped models are trained on
real renders of IFC houses (see fenestra/pipeline/models/README.md), never on this.
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from fenestra import files
from fenestra.coco import coco_ground_truth, gt_annotation
from fenestra.masks import instance_masks
from fenestra.rendered_view import write_view


def toy_view(rng: np.random.Generator, width: int = 160, height: int = 120,
             n_windows: int = 3) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """One toy view: RGB image (H, W, 3) uint8, instance map (H, W) uint16, quads (list of (4, 2))."""
    wall = rng.uniform(80, 220, 3)
    img = np.clip(wall + rng.normal(0, 12, (height, width, 3)), 0, 255).astype(np.float32)
    inst = np.zeros((height, width), np.uint16)
    quads = []
    cols = np.linspace(0, width, n_windows + 1)
    for k in range(n_windows):
        w = rng.uniform(0.45, 0.7) * (cols[1] - cols[0])
        h = rng.uniform(0.35, 0.6) * height
        x0 = rng.uniform(cols[k] + 2, cols[k + 1] - w - 2)
        y0 = rng.uniform(4, height - h - 4)
        q = np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]])
        q += rng.normal(0, 1.5, q.shape)  # a touch of perspective
        pts = np.round(q * 16).astype(np.int32)
        m = np.zeros((height, width), np.uint8)
        cv2.fillPoly(m, [pts], 1, lineType=cv2.LINE_8, shift=4)
        glass = rng.uniform(10, 70, 3)
        grad = np.linspace(0, 40, height)[:, None, None]
        img = np.where(m[..., None] > 0, glass + grad + rng.normal(0, 6, img.shape), img)
        inst[m > 0] = k + 1
        quads.append(q)
    return np.clip(img, 0, 255).astype(np.uint8), inst, quads


def write_toy_dataset(out_dir: str | Path, n_views: int = 4, seed: int = 0, width: int = 160,
                      height: int = 120) -> Path:
    """Write a toy dataset folder (views/NNNNNN/{image,instances}.png, view.json, coco.json) with
    fenestra.rendered_view's view writer and fenestra.coco's builder."""
    out = Path(out_dir)
    rng = np.random.default_rng(seed)
    images, anns = [], []
    for i in range(n_views):
        img, inst, quads = toy_view(rng, width, height)
        fx = width
        meta = {"K": [[fx, 0, (width - 1) / 2], [0, fx, (height - 1) / 2], [0, 0, 1]], "width": width,
                "height": height, "R": np.eye(3).tolist(), "t": [0, 0, 0], "distortion": None,
                "renderer": "toy", "seed": seed,
                "windows": [{"id": f"toy{k + 1}", "instance_id": k + 1, "corners_px": q.tolist()}
                            for k, q in enumerate(quads)]}
        write_view(out / "views" / f"{i:06d}", img, inst, meta)
        key = f"views/{i:06d}/image.png"
        images.append((key, height, width))
        anns += [gt_annotation(key, m.rle()) for m in instance_masks(inst, range(1, len(quads) + 1))]
    files.write_text(out / "coco.json", json.dumps(coco_ground_truth(images, anns)))
    return out
