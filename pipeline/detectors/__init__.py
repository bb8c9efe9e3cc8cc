"""Window-void detectors behind one registry.

    from pipeline.detectors import DETECTORS, detect
    dets = detect("default", image)                        # learned: EffWin (pretrained backbone, corner head)
    dets = detect("winnet", image)                         # learned from scratch (the default before issue #13)
    dets = detect("oracle", image, instances=inst)         # exact masks from an instance map
    dets = detect("oracle-degraded", image, instances=inst, config=DegradeConfig(seed=1))
    dets = detect("maskrcnn", image, weights="pipeline/models/maskrcnn.pt")

``DETECTORS[name]`` is a ``DetectorEntry``: ``.build(**options)`` makes a detector, a callable
``(image, **per_image) -> list[Detection]`` (every candidate, best first), and its capabilities say
how to call it (``needs_instances``: the oracles take the ground-truth instance map, per image, and
run at full resolution). ``detect`` caches the built detector, applies
``score_threshold`` and checks the input; learned detectors see photos larger than
``LIMITS.detector_max_side_px`` resized, their masks come back sparse at full resolution
(Detection.origin). Detection.box is (x0, y0, x1, y1) on the pixel-edge
outline of the mask (pixel centres at integers, so x1 - x0 is the width in px).
"""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from fenestra.checks import check_image, check_instances
from fenestra.conventions import LIMITS
from fenestra.errors import FenestraError
from pipeline.detectors.checkpoint import check_device, read_checkpoint
from pipeline.detectors.oracle import DegradeConfig, degraded_detections, oracle_detections
from pipeline.types import Detection

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"
DEFAULT_WEIGHTS = MODELS_DIR / "default.pt"
WINNET_WEIGHTS = MODELS_DIR / "winnet.pt"

Detector = Callable[..., list[Detection]]


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


def _winnet_model(ckpt: dict):
    from pipeline.detectors.winnet import WinNet, WinNetConfig  # noqa: PLC0415

    return WinNet(WinNetConfig(tuple(ckpt["widths"])))


def _effwin_model(ckpt: dict):
    from pipeline.detectors.effwin import EffWin, EffWinConfig  # noqa: PLC0415

    c = ckpt["config"]  # only the model code is needed: the ImageNet weights are in the checkpoint
    return EffWin(EffWinConfig(c["backbone"], tuple(c["fine"]), tuple(c["decoder"])))


MAP_MODELS = {"winnet": _winnet_model, "effwin": _effwin_model}  # arch -> model from its checkpoint


def load_map_model(weights: str | Path | None = None, default: Path = DEFAULT_WEIGHTS, archs=tuple(MAP_MODELS)):
    """(arch, model in eval mode, PostConfig) from a WinNet or EffWin weights file (default: the
    shipped ``default``), read once; FenestraError naming the file if it is missing or holds
    another architecture."""
    import torch  # noqa: PLC0415

    from pipeline.detectors.winnet import PostConfig  # noqa: PLC0415

    path = Path(weights) if weights is not None else default
    if not path.is_file():
        raise FenestraError(f"no detector weights at {path}: train them with `fenestra train --config "
                            "training/configs/<arch>.toml` (see pipeline/models/README.md)")
    ckpt = read_checkpoint(path, archs)
    model = MAP_MODELS[ckpt["arch"]](ckpt)
    model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in ckpt["state_dict"].items()})
    model.to(memory_format=torch.channels_last)  # NHWC: faster convolutions on CPU (oneDNN)
    return ckpt["arch"], model.eval(), PostConfig(**ckpt.get("post", {}))


def load_map_predictor(weights: str | Path | None = None):
    """(predict, PostConfig) of a winnet or effwin weights file (default: the shipped default):
    predict(image (H, W, 3) uint8 RGB) -> (void, core) probability maps (H, W) float32, the inputs
    of winnet.instances_from_maps (post-processing tuning: training/tune.py)."""
    from pipeline.detectors import effwin, winnet  # noqa: PLC0415

    arch, model, post = load_map_model(weights)
    if arch == "winnet":
        return (lambda image: winnet.predict_maps(model, image)), post
    return (lambda image: tuple(effwin.predict_maps(model, image)[:2])), post


def _map_detector(weights: str | Path | None, threads: int | None, device: str, default: Path,
                  archs: tuple[str, ...]) -> Detector:
    """A WinNet or EffWin detector (EffWin's detections carry corners)."""
    from pipeline.detectors import effwin, winnet  # noqa: PLC0415

    arch, model, post = load_map_model(weights, default, archs)
    model.to(check_device(device))
    set_cpu_threads(threads)
    if arch == "winnet":
        return lambda image, **_: winnet.instances_from_maps(*winnet.predict_maps(model, image), post)
    return lambda image, **_: effwin.detections_from_maps(effwin.predict_maps(model, image), post)


def _winnet(weights: str | Path | None = None, threads: int | None = None, device: str = "cpu") -> Detector:
    return _map_detector(weights, threads, device, WINNET_WEIGHTS, ("winnet",))


def _default(weights: str | Path | None = None, threads: int | None = None, device: str = "cpu") -> Detector:
    """The shipped default (pipeline/models/default.pt, EffWin), or any winnet/effwin weights file."""
    return _map_detector(weights, threads, device, DEFAULT_WEIGHTS, tuple(MAP_MODELS))


def _maskrcnn(weights: str | Path | None = None, threads: int | None = None, device: str = "cpu") -> Detector:
    from pipeline.detectors.maskrcnn import load_maskrcnn, maskrcnn_detect  # noqa: PLC0415

    model = load_maskrcnn(weights, device)
    set_cpu_threads(threads)

    def run(image: np.ndarray, **_: object) -> list[Detection]:
        return maskrcnn_detect(model, image)
    return run


@dataclass(frozen=True)
class DetectorEntry:
    """A registered detector: how to build it, and what it needs.

    build(**options) -> Detector. needs_instances: it reads the ground-truth instance map
    (``instances=`` (H, W) int, per image; the oracles), so it runs only where one exists (renders,
    labelled masks) and always at the image's full resolution. in_all: part of a profile's
    ``detectors = ["all"]`` (False for maskrcnn, whose weights are not shipped: a fresh clone
    would have to skip it).
    """

    build: Callable[..., Detector]
    needs_instances: bool = False
    in_all: bool = True


DETECTORS: dict[str, DetectorEntry] = {
    "oracle": DetectorEntry(_oracle, needs_instances=True),
    "oracle-degraded": DetectorEntry(_oracle_degraded, needs_instances=True),
    "default": DetectorEntry(_default),
    "winnet": DetectorEntry(_winnet),
    "maskrcnn": DetectorEntry(_maskrcnn, in_all=False),
}


def detector_entry(name: str) -> DetectorEntry:
    """The registry entry of detector ``name``; ValueError naming it and the choices if unknown."""
    if name not in DETECTORS:
        raise ValueError(f"unknown detector {name!r}; choose from {sorted(DETECTORS)}")
    return DETECTORS[name]


@functools.lru_cache(maxsize=8)
def _cached(name: str, options: tuple) -> Detector:
    return DETECTORS[name].build(**dict(options))


def get_detector(name: str, **options: object) -> Detector:
    """The detector ``name`` built with ``options`` (cached: weights load once)."""
    entry = detector_entry(name)
    key = tuple(sorted((k, str(v) if isinstance(v, Path) else v) for k, v in options.items()))
    try:
        hash(key)
    except TypeError:
        return entry.build(**options)
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
    needs_instances = detector_entry(name).needs_instances
    if needs_instances and instances is None:
        raise ValueError(f"detector {name!r} needs instances= an (H, W) instance map")
    run = get_detector(name, **options)
    scale = 1.0 if needs_instances else input_scale(image.shape[:2])
    if scale == 1.0:
        dets = run(image, **per_image)
    else:  # bounded memory and time: the network sees a smaller copy, masks come back sparse
        dets = [full_resolution(d, scale, image.shape[:2]) for d in run(downscale(image, scale), **per_image)]
    return [d for d in dets if d.score >= score_threshold]


def input_scale(shape: tuple[int, int], max_side: int = LIMITS.detector_max_side_px) -> float:
    """Factor (<= 1) that brings an (H, W) image's long side down to ``max_side`` px."""
    return min(1.0, max_side / max(shape))


def downscale(image: np.ndarray, scale: float) -> np.ndarray:
    """(round(H s), round(W s), 3) copy of an image, INTER_AREA."""
    H, W = image.shape[:2]
    return cv2.resize(image, (max(1, round(W * scale)), max(1, round(H * scale))), interpolation=cv2.INTER_AREA)


def full_resolution(det: Detection, scale: float, shape: tuple[int, int]) -> Detection:
    """A detection on an image downscaled by ``scale`` mapped back to the (H, W) original, sparse:
    the mask's bounding box (+1 px) resized bilinearly (threshold 0.5) into a crop at ``origin``.

    The small detection's mask may itself be sparse (a crop at ``det.origin``). Box and corners
    (pixel centres at integers) map by ``(v + 0.5) / scale - 0.5`` (:func:`box_to_full`); corners
    (4, 2) px stay None when the detector has none.
    """
    H, W = shape
    small = np.asarray(det.mask, dtype=np.uint8)
    box = box_to_full(det.box, scale)
    corners = None if det.corners is None else points_to_full(det.corners, scale)
    x, y, w, h = cv2.boundingRect(small)
    if w == 0 or h == 0:
        return dataclasses.replace(det, mask=np.zeros((0, 0), bool), box=box, origin=(0, 0), corners=corners)
    ox, oy = det.origin
    sx0, sy0 = max(x - 1, 0), max(y - 1, 0)  # crop pixels, +1 px of background where the crop has it
    sx1, sy1 = min(x + w + 1, small.shape[1]), min(y + h + 1, small.shape[0])
    fx0, fy0 = int(round((ox + sx0) / scale)), int(round((oy + sy0) / scale))
    fx1, fy1 = min(W, int(round((ox + sx1) / scale))), min(H, int(round((oy + sy1) / scale)))
    crop = cv2.resize(small[sy0:sy1, sx0:sx1] * np.uint8(255), (fx1 - fx0, fy1 - fy0), interpolation=cv2.INTER_LINEAR)
    return dataclasses.replace(det, mask=crop >= 128, box=box, origin=(fx0, fy0), corners=corners)


def points_to_full(points: np.ndarray, scale: float) -> np.ndarray:
    """Points (..., 2) px on the downscaled image -> the original's (pixel centres at integers)."""
    return (np.asarray(points, dtype=np.float64) + 0.5) / scale - 0.5


def box_to_full(box: np.ndarray, scale: float) -> np.ndarray:
    """(4,) box px on the downscaled image -> the original's (pixel centres at integers)."""
    return points_to_full(box, scale)


__all__ = ["DETECTORS", "DetectorEntry", "DegradeConfig", "Detection", "detect", "detector_entry", "get_detector"]
