"""Mask R-CNN's training recipe (inference: fenestra/pipeline/detectors/maskrcnn.py): torchvision's
losses, SGD with momentum; the weights file holds the backbone, the resize parameters and fp16
weights.

Batches are EffWin's crops (recipes.effwin.effwin_sample: scale, crop, street occluders, an eave
shadow, photometric changes; the real photos' own augmentation) of the same renders and real street
photos, a real photo with probability ``real_fraction``: the same data and held-out rules as the
default detector.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from fenestra.training.recipes import Recipe

if TYPE_CHECKING:
    from fenestra.training.train import TrainConfig

MIN_WINDOW_PX = 16  # a window with fewer visible pixels in a crop is no training target there


def maskrcnn_batch(data, cfg: TrainConfig, rng: np.random.Generator):
    """One augmented batch for torchvision Mask R-CNN.

    Returns:
        (images, targets): cfg.batch_size (3, h, w) float32 tensors in [0, 1] (h, w = cfg.crop_hw)
        and their torchvision targets (boxes (N, 4) px, labels (N,), masks (N, h, w) uint8). A crop
        showing no window is drawn again.
    """
    from fenestra.pipeline.detectors.maskrcnn import maskrcnn_targets  # noqa: PLC0415 (fenestra.pipeline.detectors.maskrcnn loads torch: imported when first used)
    from fenestra.training.recipes.effwin import draw_pool, effwin_sample, sample_pools  # noqa: PLC0415 (fenestra.training.recipes.effwin loads torch: imported when first used)

    pools = sample_pools(data)
    imgs, tgts = [], []
    while len(imgs) < cfg.batch_size:
        pool = draw_pool(pools, cfg, rng)
        img, ins, _, _ = effwin_sample(data[pool[int(rng.integers(len(pool)))]], cfg, rng)
        ids, counts = np.unique(ins[ins > 0], return_counts=True)
        ins = np.where(np.isin(ins, ids[counts >= MIN_WINDOW_PX]), ins, 0)
        if not ins.any():
            continue
        imgs.append(torch.from_numpy(np.ascontiguousarray(img)).permute(2, 0, 1).float() / 255.0)
        tgts.append(maskrcnn_targets(ins))
    return imgs, tgts


def maskrcnn_build(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """torchvision Mask R-CNN on cfg.maskrcnn_backbone (the EfficientNet-Lite0 from its ImageNet
    weights when cfg.pretrained) and SGD with momentum over the trainable parameters."""
    from fenestra.pipeline.detectors.maskrcnn import build_maskrcnn  # noqa: PLC0415 (fenestra.pipeline.detectors.maskrcnn loads torch: imported when first used)

    model = build_maskrcnn(cfg.maskrcnn_backbone, cfg.maskrcnn_min_size, cfg.maskrcnn_max_size,
                           pretrained=cfg.pretrained and cfg.maskrcnn_backbone != "resnet50")
    params = [p for p in model.parameters() if p.requires_grad]
    return model, torch.optim.SGD(params, lr=cfg.lr, momentum=0.9, weight_decay=cfg.weight_decay)


def maskrcnn_losses(model: torch.nn.Module, batch, cfg: TrainConfig) -> dict[str, torch.Tensor]:
    """torchvision's loss parts of one batch (images, targets) moved to cfg.device, and their sum."""
    imgs, tgts = batch
    parts = model([i.to(cfg.device) for i in imgs], [{k: v.to(cfg.device) for k, v in t.items()} for t in tgts])
    parts["loss"] = sum(parts.values())
    return parts


def maskrcnn_checkpoint(model: torch.nn.Module, cfg: TrainConfig) -> dict:
    """arch, the backbone and resize parameters, fp16 weights."""
    return {"arch": "maskrcnn",
            "model_kw": {"backbone": cfg.maskrcnn_backbone, "min_size": cfg.maskrcnn_min_size,
                         "max_size": cfg.maskrcnn_max_size},
            "state_dict": {k: (v.half() if v.is_floating_point() else v).cpu() for k, v in model.state_dict().items()}}


def maskrcnn_check(cfg: TrainConfig) -> None:
    """A backbone of maskrcnn.BACKBONES."""
    from fenestra.pipeline.detectors.maskrcnn import BACKBONES  # noqa: PLC0415 (fenestra.pipeline.detectors.maskrcnn loads torch: imported when first used)

    if cfg.maskrcnn_backbone not in BACKBONES:
        raise ValueError(f"maskrcnn_backbone must be one of {list(BACKBONES)}, got {cfg.maskrcnn_backbone!r}")


RECIPE = Recipe(maskrcnn_build, maskrcnn_batch, maskrcnn_losses, maskrcnn_checkpoint, check=maskrcnn_check)
