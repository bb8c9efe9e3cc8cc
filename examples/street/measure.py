"""Measure `fenestra reconstruct` (no intrinsics) on labelled street photos (YOLO boxes).

    .venv/bin/python -m examples.street.measure ../shared/real/spb_facades OUT [--export-all]

Per photo: output written or not, K source, walls, windows detected / exported, and what each
exported window is by the labels (the label box its quad's bounding box overlaps most, IoU >= 0.3:
window=0, cantilever=1, arch=2, signboard=3, win_ad=4, door=5; "none" below 0.3). Prints one JSON
line per photo, then the totals. Not a bench metric (that is `fenestra bench --profile real`).
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from pipeline.photo import PhotoOptions, reconstruct_photo

CLASSES = {0: "window", 1: "cantilever", 2: "arch", 3: "signboard", 4: "win_ad", 5: "door"}
MIN_IOU = 0.3


def label_boxes(path: Path, size: tuple[int, int]) -> list[tuple[str, np.ndarray]]:
    """[(class name, (x0, y0, x1, y1) px)] from a YOLO label file for a (W, H) photo."""
    W, H = size
    out = []
    for line in path.read_text().split("\n"):
        if line.strip():
            c, cx, cy, w, h = (float(v) for v in line.split()[:5])
            out.append((CLASSES.get(int(c), str(int(c))), np.array([(cx - w / 2) * W, (cy - h / 2) * H,
                                                                    (cx + w / 2) * W, (cy + h / 2) * H])))
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    w = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    h = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = w * h
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def what_is(quad, labels) -> str:
    q = np.asarray(quad)
    box = np.array([*q.min(axis=0), *q.max(axis=0)])
    best = max(((iou(box, b), c) for c, b in labels), default=(0.0, "none"))
    return best[1] if best[0] >= MIN_IOU else "none"


def main(root: Path, out: Path, export_all: bool = False) -> dict:
    totals: dict = {"photos": 0, "with_output": 0, "exported": {}, "walls": []}
    for photo in sorted((root / "images").glob("*.jpg")):
        t0 = time.perf_counter()
        try:
            doc = reconstruct_photo(photo, out / photo.stem, options=PhotoOptions(export_all=export_all), force=True)
        except Exception as e:  # noqa: BLE001 -- measured, reported
            print(json.dumps({"photo": photo.name, "error": f"{type(e).__name__}: {e}"}), flush=True)
            totals["photos"] += 1
            continue
        W, H = doc["image_size"]
        labels = label_boxes(root / "labels" / f"{photo.stem}.txt", (W, H))
        kinds = [what_is(w["quad_snapped"], labels) for w in doc["windows"] if w["exported"]]
        counts = {k: kinds.count(k) for k in sorted(set(kinds))}
        written = (out / photo.stem / "windows.json").is_file() and (out / photo.stem / "overlay.png").is_file()
        totals["photos"] += 1
        totals["with_output"] += written
        totals["walls"].append(len(doc["walls"]))
        for k, v in counts.items():
            totals["exported"][k] = totals["exported"].get(k, 0) + v
        print(json.dumps({"photo": photo.name, "output": written, "K": doc["K_source"]["source"],
                          "f": round(doc["K_source"]["focal_px"]), "walls": len(doc["walls"]),
                          "detected": len(doc["windows"]), "flagged": sum(bool(w["flags"]) for w in doc["windows"]),
                          "exported_by_label": counts, "s": round(time.perf_counter() - t0, 1)}), flush=True)
    ex = totals["exported"]
    n = sum(ex.values())
    totals["export_precision_window"] = (ex.get("window", 0) + ex.get("win_ad", 0)) / n if n else None
    totals["median_walls"] = float(np.median(totals["walls"])) if totals["walls"] else None
    print(json.dumps(totals), flush=True)
    return totals


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]), "--export-all" in sys.argv)
