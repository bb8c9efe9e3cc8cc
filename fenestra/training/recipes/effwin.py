"""EffWin's training recipe (inference: fenestra/pipeline/detectors/effwin.py): WinNet's void/core maps and
losses plus corner heatmaps (penalty-reduced focal loss), optionally real photos' box masks; the
pretrained backbone learns at a tenth of the rate."""
from __future__ import annotations

import dataclasses
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import torch
import torch.nn.functional as F

from fenestra.training.augment import AugmentConfig, neighbour_strip, occluders, photometric, random_scale_crop, shadow_band
from fenestra.training.recipes import Recipe
from fenestra.training.recipes.winnet import winnet_loss

if TYPE_CHECKING:
    from fenestra.training.train import TrainConfig


def sample_augment(item, cfg: TrainConfig) -> AugmentConfig:
    """The augmentation of an item: cfg.real_augment for a real photo (corners None) when set,
    else cfg.augment."""
    return cfg.real_augment if item[2] is None and cfg.real_augment is not None else cfg.augment


def effwin_sample(item, cfg: TrainConfig, rng: np.random.Generator, street: bool = True):
    """One augmented crop of a (image, instances, corners or None) item: image (h, w, 3) uint8,
    instances (h, w) int, corner heatmaps (4, h, w) float32 (zeros for a real photo: boxes, no
    corners). street: also draw occluders and an eave shadow. Augmented as sample_augment says."""
    from fenestra.pipeline.detectors.effwin import corner_heatmaps  # noqa: PLC0415

    image, inst, corners = item
    aug = sample_augment(item, cfg)
    img, ins, warp = random_scale_crop(image, inst, cfg.crop_hw, aug, rng)
    occ = np.zeros(ins.shape, bool)
    if street:
        img, ins, occ = occluders(img, ins, aug, rng)
        img = shadow_band(img, ins, aug, rng)
    img = photometric(img, aug, rng)
    if corners is None:
        return img, ins, np.zeros((4, *ins.shape), np.float32)
    c = warp.points(corners)
    return img, ins, corner_heatmaps(c[:, [1, 0, 3, 2]] if warp.flip else c, ins.shape) * ~occ


def effwin_batch(data, cfg: TrainConfig, rng: np.random.Generator):
    """One augmented batch: images (B, 3, h, w) normalised, targets (B, 6, h, w) [void, core, TL, TR,
    BR, BL heatmaps] and per-sample corner weights (B,) (0 for real photos: boxes, no corners).
    A sample is a real photo with probability cfg.real_fraction; with cfg.augment.neighbour_prob a
    strip of another sample of the same pool (a neighbouring facade) is pasted beside it."""
    from fenestra.pipeline.detectors.effwin import to_tensor  # noqa: PLC0415
    from fenestra.pipeline.detectors.winnet import core_targets  # noqa: PLC0415

    real = [i for i, d in enumerate(data) if d[2] is None]
    synth = [i for i, d in enumerate(data) if d[2] is not None]
    imgs, tgts, wts = [], [], []
    for _ in range(cfg.batch_size):
        pool = real if real and (not synth or rng.random() < cfg.real_fraction) else synth
        item = data[pool[int(rng.integers(len(pool)))]]
        img, ins, heat = effwin_sample(item, cfg, rng)
        aug = sample_augment(item, cfg)
        if aug.neighbour_prob > 0 and rng.random() < aug.neighbour_prob:
            o_img, o_ins, o_heat = effwin_sample(data[pool[int(rng.integers(len(pool)))]], cfg, rng, street=False)
            img, ins, strip = neighbour_strip(img, ins, o_img, o_ins, replace(aug, neighbour_prob=1.0), rng)
            heat = np.where(strip, o_heat, heat)
        tgts.append(np.concatenate([np.stack([ins > 0, core_targets(ins, cfg.core_shrink_px, cfg.core_shrink_frac)]), heat]))
        imgs.append(img)
        wts.append(0.0 if item[2] is None else 1.0)
    return (to_tensor(np.stack(imgs)), torch.from_numpy(np.stack(tgts).astype(np.float32)),
            torch.tensor(wts, dtype=torch.float32))


def corner_focal_loss(logits: torch.Tensor, heat: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """CenterNet's penalty-reduced focal loss on corner heatmaps (B, 4, h, w): pixels with target
    >= 0.7 (within ~1.3 sigma of a corner) are positives, the rest negatives down-weighted by
    (1 - target)^4; per-sample weights (B,) (0: no corner labels); normalised by the positives."""
    p = torch.sigmoid(logits).clamp(1e-4, 1 - 1e-4)
    pos = (heat >= 0.7).float()
    w = weight.view(-1, 1, 1, 1)
    pos_l = -(torch.log(p) * (1 - p) ** 2 * pos * w).sum()
    neg_l = -(torch.log(1 - p) * p ** 2 * (1 - heat) ** 4 * (1 - pos) * w).sum()
    return (pos_l + neg_l) / (pos * w).sum().clamp_min(1.0)


def edge_band(void: torch.Tensor, px: int) -> torch.Tensor:
    """(B, h, w) 1.0 where a pixel lies within ``px`` (chessboard distance) of a void target's outline,
    on either side, else 0.0: the dilation minus the erosion of the (B, h, w) 0/1 void map by a
    (2 px + 1) square."""
    v = void[:, None].float()
    k = 2 * px + 1
    dil = F.max_pool2d(v, k, stride=1, padding=px)
    ero = -F.max_pool2d(-v, k, stride=1, padding=px)
    return (dil - ero)[:, 0]


def effwin_losses(model: torch.nn.Module, batch, cfg: TrainConfig) -> dict[str, torch.Tensor]:
    """winnet_loss on the void/core maps (the void BCE weighted 1 + cfg.edge_weight on the
    :func:`edge_band` of the rendered samples, whose outlines are exact) plus cfg.corner_weight x
    corner_focal_loss."""
    x, y, w = (t.to(cfg.device) for t in batch)
    if cfg.channels_last:
        x = x.contiguous(memory_format=torch.channels_last)
    logits = model(x).float()
    void_weight = None
    if cfg.edge_weight > 0:
        void_weight = 1.0 + cfg.edge_weight * edge_band(y[:, 0], cfg.edge_px) * (w > 0).float().view(-1, 1, 1)
    parts = winnet_loss(logits[:, :2], y[:, :2], void_weight)
    parts["corner_focal"] = cfg.corner_weight * corner_focal_loss(logits[:, 2:], y[:, 2:], w)
    parts["loss"] = parts["loss"] + parts["corner_focal"]
    return parts


def effwin_build(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """EffWin (backbone from its ImageNet weights if cfg.pretrained) and AdamW; the pretrained
    backbone learns at a tenth of cfg.lr."""
    from fenestra.pipeline.detectors.effwin import EffWin  # noqa: PLC0415

    model = EffWin(effwin_config(cfg), pretrained=cfg.pretrained)
    backbone = [p for n, p in model.named_parameters() if n.startswith(("stem.", "blocks."))]
    rest = [p for n, p in model.named_parameters() if not n.startswith(("stem.", "blocks."))]
    groups = [{"params": backbone, "lr_scale": 0.1 if cfg.pretrained else 1.0}, {"params": rest, "lr_scale": 1.0}]
    return model, torch.optim.AdamW(groups, lr=cfg.lr, weight_decay=cfg.weight_decay)


def effwin_config(cfg: TrainConfig):
    """The EffWinConfig of a TrainConfig."""
    from fenestra.pipeline.detectors.effwin import EffWinConfig  # noqa: PLC0415

    return EffWinConfig(cfg.effwin_backbone, tuple(cfg.effwin_fine), tuple(cfg.effwin_decoder))


def effwin_checkpoint(model: torch.nn.Module, cfg: TrainConfig) -> dict:
    """arch, EffWinConfig, fp16 weights and EffWin's post-processing defaults (PostConfig over
    effwin.POST_DEFAULTS)."""
    from fenestra.pipeline.detectors.effwin import POST_DEFAULTS  # noqa: PLC0415
    from fenestra.pipeline.detectors.winnet import PostConfig  # noqa: PLC0415

    sd = {k: (v.half() if v.is_floating_point() else v).cpu() for k, v in model.state_dict().items()}
    return {"arch": "effwin", "config": dataclasses.asdict(effwin_config(cfg)), "state_dict": sd,
            "post": dataclasses.asdict(PostConfig(**POST_DEFAULTS))}


def effwin_check(cfg: TrainConfig) -> None:
    """The backbone at half resolution and stride 32: crops must be multiples of 64 px."""
    if any(c % 64 for c in cfg.crop_hw):
        raise ValueError(f"effwin: crop_hw must be multiples of 64, got {cfg.crop_hw}")


RECIPE = Recipe(effwin_build, effwin_batch, effwin_losses, effwin_checkpoint, check=effwin_check)
