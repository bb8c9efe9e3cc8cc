"""Shipping trained weights: the one explicit step from a training run's output to the product.

    fenestra ship-weights out/train/default.pt      # -> fenestra/pipeline/models/default.pt (EffWin; out/train/winnet.pt -> winnet.pt,
                                                    #    out/train/quadnet.pt -> quadnet.pt)

Training writes under out/ (never into pipeline/); this copies a weights file to where its
detector loads it, after checking that the detector builds from it and runs on an image.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fenestra.errors import FenestraError
from fenestra.pipeline.detectors import DETECTORS, read_weights
from fenestra.training import weights_file

CHECK_IMAGE_HW = (64, 96)  # the blank image the shipped detector must run on


@dataclass(frozen=True)
class Shipped:
    """Where the weights went, the detector that loads them, the file's sha256, its training metadata."""

    path: Path
    detector: str
    sha256: str
    meta: dict


def shipping_detector(src: Path, ckpt: dict) -> str:
    """The registered trainable detector a weights file ships to: among those of its arch, the one
    whose shipped file has its name (out/train/quadnet.pt -> ``quadnet``: two detectors share the
    EffWin arch), else the first (the arch's own)."""
    names = [n for n in DETECTORS.where(trainable=True) if DETECTORS[n].model.arch == ckpt["arch"]]
    return next((n for n in names if DETECTORS[n].model.weights.name == src.name), names[0])


def ship_weights(src: str | Path, dest: str | Path | None = None, force: bool = False) -> Shipped:
    """Check ``src`` (its architecture's detector builds from it and runs on a blank
    CHECK_IMAGE_HW image), then copy it atomically to ``dest`` (default: the file that detector
    loads: the registered trainable detector of its arch, ``DETECTORS[name].model.weights``,
    listed in fenestra/pipeline/models' manifest) under fenestra.outputs' rule
    (training.weights_file): never over ``src`` itself nor a file Fenestra did not write
    (``force``: also over a weights file no manifest lists). FenestraError naming the problem
    (checked before the detector runs); nothing is written then."""
    src = Path(src)
    if not src.is_file():
        raise FenestraError(f"no weights file at {src}")
    ckpt = read_weights(src)  # FenestraError unless it is a trainable detector's weights file
    detector = shipping_detector(src, ckpt)
    dest = Path(dest) if dest is not None else DETECTORS[detector].model.weights
    weights_file.check(dest, (src,), force, option="--to")
    run = DETECTORS[detector].build(weights=src)
    dets = run(np.zeros((*CHECK_IMAGE_HW, 3), np.uint8))
    if not isinstance(dets, list):
        raise FenestraError(f"detector {detector!r} with {src} returned {type(dets).__name__}, not a list")
    data = src.read_bytes()
    weights_file.copy(dest, data, (src,), force)
    return Shipped(dest, detector, hashlib.sha256(data).hexdigest(), ckpt.get("meta", {}))
