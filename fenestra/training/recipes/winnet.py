"""WinNet's training recipe (inference: fenestra/pipeline/detectors/winnet.py): crops with void and core
targets, BCE + soft Dice per map, AdamW; the weights file holds the widths and fp16 weights."""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
import torch
import torch.nn.functional as F

from fenestra.training.augment import photometric, random_scale_crop, shadow_band
from fenestra.training.recipes import Recipe

if TYPE_CHECKING:
    from fenestra.training.train import TrainConfig


def winnet_batch(data, cfg: TrainConfig, rng: np.random.Generator):
    """One augmented batch: images (B, 3, h, w) normalised, targets (B, 2, h, w) {0, 1} [void, core]."""
    from fenestra.pipeline.detectors.winnet import core_targets, to_tensor  # noqa: PLC0415 (fenestra.pipeline.detectors.winnet loads SciPy, torch: imported when first used)

    imgs, tgts = [], []
    for _ in range(cfg.batch_size):
        image, inst = data[int(rng.integers(len(data)))][:2]
        img, ins, _ = random_scale_crop(image, inst, cfg.crop_hw, cfg.augment, rng)
        imgs.append(photometric(shadow_band(img, ins, cfg.augment, rng), cfg.augment, rng))
        tgts.append(np.stack([ins > 0, core_targets(ins, cfg.core_shrink_px, cfg.core_shrink_frac)]))
    return to_tensor(np.stack(imgs)), torch.from_numpy(np.stack(tgts).astype(np.float32))


def winnet_loss(logits: torch.Tensor, target: torch.Tensor,
                void_weight: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """BCE + soft Dice per map; returns the parts and their sum under "loss". void_weight: per-pixel
    weights (B, h, w) of the void map's BCE (its mean over pixels; None: 1 everywhere)."""
    bce_px = F.binary_cross_entropy_with_logits(logits, target, reduction="none")
    if void_weight is not None:
        bce_px = torch.cat([bce_px[:, :1] * void_weight[:, None], bce_px[:, 1:]], dim=1)
    bce = bce_px.mean(dim=(0, 2, 3))
    p = torch.sigmoid(logits)
    inter = (p * target).sum(dim=(0, 2, 3))
    dice = 1.0 - (2 * inter + 1.0) / (p.sum(dim=(0, 2, 3)) + target.sum(dim=(0, 2, 3)) + 1.0)
    parts = {"void_bce": bce[0], "core_bce": bce[1], "void_dice": dice[0], "core_dice": dice[1]}
    parts["loss"] = sum(parts.values())
    return parts


def winnet_build(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """WinNet of cfg.winnet_widths and AdamW."""
    from fenestra.pipeline.detectors.winnet import WinNet, WinNetConfig  # noqa: PLC0415 (fenestra.pipeline.detectors.winnet loads SciPy, torch: imported when first used)

    model = WinNet(WinNetConfig(cfg.winnet_widths))
    return model, torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)


def winnet_losses(model: torch.nn.Module, batch, cfg: TrainConfig) -> dict[str, torch.Tensor]:
    """winnet_loss of one batch (images, targets) moved to cfg.device (channels-last if set)."""
    x, y = (t.to(cfg.device) for t in batch)
    if cfg.channels_last:
        x = x.contiguous(memory_format=torch.channels_last)
    return winnet_loss(model(x).float(), y)


def winnet_checkpoint(model: torch.nn.Module, cfg: TrainConfig) -> dict:
    """arch, widths, fp16 weights and the post-processing defaults (PostConfig)."""
    from fenestra.pipeline.detectors.winnet import PostConfig  # noqa: PLC0415 (fenestra.pipeline.detectors.winnet loads SciPy, torch: imported when first used)

    sd = {k: (v.half() if v.is_floating_point() else v).cpu() for k, v in model.state_dict().items()}
    return {"arch": "winnet", "widths": list(cfg.winnet_widths), "state_dict": sd,
            "post": dataclasses.asdict(PostConfig())}


RECIPE = Recipe(winnet_build, winnet_batch, winnet_losses, winnet_checkpoint)
