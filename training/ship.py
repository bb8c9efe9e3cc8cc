"""Shipping trained weights: the one explicit step from a training run's output to the product.

    fenestra ship-weights out/train/default.pt      # -> pipeline/models/default.pt (EffWin; out/train/winnet.pt -> winnet.pt)

Training writes under out/ (never into pipeline/); this copies a weights file to where its
detector loads it, after checking that the detector builds from it and runs on an image.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fenestra.errors import FenestraError
from fenestra.files import write_bytes
from pipeline.detectors import detector_entry
from training.train import ARCHS

CHECK_IMAGE_HW = (64, 96)  # the blank image the shipped detector must run on


@dataclass(frozen=True)
class Shipped:
    """Where the weights went, the detector that loads them, the file's sha256, its training metadata."""

    path: Path
    detector: str
    sha256: str
    meta: dict


def read_weights(path: Path) -> dict:
    """A weights file's dict (torch.load on the CPU); FenestraError naming the file if it is not
    one of a trainable architecture (ARCHS)."""
    import torch  # noqa: PLC0415

    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as e:  # noqa: BLE001 - pickle, zip and torch errors all mean "not weights"
        raise FenestraError(f"{path} is not a weights file ({type(e).__name__})") from e
    arch = ckpt.get("arch") if isinstance(ckpt, dict) else None
    if arch not in ARCHS:
        raise FenestraError(f"{path} holds arch {arch!r}; trainable architectures: {sorted(ARCHS)}")
    return ckpt


def ship_weights(src: str | Path, dest: str | Path | None = None) -> Shipped:
    """Check ``src`` (its architecture's detector builds from it and runs on a blank
    CHECK_IMAGE_HW image), then copy it atomically to ``dest`` (default: the file that detector
    loads, ARCHS[arch].shipped). FenestraError naming the problem; nothing is written then."""
    src = Path(src)
    if not src.is_file():
        raise FenestraError(f"no weights file at {src}")
    ckpt = read_weights(src)
    arch = ARCHS[ckpt["arch"]]
    dest = Path(dest) if dest is not None else arch.shipped
    if dest.resolve() == src.resolve():
        raise FenestraError(f"{src} is already the destination")
    run = detector_entry(arch.detector).build(weights=src)
    dets = run(np.zeros((*CHECK_IMAGE_HW, 3), np.uint8))
    if not isinstance(dets, list):
        raise FenestraError(f"detector {arch.detector!r} with {src} returned {type(dets).__name__}, not a list")
    data = src.read_bytes()
    dest.parent.mkdir(parents=True, exist_ok=True)
    write_bytes(dest, data)
    return Shipped(dest, arch.detector, hashlib.sha256(data).hexdigest(), ckpt.get("meta", {}))
