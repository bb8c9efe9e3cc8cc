"""Training the learned corner refinement (fenestra/pipeline/snappers/refine.py) on rendered views.

    bash lab/scripts/refine_data.sh out/refine-data        # the detector's training houses only
    fenestra train-refine --data out/refine-data/train [--ship]  # -> out/train/refine.pt (+ fenestra/pipeline/models)

Samples: every corner of every window of the views that the render marks visible (corner_visible),
with the window at least ``min_visible_fraction`` visible, ``min_window_px`` large and the corner
at least ``border_px`` inside the image (patches beyond the border repeat its pixels, as in use). Each epoch draws a fresh input corner per sample: the exact
corner (view.json corners_px) moved like a detector's mask-fit corner (a Gaussian of
``sigma_px`` per axis, or with probability ``far_fraction`` a uniform direction at 2..``far_px``),
samples the TL-mirrored patch there at a random scale (``scale_range``: photos whose windows are
sampled a little finer or coarser), and augments it (transpose: a TL corner stays TL; grey-level
inversion; Gaussian noise). The loss: the soft-argmax's distance to the exact corner (smooth L1)
plus ``spread_weight`` times the heatmap's expected squared distance to it (a peaked, calibrated
heatmap: its spread is the snapper's confidence). Views are split by index (every
``val_every``-th view of each dataset is validation) and the validation figures (median error
before and after, share of corners kept) go into the weights' ``meta``.

Deterministic: fixed seeds, one process, torch's deterministic algorithms; a few minutes on 2 CPU
threads.
"""
from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from fenestra.errors import DatasetError
from fenestra.images import read_image
from fenestra.pipeline.reconstruct import to_gray
from fenestra.training import weights_file
from fenestra.pipeline.snappers.refine import (ARCH, FLIPS, PATCH, WIDTHS, build_net, heatmap, normalise, sample_patches,
                                      soft_argmax, to_patch)


@dataclass(frozen=True)
class RefineTrainConfig:
    """What the training run reads and does (see the module docstring)."""

    epochs: int = 12
    batch: int = 128
    lr: float = 3e-3
    weight_decay: float = 1e-4
    sigma_px: float = 1.5
    far_fraction: float = 0.25
    far_px: float = 8.0
    scale_range: tuple[float, float] = (0.8, 1.25)
    spread_weight: float = 0.02
    min_visible_fraction: float = 0.7
    min_window_px: float = 12.0
    border_px: float = 4.0
    val_every: int = 5
    seed: int = 0
    threads: int = 2


@dataclass(frozen=True)
class CornerSet:
    """Gray images (float32 (H, W)) and per corner: image index (N,), exact corner (N, 2) px, corner
    number 0..3 (TL TR BR BL) and whether its view is a validation view (N,)."""

    images: list
    image: np.ndarray
    truth: np.ndarray
    corner: np.ndarray
    val: np.ndarray


def view_dirs(roots: tuple[Path, ...]) -> list[Path]:
    """Every rendered view folder (with view.json) under the dataset roots, sorted (deterministic)."""
    dirs = sorted({p.parent for r in roots for p in Path(r).glob("**/views/*/view.json")})
    if not dirs:
        raise DatasetError(f"no rendered views (views/*/view.json) under {', '.join(map(str, roots))}")
    return dirs


def usable_corners(meta: dict, cfg: RefineTrainConfig) -> list[tuple[np.ndarray, int]]:
    """(exact corner (2,), corner number) of a view's windows that qualify (module docstring)."""
    W, H, m = meta["width"], meta["height"], cfg.border_px
    out = []
    for w in meta["windows"]:
        c = np.asarray(w["corners_px"], np.float64)
        size = min(np.linalg.norm(c[1] - c[0]), np.linalg.norm(c[2] - c[1]),
                   np.linalg.norm(c[3] - c[2]), np.linalg.norm(c[0] - c[3]))
        if w.get("visible_fraction", 0.0) < cfg.min_visible_fraction or size < cfg.min_window_px:
            continue
        for k in range(4):
            x, y = c[k]
            if w["corner_visible"][k] and m <= x <= W - 1 - m and m <= y <= H - 1 - m:
                out.append((c[k], k))
    return out


def collect(roots: tuple[Path, ...], cfg: RefineTrainConfig) -> CornerSet:
    """The :class:`CornerSet` of every view under ``roots`` (every ``val_every``-th one validation)."""
    images, image, truth, corner, val = [], [], [], [], []
    for i, d in enumerate(view_dirs(roots)):
        meta = json.loads((d / "view.json").read_text())
        corners = usable_corners(meta, cfg)
        if not corners:
            continue
        images.append(to_gray(read_image(d / "image.png")))
        for c, k in corners:
            image.append(len(images) - 1)
            truth.append(c)
            corner.append(k)
            val.append(int(d.name) % cfg.val_every == 0)
    return CornerSet(images, np.array(image), np.array(truth), np.array(corner), np.array(val))


def perturb(rng: np.random.Generator, n: int, cfg: RefineTrainConfig) -> np.ndarray:
    """(n, 2) offsets px: mostly Gaussian (sigma_px per axis), a far_fraction uniform in direction at 2..far_px."""
    off = rng.normal(0.0, cfg.sigma_px, (n, 2))
    far = rng.random(n) < cfg.far_fraction
    ang, r = rng.uniform(0, 2 * np.pi, n), rng.uniform(2.0, cfg.far_px, n)
    off[far] = np.stack([r * np.cos(ang), r * np.sin(ang)], 1)[far]
    return off


def make_batch(cs: CornerSet, idx: np.ndarray, rng: np.random.Generator, cfg: RefineTrainConfig,
               augment: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Normalised patches (n, 1, P, P) float32 and target patch coordinates (n, 2) of samples idx."""
    off = perturb(rng, len(idx), cfg)
    step = rng.uniform(*cfg.scale_range, len(idx)) if augment else np.ones(len(idx))
    patches, targets = np.empty((len(idx), PATCH, PATCH), np.float32), np.empty((len(idx), 2))
    for j, i in enumerate(idx):  # one remap per sample (different images and scales)
        centre, flip = (cs.truth[i] + off[j])[None], FLIPS[cs.corner[i]][None]
        patches[j] = sample_patches(cs.images[cs.image[i]], centre, flip, step[j])[0]
        targets[j] = to_patch(centre, flip, cs.truth[i][None], step[j])[0]
    x = normalise(patches)
    if augment:
        t = rng.random(len(idx)) < 0.5  # transpose: a TL corner stays TL
        x[t] = x[t].transpose(0, 2, 1)
        targets[t] = targets[t][:, ::-1]
        x *= np.where(rng.random(len(idx)) < 0.2, -1.0, 1.0).astype(np.float32)[:, None, None]
        x += (rng.uniform(0, 0.15, len(idx))[:, None, None] * rng.standard_normal(x.shape)).astype(np.float32)
    return x[:, None], targets


def errors(net, cs: CornerSet, idx: np.ndarray, cfg: RefineTrainConfig, seed: int) -> dict:
    """Validation figures of ``net`` on samples idx, inputs perturbed with a fixed seed: corner error
    (px) before and after one pass, the spread, and the median after gating at spread <= 2 px."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    rng = np.random.default_rng(seed)
    x, t = make_batch(cs, idx, rng, cfg, augment=False)
    before = np.linalg.norm(t - (PATCH - 1) / 2.0, axis=1)
    net.eval()
    with torch.no_grad():
        uv, spread = soft_argmax(net(torch.from_numpy(x)))
    after = np.linalg.norm(uv.double().numpy() - t, axis=1)
    spread = spread.double().numpy()
    gated = np.where(spread <= 2.0, after, before)
    return {"n": int(len(idx)), "before_median_px": float(np.median(before)), "after_median_px": float(np.median(after)),
            "after_p90_px": float(np.percentile(after, 90)), "gated_median_px": float(np.median(gated)),
            "gated_p90_px": float(np.percentile(gated, 90)), "kept_share": float(np.mean(spread <= 2.0)),
            "within_1px_after": float(np.mean(after <= 1.0)), "within_1px_before": float(np.mean(before <= 1.0))}


def train_refine(roots: tuple[Path, ...], out: Path, cfg: RefineTrainConfig = RefineTrainConfig(),
                 log: Callable[[str], None] = print) -> dict:
    """Train the refinement net on the views under ``roots``; write its weights file to ``out``
    (arch, patch, widths, fp32 state_dict, meta with the config and validation figures); returns meta.
    ``out`` follows training.weights_file's rule, checked before any view is read."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    weights_file.check(out, roots)
    t0 = time.perf_counter()
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(cfg.threads)
    torch.use_deterministic_algorithms(True)
    cs = collect(roots, cfg)
    tr, va = np.flatnonzero(~cs.val), np.flatnonzero(cs.val)
    log(f"{len(cs.images)} views, {len(tr)} training corners, {len(va)} validation corners")
    net = build_net(WIDTHS)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    steps = cfg.epochs * int(np.ceil(len(tr) / cfg.batch))
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=steps, pct_start=0.15)
    rng = np.random.default_rng(cfg.seed)
    for epoch in range(cfg.epochs):
        net.train()
        order, total = rng.permutation(tr), 0.0
        for b in range(0, len(order), cfg.batch):
            x, t = make_batch(cs, order[b:b + cfg.batch], rng, cfg)
            logits = net(torch.from_numpy(x))
            uv, _ = soft_argmax(logits)
            tt = torch.from_numpy(t).float()
            p, gx, gy = heatmap(logits)  # the spread term: expected squared distance to the target
            d2 = (gx[None, None, :] - tt[:, 0, None, None]) ** 2 + (gy[None, :, None] - tt[:, 1, None, None]) ** 2
            loss = torch.nn.functional.smooth_l1_loss(uv, tt) + cfg.spread_weight * (p * d2).sum((1, 2)).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss.detach()) * len(x)
        if epoch % 5 == 4 or epoch == cfg.epochs - 1:
            v = errors(net, cs, va, cfg, seed=1)
            log(f"epoch {epoch + 1}: loss {total / len(tr):.4f}; validation corner error median "
                f"{v['before_median_px']:.2f} -> {v['after_median_px']:.3f} px (p90 {v['after_p90_px']:.2f}), "
                f"gated {v['gated_median_px']:.3f} px, kept {100 * v['kept_share']:.0f} %  ({time.perf_counter() - t0:.0f} s)")
    meta = {"config": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(cfg).items()},
            "views": len(cs.images), "train_corners": int(len(tr)), "validation": errors(net, cs, va, cfg, seed=1),
            "train_seconds": round(time.perf_counter() - t0, 1), "data": [str(r) for r in roots]}
    net.eval()
    ckpt = {"arch": ARCH, "patch": PATCH, "widths": list(WIDTHS),
            "state_dict": {k: v.detach().clone() for k, v in net.state_dict().items()}, "meta": meta}
    weights_file.save(out, ckpt, roots)
    return meta
