"""Mask R-CNN's training recipe (inference: fenestra/pipeline/detectors/maskrcnn.py): torchvision's losses,
SGD with momentum; the weights file holds the resize parameters and fp32 weights."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from fenestra.training.augment import photometric, random_scale_crop
from fenestra.training.recipes import Recipe

if TYPE_CHECKING:
    from fenestra.training.train import TrainConfig


def maskrcnn_batch(data, cfg: TrainConfig, rng: np.random.Generator):
    """One augmented batch for torchvision Mask R-CNN: (list of (3, h, w) [0,1] tensors, targets)."""
    from fenestra.pipeline.detectors.maskrcnn import maskrcnn_targets  # noqa: PLC0415

    imgs, tgts = [], []
    while len(imgs) < cfg.batch_size:
        image, inst = data[int(rng.integers(len(data)))][:2]
        img, ins, _ = random_scale_crop(image, inst, cfg.crop_hw, cfg.augment, rng)
        ids = [k for k in np.unique(ins) if k]
        ins = np.where(np.isin(ins, [k for k in ids if (ins == k).sum() >= 16]), ins, 0)
        if not ins.any():
            continue  # torchvision accepts empty targets, but they teach little
        imgs.append(torch.from_numpy(photometric(img, cfg.augment, rng)).permute(2, 0, 1).float() / 255.0)
        tgts.append(maskrcnn_targets(ins))
    return imgs, tgts


def maskrcnn_build(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """torchvision Mask R-CNN (cfg.maskrcnn_min_size/max_size) and SGD with momentum."""
    from fenestra.pipeline.detectors.maskrcnn import build_maskrcnn  # noqa: PLC0415

    model = build_maskrcnn(cfg.maskrcnn_min_size, cfg.maskrcnn_max_size)
    params = [p for p in model.parameters() if p.requires_grad]
    return model, torch.optim.SGD(params, lr=cfg.lr, momentum=0.9, weight_decay=cfg.weight_decay)


def maskrcnn_losses(model: torch.nn.Module, batch, cfg: TrainConfig) -> dict[str, torch.Tensor]:
    """torchvision's loss parts of one batch (images, targets) moved to cfg.device, and their sum."""
    imgs, tgts = batch
    parts = model([i.to(cfg.device) for i in imgs], [{k: v.to(cfg.device) for k, v in t.items()} for t in tgts])
    parts["loss"] = sum(parts.values())
    return parts


def maskrcnn_checkpoint(model: torch.nn.Module, cfg: TrainConfig) -> dict:
    """arch, the resize parameters and fp32 weights."""
    return {"arch": "maskrcnn", "model_kw": {"min_size": cfg.maskrcnn_min_size, "max_size": cfg.maskrcnn_max_size},
            "state_dict": {k: v.cpu() for k, v in model.state_dict().items()}}


RECIPE = Recipe(maskrcnn_build, maskrcnn_batch, maskrcnn_losses, maskrcnn_checkpoint)
