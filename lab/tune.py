"""Choose the void/core post-processing thresholds (WinNet, EffWin) on VALIDATION views (never the held-out house).

    python -m lab.tune --data out/detector-data/val --views-per-dataset 5 \
        [--weights fenestra/pipeline/models/default.pt] [--write]      # --views-per-dataset 0: every view

Runs the network once per view, then scores each PostConfig of a small grid with COCOeval (segm AP);
--write stores the best one in the weights file (key "post"), which the `default` detector uses.
"""
from __future__ import annotations

import argparse
import dataclasses
import itertools
from pathlib import Path

import numpy as np
import torch

from fenestra.coco import coco_ground_truth, coco_scores, gt_annotation
from fenestra.masks import instance_masks
from fenestra.rendered_view import read_view
from fenestra.pipeline.detectors import DEFAULT_WEIGHTS, load_map_predictor
from fenestra.pipeline.detectors.winnet import PostConfig, instances_from_maps
from fenestra.training.dataset import find_datasets, list_views
from fenestra.training import weights_file
from fenestra.training.evaluate import detection_to_coco


def instance_maps_to_coco(instances: list[np.ndarray]) -> dict:
    """COCO ground truth (fenestra.coco builder) of instance maps (H, W), image ids 1, 2, ..."""
    anns = [gt_annotation(str(i), m.rle()) for i, inst in enumerate(instances, 1)
            for m in instance_masks(inst, [k for k in np.unique(inst).tolist() if k])]
    return coco_ground_truth([(str(i), *inst.shape) for i, inst in enumerate(instances, 1)], anns)


def tune(weights: Path, data: Path, views_per_dataset: int = 3) -> list[tuple[dict, PostConfig]]:
    """(fenestra.coco.coco_scores segm scores, PostConfig) for every grid point, best segm AP first
    (views_per_dataset 0: all)."""
    predict, shipped = load_map_predictor(weights)
    maps, insts = [], []
    for d in find_datasets([data]):
        vs = list_views(d)
        if views_per_dataset > 0:
            vs = [vs[j] for j in np.linspace(0, len(vs) - 1, views_per_dataset).round().astype(int)]
        for v in vs:
            view = read_view(v.dir)
            maps.append(predict(view.image))
            insts.append((len(insts) + 1, view.instances))
    gt = instance_maps_to_coco([inst for _, inst in insts])  # ids 1, 2, ... as in insts
    out = []
    for vt, ct in itertools.product((0.4, 0.5, 0.6), (0.3, 0.5, 0.7)):
        post = dataclasses.replace(shipped, void_threshold=vt, core_threshold=ct)  # the file's other choices kept
        res = [detection_to_coco(det, i) for (i, _), (v, c) in zip(insts, maps)
               for det in instances_from_maps(v, c, post) if det.score >= 0.05]
        out.append((coco_scores(gt, res, ("segm",)), post))
        print(f"void {vt} core {ct}: segm AP {100 * out[-1][0]['segm_AP']:.1f} "
              f"AP50 {100 * out[-1][0]['segm_AP50']:.1f}", flush=True)
    return sorted(out, key=lambda r: -r[0]["segm_AP"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--weights", type=Path, default=DEFAULT_WEIGHTS)
    ap.add_argument("--views-per-dataset", type=int, default=3)
    ap.add_argument("--write", action="store_true")
    a = ap.parse_args()
    torch.set_num_threads(2)
    best_stats, best = tune(a.weights, a.data, a.views_per_dataset)[0]
    print(f"best: {best} (segm AP {100 * best_stats['segm_AP']:.1f})")
    if a.write:
        ckpt = torch.load(a.weights, map_location="cpu", weights_only=False)
        ckpt["post"] = dataclasses.asdict(best)
        weights_file.save(a.weights, ckpt, force=True)  # in place, atomically: the weights file it read (recognised)
        print(f"wrote post-processing config into {a.weights}")


if __name__ == "__main__":
    main()
