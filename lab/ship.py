"""Shipping trained weights: the one explicit step from a training run's output to the package.

    python -m lab.ship out/train/default.pt     # -> fenestra/pipeline/models/default.pt (EffWin; out/train/winnet.pt
                                                #    -> winnet.pt, out/train/quadnet.pt -> quadnet.pt, maskrcnn.pt ...)
    python -m lab.ship out/train/refine.pt      # the corner refinement -> fenestra/pipeline/models/refine.pt

Training writes under out/ (never into the package); this copies a weights file to where its
detector (or the ``refine`` snapper) loads it, after checking that it builds from it and runs.
It writes into the package's own folder, which only a checkout does: it is the lab's, not the
installed package's.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fenestra import outputs
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


def is_refine_weights(src: Path) -> bool:
    """``src`` is a corner-refinement weights file (what ``fenestra train-refine`` writes: its arch
    is pipeline.snappers.refine.ARCH), not a detector's."""
    import torch  # noqa: PLC0415 (torch: imported when first used)

    from fenestra.pipeline.snappers.refine import ARCH  # noqa: PLC0415 (torch: imported when first used)

    try:
        ckpt = torch.load(src, map_location="cpu", weights_only=True)
    except Exception:  # noqa: BLE001 -- not a weights file at all: the detector's reader says why
        return False
    return isinstance(ckpt, dict) and ckpt.get("arch") == ARCH


def ship_refine(src: str | Path, dest: str | Path | None = None, force: bool = False) -> Shipped:
    """Check that the ``refine`` snapper loads ``src``, then copy it atomically to ``dest``
    (default: pipeline.snappers.refine.SHIPPED) under the same rule as :func:`ship_weights`."""
    from fenestra.pipeline.snappers.refine import SHIPPED, load_refiner  # noqa: PLC0415 (torch: imported when first used)

    src = Path(src)
    dest = Path(dest) if dest is not None else SHIPPED
    weights_file.check(dest, (src,), force, option="--to")
    load_refiner(str(src))  # refuses a file the snapper cannot use
    data = src.read_bytes()
    weights_file.copy(dest, data, (src,), force)
    return Shipped(dest, "refine", hashlib.sha256(data).hexdigest(), {})


def main(argv: list[str] | None = None) -> int:
    """``python -m lab.ship W.pt [--to PATH] [--force]``: exit 2 with one line on a refused file."""
    import argparse  # noqa: PLC0415
    import sys  # noqa: PLC0415

    ap = argparse.ArgumentParser(description="Ship trained weights: check that their detector (or the refine "
                                             "snapper) loads and runs them, then copy them into place.")
    ap.add_argument("src", type=Path, help="trained weights (what `fenestra train` / `train-refine` wrote)")
    ap.add_argument("--to", type=Path, default=None, help="destination (default: the file the detector loads, e.g. "
                                                          "fenestra/pipeline/models/default.pt for EffWin)")
    ap.add_argument("--force", action="store_true", help="--to may replace a weights file that no Fenestra manifest lists")
    a = ap.parse_args(argv)
    try:
        shipped = (ship_refine if a.src.is_file() and is_refine_weights(a.src) else ship_weights)(a.src, a.to, a.force)
    except (FenestraError, outputs.OwnershipError, ValueError, OSError) as e:
        print("error: " + " ".join(str(e).split()), file=sys.stderr)
        return 2
    print(f"shipped {a.src} -> {shipped.path} (detector {shipped.detector!r}, sha256 {shipped.sha256[:16]}, "
          f"{shipped.meta.get('iterations_done', '?')} iterations, {shipped.meta.get('train_seconds', '?')} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
