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
from fenestra.errors import FenestraError
from fenestra.pipeline.detectors import read_weights

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
    from fenestra.pipeline.detectors.effwin import corner_heatmaps  # noqa: PLC0415 (fenestra.pipeline.detectors.effwin loads SciPy, torch: imported when first used)

    image, inst, corners = item[:3]
    aug = sample_augment(item, cfg)
    img, ins, warp = random_scale_crop(image, inst, cfg.crop_hw, aug, rng)
    occ = np.zeros(ins.shape, bool)
    if street:
        img, ins, occ = occluders(img, ins, aug, rng)
        img = shadow_band(img, ins, aug, rng)
    img = photometric(img, aug, rng)
    if corners is None:
        return img, ins, np.zeros((4, *ins.shape), np.float32), warp
    c = warp.points(corners)
    return img, ins, corner_heatmaps(c[:, [1, 0, 3, 2]] if warp.flip else c, ins.shape) * ~occ, warp


def warped_quads(item, warp, id_shift: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(ids (N,) shifted by ``id_shift``, whole quads (N, 4, 2) px on the crop, TL TR BR BL) of an
    item's dataset.WindowQuads (its 4th element) through a crop's CropWarp."""
    quads = item[3]
    c = warp.points(quads.corners)
    return quads.ids + id_shift, (c[:, [1, 0, 3, 2]] if warp.flip else c)


def sample_quad_targets(ins: np.ndarray, parts: list[tuple[np.ndarray, np.ndarray, np.ndarray | None]]) -> np.ndarray:
    """The quad head's targets (11, h, w) float32 of one crop [centre, 8 offsets, reg, ignore]
    (quadhead.quad_targets), from its final instance map (h * stride, w * stride) and ``parts``:
    (ids, quads, region) per source crop, region (H, W) bool where that source's pixels are
    (None: everywhere; a pasted neighbour strip has its own), so each cell takes its own source's
    targets."""
    from fenestra.pipeline.detectors.quadhead import QUAD_STRIDE, quad_targets  # noqa: PLC0415 (fenestra.pipeline.detectors.quadhead loads torch: imported when first used)

    seen = np.bincount(ins.ravel().astype(np.int64), minlength=1)
    out = None
    for ids, quads, region in parts:
        n = np.array([seen[i] if 0 < i < seen.size else 0 for i in ids])
        t = quad_targets(quads, n, ins.shape)
        stack = np.concatenate([t.centre[None], t.offsets, t.reg[None], t.ignore[None]])
        if out is None:
            out = stack
        else:
            cells = region[QUAD_STRIDE // 2::QUAD_STRIDE, QUAD_STRIDE // 2::QUAD_STRIDE]
            out = np.where(cells[None], stack, out)
    return out


def sample_pools(data) -> tuple[list[int], list[int]]:
    """(indices of the real photos (corners None), indices of the rendered views) of the training data."""
    return [i for i, d in enumerate(data) if d[2] is None], [i for i, d in enumerate(data) if d[2] is not None]


def draw_pool(pools: tuple[list[int], list[int]], cfg: TrainConfig, rng: np.random.Generator) -> list[int]:
    """The pool a sample is drawn from: the real photos with probability cfg.real_fraction (always
    when there is no rendered view), else the rendered views."""
    real, synth = pools
    return real if real and (not synth or rng.random() < cfg.real_fraction) else synth


def effwin_batch(data, cfg: TrainConfig, rng: np.random.Generator):
    """One augmented batch: images (B, 3, h, w) normalised, targets (B, 6, h, w) [void, core, TL, TR,
    BR, BL heatmaps] and per-sample corner weights (B,) (0 for real photos: boxes, no corners);
    with cfg.effwin_quad_head also the quad head's targets (B, 11, h / 4, w / 4) (sample_quad_targets).
    A sample is a real photo with probability cfg.real_fraction; with cfg.augment.neighbour_prob a
    strip of another sample of the same pool (a neighbouring facade) is pasted beside it."""
    from fenestra.pipeline.detectors.effwin import to_tensor  # noqa: PLC0415 (fenestra.pipeline.detectors.effwin loads SciPy, torch: imported when first used)
    from fenestra.pipeline.detectors.winnet import core_targets  # noqa: PLC0415 (fenestra.pipeline.detectors.winnet loads SciPy, torch: imported when first used)

    pools = sample_pools(data)
    imgs, tgts, wts, quads = [], [], [], []
    for _ in range(cfg.batch_size):
        pool = draw_pool(pools, cfg, rng)
        item = data[pool[int(rng.integers(len(pool)))]]
        img, ins, heat, warp = effwin_sample(item, cfg, rng)
        parts = [(*warped_quads(item, warp), None)] if cfg.effwin_quad_head else []
        aug = sample_augment(item, cfg)
        if aug.neighbour_prob > 0 and rng.random() < aug.neighbour_prob:
            other = data[pool[int(rng.integers(len(pool)))]]
            o_img, o_ins, o_heat, o_warp = effwin_sample(other, cfg, rng, street=False)
            shift = int(ins.max()) if ins.size else 0
            img, ins, strip = neighbour_strip(img, ins, o_img, o_ins, replace(aug, neighbour_prob=1.0), rng)
            heat = np.where(strip, o_heat, heat)
            if cfg.effwin_quad_head:
                parts.append((*warped_quads(other, o_warp, shift), strip))
        tgts.append(np.concatenate([np.stack([ins > 0, core_targets(ins, cfg.core_shrink_px, cfg.core_shrink_frac)]), heat]))
        if cfg.effwin_quad_head:
            quads.append(sample_quad_targets(ins, parts))
        imgs.append(img)
        wts.append(0.0 if item[2] is None else 1.0)
    batch = (to_tensor(np.stack(imgs)), torch.from_numpy(np.stack(tgts).astype(np.float32)),
             torch.tensor(wts, dtype=torch.float32))
    return (*batch, torch.from_numpy(np.stack(quads))) if quads else batch


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


def quad_losses(q: torch.Tensor, t: torch.Tensor, w: torch.Tensor) -> dict[str, torch.Tensor]:
    """The quad head's losses: ``quad_centre``, the penalty-reduced focal loss of the centre logit
    (cells at target >= 0.99 positive, the rest down-weighted by (1 - target)^4, ignored cells not
    counted), normalised by the positives; ``quad_offsets``, the L1 error of the eight corner offsets
    (units of quadhead.OFFSET_SCALE_PX, summed over them) on the regression cells of the samples
    with exact corners (w > 0), per cell. q: (B, 9, h, w) raw head output; t: (B, 11, h, w) targets
    (sample_quad_targets); w: (B,) 1 for exact corners, 0 for boxes."""
    p = torch.sigmoid(q[:, 0]).clamp(1e-4, 1 - 1e-4)
    heat, reg, keep = t[:, 0], t[:, 9], 1.0 - t[:, 10]
    pos = (heat >= 0.99).float()
    pos_l = -(torch.log(p) * (1 - p) ** 2 * pos).sum()
    neg_l = -(torch.log(1 - p) * p ** 2 * (1 - heat) ** 4 * (1 - pos) * keep).sum()
    centre = (pos_l + neg_l) / pos.sum().clamp_min(1.0)
    cells = reg * w.view(-1, 1, 1)
    offsets = ((q[:, 1:9] - t[:, 1:9]).abs().sum(dim=1) * cells).sum() / cells.sum().clamp_min(1.0)
    return {"quad_centre": centre, "quad_offsets": offsets}


def effwin_losses(model: torch.nn.Module, batch, cfg: TrainConfig) -> dict[str, torch.Tensor]:
    """winnet_loss on the void/core maps (the void BCE weighted 1 + cfg.edge_weight on the
    :func:`edge_band` of the rendered samples, whose outlines are exact) plus cfg.corner_weight x
    corner_focal_loss; with a quad head plus its :func:`quad_losses` (cfg.quad_weight,
    cfg.quad_offset_weight; on the real photos' boxes cfg.quad_box_weight). With cfg.train_only = "quad" the frozen network runs in eval mode
    (its batch-norm statistics kept) and only the quad head's losses are returned."""
    x, y, w = (t.to(cfg.device) for t in batch[:3])
    if cfg.channels_last:
        x = x.contiguous(memory_format=torch.channels_last)
    if cfg.train_only == "quad":
        model.eval()
        model.quad.train()
    logits, feats = model.forward_features(x)
    logits = logits.float()
    quad = {}
    if cfg.effwin_quad_head:
        quad = quad_losses(feats["quad"].float(), batch[3].to(cfg.device), torch.where(w > 0, w, cfg.quad_box_weight))
        quad = {"quad_centre": cfg.quad_weight * quad["quad_centre"],
                "quad_offsets": cfg.quad_offset_weight * quad["quad_offsets"]}
    if cfg.train_only == "quad":
        return {**quad, "loss": quad["quad_centre"] + quad["quad_offsets"]}
    void_weight = None
    if cfg.edge_weight > 0:
        void_weight = 1.0 + cfg.edge_weight * edge_band(y[:, 0], cfg.edge_px) * (w > 0).float().view(-1, 1, 1)
    parts = winnet_loss(logits[:, :2], y[:, :2], void_weight)
    parts["corner_focal"] = cfg.corner_weight * corner_focal_loss(logits[:, 2:], y[:, 2:], w)
    parts["loss"] = parts["loss"] + parts["corner_focal"] + sum(quad.values(), torch.zeros(()))
    return {**{k: v for k, v in parts.items() if k != "loss"}, **quad, "loss": parts["loss"]}


def effwin_build(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """EffWin (backbone from its ImageNet weights if cfg.pretrained) and AdamW; the pretrained
    backbone learns at a tenth of cfg.lr."""
    from fenestra.pipeline.detectors.effwin import EffWin  # noqa: PLC0415 (fenestra.pipeline.detectors.effwin loads SciPy, torch: imported when first used)

    model = EffWin(effwin_config(cfg), pretrained=cfg.pretrained and not cfg.init_weights)
    if cfg.init_weights:
        load_init_weights(model, cfg.init_weights)
    if cfg.train_only == "quad":
        for n, p in model.named_parameters():
            p.requires_grad_(n.startswith("quad."))
        return model, torch.optim.AdamW(model.quad.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    backbone = [p for n, p in model.named_parameters() if n.startswith(("stem.", "blocks."))]
    rest = [p for n, p in model.named_parameters() if not n.startswith(("stem.", "blocks."))]
    scale = 0.1 if cfg.pretrained or cfg.init_weights else 1.0
    groups = [{"params": backbone, "lr_scale": scale}, {"params": rest, "lr_scale": 1.0}]
    return model, torch.optim.AdamW(groups, lr=cfg.lr, weight_decay=cfg.weight_decay)


def load_init_weights(model: torch.nn.Module, path: str) -> None:
    """Load an EffWin weights file into ``model``: every tensor of the file must fit, and only a
    quad head (``quad.*``) may be missing from it (it is then trained from its initialisation).
    FenestraError naming the file otherwise."""

    ckpt = read_weights(path, ("effwin",))
    state = {k: v.float() if v.is_floating_point() else v for k, v in ckpt["state_dict"].items()}
    try:
        missing, unexpected = model.load_state_dict(state, strict=False)
    except RuntimeError as e:
        raise FenestraError(f"{path}: its weights do not fit this EffWin ({str(e).splitlines()[0]})") from None
    bad = [k for k in missing if not k.startswith("quad.")] + list(unexpected)
    if bad:
        raise FenestraError(f"{path}: its weights do not fit this EffWin (missing or unexpected: {bad[:4]})")


def effwin_config(cfg: TrainConfig):
    """The EffWinConfig of a TrainConfig."""
    from fenestra.pipeline.detectors.effwin import EffWinConfig  # noqa: PLC0415 (fenestra.pipeline.detectors.effwin loads SciPy, torch: imported when first used)

    return EffWinConfig(cfg.effwin_backbone, tuple(cfg.effwin_fine), tuple(cfg.effwin_decoder), cfg.effwin_quad_head)


def effwin_checkpoint(model: torch.nn.Module, cfg: TrainConfig) -> dict:
    """arch, EffWinConfig, fp16 weights and EffWin's post-processing defaults (PostConfig over
    effwin.POST_DEFAULTS); a quad head trained alone (cfg.train_only) keeps init_weights' box
    verifier and post-processing, the frozen network being bit for bit that file's."""
    from fenestra.pipeline.detectors.effwin import POST_DEFAULTS  # noqa: PLC0415 (fenestra.pipeline.detectors.effwin loads SciPy, torch: imported when first used)
    from fenestra.pipeline.detectors.winnet import PostConfig  # noqa: PLC0415 (fenestra.pipeline.detectors.winnet loads SciPy, torch: imported when first used)

    sd = {k: (v.half() if v.is_floating_point() else v).cpu() for k, v in model.state_dict().items()}
    out = {"arch": "effwin", "config": dataclasses.asdict(effwin_config(cfg)), "state_dict": sd,
           "post": dataclasses.asdict(PostConfig(**POST_DEFAULTS))}
    if cfg.train_only == "quad":  # the frozen network is init_weights' own: so is its box verifier
        from fenestra.pipeline.detectors import read_weights  # noqa: PLC0415 (pipeline.detectors loads torch: imported when first used)

        init = read_weights(cfg.init_weights, ("effwin",))
        out.update({k: init[k] for k in ("verifier", "post") if k in init})
    return out


def effwin_check(cfg: TrainConfig) -> None:
    """The backbone at half resolution and stride 32: crops must be multiples of 64 px."""
    if any(c % 64 for c in cfg.crop_hw):
        raise ValueError(f"effwin: crop_hw must be multiples of 64, got {cfg.crop_hw}")


RECIPE = Recipe(effwin_build, effwin_batch, effwin_losses, effwin_checkpoint, check=effwin_check)
