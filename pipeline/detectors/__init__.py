"""Window-void detectors behind one registry.

    from pipeline.detectors import DETECTORS, detect
    dets = detect("default", image)                        # learned, CPU-fast (WinNet)
    dets = detect("oracle", image, instances=inst)         # exact masks from an instance map
    dets = detect("oracle-degraded", image, instances=inst, config=DegradeConfig(seed=1))
    dets = detect("maskrcnn", image, weights="pipeline/models/maskrcnn.pt")

``DETECTORS[name](**options)`` builds a detector: a callable ``(image, **per_image) ->
list[Detection]`` (every candidate, best first). ``detect`` caches the built detector, applies
``score_threshold`` and checks the input. Detection.box is (x0, y0, x1, y1) on the pixel-edge
outline of the mask (pixel centres at integers, so x1 - x0 is the width in px).
"""
from __future__ import annotations

import functools
from pathlib import Path
from typing import Callable

import numpy as np

from fenestra.errors import FenestraError
from pipeline.detectors.oracle import DegradeConfig, check_instances, degraded_detections, oracle_detections
from pipeline.types import Detection

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"
DEFAULT_WEIGHTS = MODELS_DIR / "default.pt"

Detector = Callable[..., list[Detection]]


def check_image(image: np.ndarray) -> np.ndarray:
    """Validate an RGB image (H, W, 3) uint8; raises ValueError naming the problem."""
    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"image must be (H, W, 3) RGB, got shape {a.shape}")
    if a.dtype != np.uint8:
        raise ValueError(f"image must be uint8, got dtype {a.dtype}")
    if a.shape[0] < 8 or a.shape[1] < 8:
        raise ValueError(f"image too small: {a.shape[1]}x{a.shape[0]} px")
    return a


def set_cpu_threads(n: int | None = None) -> None:
    """Use at most n (default: all, capped at 4) torch CPU threads for inference."""
    import os  # noqa: PLC0415

    import torch  # noqa: PLC0415  (lazy: torch costs ~1.5 s to import)

    torch.set_num_threads(n or max(1, min(4, os.cpu_count() or 1)))


def _oracle(**_: object) -> Detector:
    def run(image: np.ndarray, instances: np.ndarray | None = None) -> list[Detection]:
        return oracle_detections(check_instances(instances, image.shape))
    return run


def _oracle_degraded(config: DegradeConfig = DegradeConfig()) -> Detector:
    if not isinstance(config, DegradeConfig):
        raise ValueError(f"config must be a DegradeConfig, got {type(config).__name__}")

    def run(image: np.ndarray, instances: np.ndarray | None = None) -> list[Detection]:
        return degraded_detections(check_instances(instances, image.shape), config)
    return run


def load_winnet(weights: str | Path | None = None):
    """(model, PostConfig) from a WinNet checkpoint (default: the shipped pipeline/models/default.pt)."""
    import torch  # noqa: PLC0415

    from pipeline.detectors.winnet import PostConfig, WinNet, WinNetConfig  # noqa: PLC0415

    path = Path(weights) if weights is not None else DEFAULT_WEIGHTS
    if not path.is_file():
        raise FenestraError(f"no WinNet weights at {path}: train them with "
                            "`fenestra train --config pipeline/models/default.toml` (see pipeline/models/README.md)")
    ckpt = torch.load(path, map_location="cpu", weights_only=False)
    if ckpt.get("arch") != "winnet":
        raise FenestraError(f"{path} holds a {ckpt.get('arch')!r} model, not 'winnet'")
    model = WinNet(WinNetConfig(tuple(ckpt["widths"])))
    model.load_state_dict({k: v.float() for k, v in ckpt["state_dict"].items()})
    model.to(memory_format=torch.channels_last)  # NHWC: faster convolutions on CPU (oneDNN)
    return model.eval(), PostConfig(**ckpt.get("post", {}))


def _default(weights: str | Path | None = None, threads: int | None = None, device: str = "cpu") -> Detector:
    from pipeline.detectors.winnet import instances_from_maps, predict_maps  # noqa: PLC0415

    model, post = load_winnet(weights)
    model.to(device)
    set_cpu_threads(threads)

    def run(image: np.ndarray, **_: object) -> list[Detection]:
        return instances_from_maps(*predict_maps(model, image), post)
    return run


def _maskrcnn(weights: str | Path | None = None, threads: int | None = None, device: str = "cpu") -> Detector:
    from pipeline.detectors.maskrcnn import load_maskrcnn, maskrcnn_detect  # noqa: PLC0415

    model = load_maskrcnn(weights, device)
    set_cpu_threads(threads)

    def run(image: np.ndarray, **_: object) -> list[Detection]:
        return maskrcnn_detect(model, image)
    return run


DETECTORS: dict[str, Callable[..., Detector]] = {
    "oracle": _oracle,
    "oracle-degraded": _oracle_degraded,
    "default": _default,
    "maskrcnn": _maskrcnn,
}


@functools.lru_cache(maxsize=8)
def _cached(name: str, options: tuple) -> Detector:
    return DETECTORS[name](**dict(options))


def get_detector(name: str, **options: object) -> Detector:
    """The detector ``name`` built with ``options`` (cached: weights load once)."""
    if name not in DETECTORS:
        raise ValueError(f"unknown detector {name!r}; choose from {sorted(DETECTORS)}")
    key = tuple(sorted((k, str(v) if isinstance(v, Path) else v) for k, v in options.items()))
    try:
        hash(key)
    except TypeError:
        return DETECTORS[name](**options)
    return _cached(name, key)


def detect(name: str, image: np.ndarray, score_threshold: float = 0.5,
           instances: np.ndarray | None = None, **options: object) -> list[Detection]:
    """Detect window voids in one RGB photo (H, W, 3) uint8; Detections best first.

    instances: (H, W) int instance map, required by the oracles only. options: the detector's
    build options (e.g. weights=PATH, config=DegradeConfig(...), threads=N).
    """
    image = check_image(image)
    if not 0.0 <= score_threshold <= 1.0:
        raise ValueError(f"score_threshold must be in [0, 1], got {score_threshold}")
    per_image = {} if instances is None else {"instances": instances}
    if name in ("oracle", "oracle-degraded") and instances is None:
        raise ValueError(f"detector {name!r} needs instances= an (H, W) instance map")
    dets = get_detector(name, **options)(image, **per_image)
    return [d for d in dets if d.score >= score_threshold]


__all__ = ["DETECTORS", "DegradeConfig", "Detection", "detect", "get_detector", "check_image"]
