"""Time one training step of a config on this machine: batch making, and the network step with and
without bfloat16 autocast and channels-last layout (the figures quoted in fenestra/pipeline/models/README.md
and docs/experiments.md).

    .venv/bin/python tools/steptime.py [--config fenestra/training/configs/winnet.toml] [--widths 16,32,64,96,128] [--crop 256]

Reads one view per training dataset folder, makes 7 batches (times the last 6), runs 8 steps per variant from a fresh
model and prints the median of the last 6 (ms). Medians only: the machine is shared and noisy.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from fenestra.training.recipes.winnet import winnet_loss  # noqa: E402
from fenestra.training.train import build_model, load_config, make_batch, read_views, select_views  # noqa: E402

VARIANTS = {"fp32": (False, False), "fp32 channels_last": (False, True), "bf16 channels_last": (True, True)}


def step_ms(cfg, batches: list, amp: bool, channels_last: bool, steps: int = 8) -> float:
    """Median wall time (ms) of a WinNet forward + backward + AdamW step, first 2 steps dropped."""
    torch.manual_seed(cfg.seed)
    model, opt = build_model(cfg)
    model.train()
    if channels_last:
        model.to(memory_format=torch.channels_last)
    times = []
    for i in range(steps):
        x, y = batches[i % len(batches)]
        if channels_last:
            x = x.contiguous(memory_format=torch.channels_last)
        t0 = time.perf_counter()
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=amp):
            loss = winnet_loss(model(x).float(), y)["loss"]
        opt.zero_grad()
        loss.backward()
        opt.step()
        times.append(time.perf_counter() - t0)
    return float(np.median(times[2:]) * 1000.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="fenestra/training/configs/winnet.toml")
    ap.add_argument("--widths", action="append", default=[],
                    help="comma-separated WinNet widths to time instead of the config's (repeatable)")
    ap.add_argument("--crop", type=int, help="square crop side (px) instead of the config's crop_hw")
    a = ap.parse_args()
    cfg = load_config(a.config, crop_hw=(a.crop, a.crop) if a.crop else None)
    if cfg.arch != "winnet":
        raise SystemExit(f"steptime times WinNet configs; {a.config} has arch {cfg.arch!r}")
    torch.set_num_threads(cfg.threads)
    data = read_views(select_views(cfg.data, 1, log=lambda *_: None))
    batches = [make_batch(data, cfg, 0)]  # the first batch also pays for lazy imports
    t0 = time.perf_counter()
    batches += [make_batch(data, cfg, it) for it in range(1, 7)]
    print(f"batch making: {(time.perf_counter() - t0) / 6 * 1000:.0f} ms/batch "
          f"({cfg.batch_size} x {cfg.crop_hw[0]}x{cfg.crop_hw[1]}, {cfg.threads} threads)")
    widths = [tuple(int(c) for c in w.split(",")) for w in a.widths] or [cfg.winnet_widths]
    for w in widths:
        c = replace(cfg, winnet_widths=w)
        row = {name: step_ms(c, batches, amp, cl) for name, (amp, cl) in VARIANTS.items()}
        print(f"widths {'-'.join(map(str, w))}: " + ", ".join(f"{k} {v:.0f} ms" for k, v in row.items()), flush=True)


if __name__ == "__main__":
    main()
