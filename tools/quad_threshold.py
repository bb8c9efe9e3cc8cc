"""The quad head's operating point: precision, recall and F1 against the centre-peak threshold.

    .venv/bin/python tools/quad_threshold.py [--weights out/train/quadnet.pt] [--renders out/detector-data/val] \
        [--yolo ../shared/real/spb_facades/train] [--views 60] [--photos 40]

Runs a quad-head weights file as its detector does (network, mirror average, quads from centres,
box verifier) with every centre peak down to 0.05 kept, on the validation renders (never trained
on; a window is its instance in instances.png, matched at mask IoU >= 0.5) and on the validation
part of the St Petersburg photos (every 5th photo, never trained on; window boxes of class 0,
matched at box IoU >= 0.5; doors and signboards are no windows). Prints precision, recall and F1 per
threshold on each, and the threshold that maximises the mean F1 of the two: the score scale that
puts it at the detectors' 0.5 (``QuadDecode.score_scale``) is its 0.5 / threshold.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

THRESHOLDS = (0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.7)


def candidates(weights: Path):
    """image -> Detections with their raw centre probability as score (threshold 0.05)."""
    from fenestra.pipeline.detectors import DETECTORS, load_model  # noqa: PLC0415
    from fenestra.pipeline.detectors.effwin import (predict_maps_features, quad_decode, quads_from_maps,  # noqa: PLC0415
                                                    verifier_from_checkpoint, post_config)
    from fenestra.pipeline.detectors.verifier import classified  # noqa: PLC0415

    _, net, ckpt = load_model(DETECTORS["quadnet"].model, weights)
    decode = dataclasses.replace(quad_decode(ckpt), centre_threshold=0.05, score_scale=1.0)
    head, post = verifier_from_checkpoint(net, ckpt), post_config(ckpt)

    def run(image):
        maps, feats = predict_maps_features(net, image, post.mirror)
        dets = quads_from_maps(maps, feats, decode)
        return dets if head is None else [d for d in classified(dets, maps[0], feats, head) if d.kind == "window"]
    return run


def greedy_matches(ious: np.ndarray, scores: np.ndarray, thr: float = 0.5) -> np.ndarray:
    """(D,) bool: detection d (best score first) matches a ground truth not yet taken at IoU >= thr.
    ious: (D, G)."""
    hit = np.zeros(len(scores), bool)
    taken = np.zeros(ious.shape[1], bool)
    for d in np.argsort(-scores):
        if ious.shape[1] == 0:
            break
        cand = np.where(~taken, ious[d], -1.0)
        g = int(np.argmax(cand))
        if cand[g] >= thr:
            hit[d], taken[g] = True, True
    return hit


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, M) IoU of boxes (N, 4) and (M, 4) x0 y0 x1 y1."""
    ix = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)
    iy = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0, None)
    inter = ix * iy
    area = lambda x: (x[:, 2] - x[:, 0]) * (x[:, 3] - x[:, 1])  # noqa: E731
    return inter / np.maximum(area(a)[:, None] + area(b)[None, :] - inter, 1e-9)


def render_records(run, root: Path, n: int) -> tuple[list, int]:
    from fenestra.rendered_view import read_view  # noqa: PLC0415
    from fenestra.training.dataset import find_datasets, list_views  # noqa: PLC0415

    views = [v for d in find_datasets([root]) for v in list_views(d)]
    views = [views[i] for i in np.linspace(0, len(views) - 1, min(n, len(views))).round().astype(int)]
    recs, n_gt = [], 0
    for vf in views:
        v = read_view(vf.dir)
        inst = v.instances
        ids = [i for i in np.unique(inst) if i > 0 and (inst == i).sum() >= 30]
        n_gt += len(ids)
        dets = run(v.image)
        ious = np.zeros((len(dets), len(ids)))
        for a, d in enumerate(dets):
            m = np.zeros(inst.shape, bool)
            (x0, y0), (h, w) = d.origin, d.mask.shape
            m[y0:y0 + h, x0:x0 + w] = d.mask
            for b, i in enumerate(ids):
                g = inst == i
                ious[a, b] = (g & m).sum() / max(1, (g | m).sum())
        scores = np.array([d.score for d in dets])
        recs += list(zip(scores, greedy_matches(ious, scores)))
    return recs, n_gt


def photo_records(run, yolo: Path, n: int) -> tuple[list, int]:
    from fenestra.images import read_image  # noqa: PLC0415
    from fenestra.training.dataset import photo_labels, real_box_photos  # noqa: PLC0415
    from fenestra.yolo import yolo_boxes  # noqa: PLC0415
    from fenestra.pipeline.detectors import downscale, input_scale, full_resolution  # noqa: PLC0415

    photos = real_box_photos(yolo, "val")[:n]
    recs, n_gt = [], 0
    for p in photos:
        image = read_image(p)
        text, where = photo_labels(p)
        gt = np.asarray(yolo_boxes(text, image.shape[1], image.shape[0], (0,), where), float).reshape(-1, 4)
        n_gt += len(gt)
        s = input_scale(image.shape[:2])
        dets = run(downscale(image, s) if s < 1 else image)
        if s < 1:
            dets = [full_resolution(d, s, image.shape[:2]) for d in dets]
        boxes = np.array([d.box for d in dets], float).reshape(-1, 4)
        scores = np.array([d.score for d in dets])
        recs += list(zip(scores, greedy_matches(box_iou(boxes, gt), scores)))
    return recs, n_gt


def curve(recs: list, n_gt: int) -> dict[float, tuple[float, float, float]]:
    s = np.array([r[0] for r in recs])
    hit = np.array([r[1] for r in recs], bool)
    out = {}
    for t in THRESHOLDS:
        k = s >= t
        tp = int((hit & k).sum())
        prec = tp / max(1, int(k.sum()))
        rec = tp / max(1, n_gt)
        out[t] = (prec, rec, 2 * prec * rec / max(1e-9, prec + rec))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", type=Path, default=ROOT / "out" / "train" / "quadnet.pt")
    ap.add_argument("--renders", type=Path, default=ROOT / "out" / "detector-data" / "val")
    ap.add_argument("--yolo", type=Path, default=ROOT.parent / "shared" / "real" / "spb_facades" / "train")
    ap.add_argument("--detector", default="quadnet", help="quadnet (the weights' raw centre peaks), or another "
                    "registered detector as a reference (its shipped weights and scores)")
    ap.add_argument("--views", type=int, default=60)
    ap.add_argument("--photos", type=int, default=40)
    a = ap.parse_args()
    from fenestra.pipeline.detectors import set_cpu_threads  # noqa: PLC0415

    set_cpu_threads(2)
    if a.detector == "quadnet":
        run = candidates(a.weights)
    else:  # a reference: another detector's own candidates and scores
        from fenestra.pipeline.detectors import get_detector  # noqa: PLC0415

        run = get_detector(a.detector)
    curves = {}
    if a.renders.is_dir():
        curves["validation renders"] = curve(*render_records(run, a.renders, a.views))
    if a.yolo.is_dir():
        curves["spb validation photos"] = curve(*photo_records(run, a.yolo, a.photos))
    for name, c in curves.items():
        print(f"{name}: threshold precision recall F1")
        for t, (p, r, f) in c.items():
            print(f"  {t:.2f}  {p:.3f}  {r:.3f}  {f:.3f}")
    best = max(THRESHOLDS, key=lambda t: np.mean([c[t][2] for c in curves.values()]))
    print(f"best threshold (mean F1): {best:.2f} -> score_scale {0.5 / best:.3f}")


if __name__ == "__main__":
    main()
