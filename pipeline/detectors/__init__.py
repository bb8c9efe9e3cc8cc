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

from fenestra.conventions import LIMITS
from fenestra.errors import FenestraError
from pipeline.detectors.checkpoint import check_device, read_checkpoint
from pipeline.detectors.oracle import DegradeConfig, check_instances, degraded_detections, oracle_detections
from pipeline.types import Detection, check_image

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


def load_winnet(weights: str | Path | None = None):
    """(model, PostConfig) from a WinNet checkpoint (default: the shipped pipeline/models/winnet.pt)."""
    import torch  # noqa: PLC0415

    from pipeline.detectors.winnet import PostConfig, WinNet, WinNetConfig  # noqa: PLC0415

    ckpt = read_checkpoint(_weights_file(weights, WINNET_WEIGHTS), "winnet")
    model = WinNet(WinNetConfig(tuple(ckpt["widths"])))
    model.load_state_dict({k: v.float() for k, v in ckpt["state_dict"].items()})
    model.to(memory_format=torch.channels_last)  # NHWC: faster convolutions on CPU (oneDNN)
    return model.eval(), PostConfig(**ckpt.get("post", {}))


def load_effwin(weights: str | Path | None = None):
    """(model, PostConfig) from an EffWin checkpoint (default: the shipped pipeline/models/default.pt).
    Only the model code is needed: the backbone's ImageNet weights are inside the checkpoint."""
    import torch  # noqa: PLC0415

    from pipeline.detectors.effwin import EffWin, EffWinConfig  # noqa: PLC0415
    from pipeline.detectors.winnet import PostConfig  # noqa: PLC0415

    ckpt = read_checkpoint(_weights_file(weights, DEFAULT_WEIGHTS), "effwin")
    c = ckpt["config"]
    model = EffWin(EffWinConfig(c["backbone"], tuple(c["fine"]), tuple(c["decoder"])))
    model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in ckpt["state_dict"].items()})
    model.to(memory_format=torch.channels_last)
    return model.eval(), PostConfig(**ckpt.get("post", {}))


def _weights_file(weights: str | Path | None, default: Path) -> Path:
    path = Path(weights) if weights is not None else default
    if not path.is_file():
        raise FenestraError(f"no detector weights at {path}: train them with `fenestra train --config "
                            "training/configs/<arch>.toml` (see pipeline/models/README.md)")
    return path


def checkpoint_arch(path: str | Path) -> str:
    """The ``arch`` a weights file holds (FenestraError if it is not a checkpoint)."""
    import torch  # noqa: PLC0415

    try:
        ckpt = torch.load(_weights_file(path, DEFAULT_WEIGHTS), map_location="cpu", weights_only=False)
    except FenestraError:
        raise
    except Exception as e:  # noqa: BLE001 - pickle, zip and torch errors all mean "not a model"
        raise FenestraError(f"{path} is not a model checkpoint ({type(e).__name__})") from e
    return str(ckpt.get("arch")) if isinstance(ckpt, dict) else type(ckpt).__name__


def load_map_predictor(weights: str | Path | None = None):
    """(predict, PostConfig) of a winnet or effwin weights file (default: the shipped default):
    predict(image (H, W, 3) uint8 RGB) -> (void, core) probability maps (H, W) float32, the inputs
    of winnet.instances_from_maps (post-processing tuning: training/tune.py)."""
    path = _weights_file(weights, DEFAULT_WEIGHTS)
    arch = checkpoint_arch(path)
    if arch == "winnet":
        from pipeline.detectors.winnet import predict_maps  # noqa: PLC0415

        model, post = load_winnet(path)
        return (lambda image: predict_maps(model, image)), post
    if arch == "effwin":
        from pipeline.detectors.effwin import predict_maps as effwin_maps  # noqa: PLC0415

        model, post = load_effwin(path)
        return (lambda image: tuple(effwin_maps(model, image)[:2])), post
    raise FenestraError(f"{path} holds a {arch!r} model; void/core maps come from winnet or effwin")


def _winnet(weights: str | Path | None = None, threads: int | None = None, device: str = "cpu") -> Detector:
    from pipeline.detectors.winnet import instances_from_maps, predict_maps  # noqa: PLC0415

    model, post = load_winnet(weights)
    model.to(check_device(device))
    set_cpu_threads(threads)

    def run(image: np.ndarray, **_: object) -> list[Detection]:
        return instances_from_maps(*predict_maps(model, image), post)
    return run


def _effwin(weights: str | Path | None = None, threads: int | None = None, device: str = "cpu") -> Detector:
    from pipeline.detectors.effwin import detections_from_maps, predict_maps  # noqa: PLC0415

    model, post = load_effwin(weights)
    model.to(check_device(device))
    set_cpu_threads(threads)

    def run(image: np.ndarray, **_: object) -> list[Detection]:
        return detections_from_maps(predict_maps(model, image), post)
    return run


def _default(weights: str | Path | None = None, threads: int | None = None, device: str = "cpu") -> Detector:
    """The shipped default (pipeline/models/default.pt), or any winnet/effwin weights file."""
    path = _weights_file(weights, DEFAULT_WEIGHTS)
    build = {"winnet": _winnet, "effwin": _effwin}.get(checkpoint_arch(path))
    if build is None:
        raise FenestraError(f"{path} holds a {checkpoint_arch(path)!r} model; the default detector loads winnet or effwin")
    return build(path, threads, device)


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


__all__ = ["DETECTORS", "DetectorEntry", "DegradeConfig", "Detection", "detect", "detector_entry", "get_detector",
           "check_image"]
