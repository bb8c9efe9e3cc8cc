"""Window-void detectors behind one registry.

    from fenestra.pipeline.detectors import DETECTORS, detect
    dets = detect("default", image)                        # learned: EffWin (pretrained backbone, corner head)
    dets = detect("quadnet", image)                        # detector v8: EffWin + quad head, one window per centre
    dets = detect("winnet", image)                         # learned from scratch (the former default)
    dets = detect("oracle", image, instances=inst)         # exact masks from an instance map
    dets = detect("oracle-degraded", image, instances=inst, config=DegradeConfig(seed=1))
    dets = detect("maskrcnn", image, weights="fenestra/pipeline/models/maskrcnn.pt")

``DETECTORS`` is a :class:`fenestra.registry.Registry` of ``DetectorEntry``: ``.build(**options)``
makes a detector, a callable ``(image, **per_image) -> list[Detection]`` (every candidate, best
first), and its capabilities say how to call it (``needs_instances``: the oracles take the
ground-truth instance map, per image, and run at full resolution; ``trainable``: it loads a weights
file, see :func:`trainable`). ``detect`` caches the built detector, applies
``score_threshold`` and checks the input; learned detectors see photos larger than
``LIMITS.detector_max_side_px`` resized, their masks come back sparse at full resolution
(Detection.origin). Detection.box is (x0, y0, x1, y1) on the pixel-edge
outline of the mask (pixel centres at integers, so x1 - x0 is the width in px).
"""
from __future__ import annotations

import dataclasses
import functools
import importlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from fenestra.checks import check_image, check_instances
from fenestra.conventions import LIMITS
from fenestra.errors import FenestraError
from fenestra.registry import Registry
from fenestra.pipeline.detectors.checkpoint import check_device, read_checkpoint
from fenestra.pipeline.detectors.oracle import (DegradeConfig, degraded_detections, detections_from_instance_map,
                                                oracle_detections)
from fenestra.pipeline.types import DETECTION_KINDS, Detection

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"
DEFAULT_WEIGHTS = MODELS_DIR / "default.pt"  # DETECTORS["default"].model.weights

Detector = Callable[..., list[Detection]]


def set_cpu_threads(n: int | None = None) -> None:
    """Use at most n torch CPU threads for inference (default: OMP_NUM_THREADS when set, as in the
    bench's workers, else all cores capped at 4)."""

    import torch  # noqa: PLC0415  (lazy: torch costs ~1.5 s to import)

    env = os.environ.get("OMP_NUM_THREADS", "")
    torch.set_num_threads(n or (int(env) if env.isdigit() and int(env) > 0 else max(1, min(4, os.cpu_count() or 1))))


def _oracle(sparse: bool = False, **_: object) -> Detector:
    """The instance map's windows as detections: full (H, W) masks (the bench's oracle rows), or
    with ``sparse`` one bounding-box crop per id (a user's ``--masks``: memory O(H W) once)."""
    if not isinstance(sparse, bool):
        raise ValueError(f"sparse must be a bool, got {sparse!r}")

    def run(image: np.ndarray, instances: np.ndarray | None = None) -> list[Detection]:
        if sparse:
            return detections_from_instance_map(check_instances(instances, image.shape))
        return oracle_detections(check_instances(instances, image.shape))
    return run


def _oracle_degraded(config: DegradeConfig = DegradeConfig()) -> Detector:
    if not isinstance(config, DegradeConfig):
        raise ValueError(f"config must be a DegradeConfig, got {type(config).__name__}")

    def run(image: np.ndarray, instances: np.ndarray | None = None) -> list[Detection]:
        return degraded_detections(check_instances(instances, image.shape), config)
    return run


@dataclass(frozen=True)
class Checkpointed:
    """How a trainable detector's weights file becomes a detector.

    arch: the file's ``"arch"`` key (what fenestra/training/recipes/<arch>.py writes); module: the inference
    file, ``fenestra/pipeline/detectors/<arch>.py`` as a dotted name (imported when the detector is built:
    torch stays unimported until then), which defines ``model_from_checkpoint(ckpt) -> model`` (eval
    mode, CPU), ``detector_from_model(model, ckpt) -> Detector`` and, for detectors with void/core
    maps, ``void_core_maps(model) -> image -> (void, core)``; weights: the shipped file (what
    ``build(weights=None)`` loads, where ``fenestra ship-weights`` copies to); config: its training
    config (fenestra/training/configs/).
    """

    arch: str
    module: str
    weights: Path
    config: str

    def load(self, ckpt: dict, device: str = "cpu"):
        """(the inference module, the model on ``device``) of a checkpoint dict of this arch."""
        mod = importlib.import_module(self.module)
        return mod, mod.model_from_checkpoint(ckpt).to(check_device(device))


@dataclass(frozen=True)
class DetectorEntry:
    """A registered detector: how to build it, and what it needs.

    build(**options) -> Detector; description: one line for CLI help. Capabilities
    (fenestra.registry): needs_instances: it reads the ground-truth instance map (``instances=``
    (H, W) int, per image; the oracles), so it runs only where one exists (renders, labelled masks)
    and always at the image's full resolution. in_all: part of a profile's ``detectors = ["all"]``
    (False for quadnet, measured by its own tools).
    trainable: it loads a weights file (``model``: :class:`Checkpointed`) that a training recipe
    (fenestra/training/recipes/<arch>.py) writes.
    """

    name: str
    build: Callable[..., Detector]
    description: str
    needs_instances: bool = False
    in_all: bool = True
    model: Checkpointed | None = None

    @property
    def trainable(self) -> bool:
        return self.model is not None


def trainable(name: str, arch: str, weights: str, description: str, any_arch: bool = False,
              **capabilities: bool) -> DetectorEntry:
    """The entry of a trainable detector: inference in fenestra/pipeline/detectors/<arch>.py, shipped weights
    fenestra/pipeline/models/<weights>.pt, training config fenestra/training/configs/<weights>.toml. Its build takes
    ``weights`` (a file; default the shipped one), ``threads`` and ``device``; any_arch: it also
    loads the weights of every other trainable detector (the default detector does)."""
    model = Checkpointed(arch, f"fenestra.pipeline.detectors.{arch}", MODELS_DIR / f"{weights}.pt",
                         f"fenestra/training/configs/{weights}.toml")
    build = functools.partial(build_trainable, model, any_arch)
    return DetectorEntry(name, build, description, model=model, **capabilities)


def checkpointed(arch: str) -> Checkpointed:
    """The Checkpointed of the registered detector that loads ``arch`` weights files; FenestraError
    naming the trainable architectures otherwise."""
    for e in DETECTORS.values():
        if e.model is not None and e.model.arch == arch:
            return e.model
    raise FenestraError(f"no registered detector loads {arch!r} weights; trainable architectures: {trainable_archs()}")


def trainable_archs() -> list[str]:
    """The weights-file architectures of the registered trainable detectors."""
    return [DETECTORS[n].model.arch for n in DETECTORS.where(trainable=True)]


def read_weights(path: str | Path, archs: tuple[str, ...] | None = None) -> dict:
    """A weights file's dict, of one of ``archs`` (default: any trainable detector's); FenestraError
    naming the file when it is not a checkpoint or holds another architecture."""
    return read_checkpoint(Path(path), tuple(trainable_archs()) if archs is None else archs)


def load_model(model: Checkpointed, weights: str | Path | None = None, any_arch: bool = False,
               device: str = "cpu"):
    """(inference module, model in eval mode on ``device``, checkpoint dict) of a weights file
    (default ``model.weights``) of ``model.arch``, or (any_arch) of any trainable detector's;
    FenestraError saying how to train the weights when the file is missing."""
    path = Path(weights) if weights is not None else model.weights
    if not path.is_file():
        raise FenestraError(f"no detector weights at {path}: train them with `fenestra train --config "
                            f"{model.config}`, then `fenestra ship-weights out/train/{model.weights.name}` "
                            "(see fenestra/pipeline/models/README.md)")
    ckpt = read_weights(path, None if any_arch else (model.arch,))
    mod, net = checkpointed(ckpt["arch"]).load(ckpt, device)
    return mod, net, ckpt


def build_trainable(model: Checkpointed, any_arch: bool, weights: str | Path | None = None,
                    threads: int | None = None, device: str = "cpu") -> Detector:
    """A trainable detector's build (see :func:`trainable`)."""
    mod, net, ckpt = load_model(model, weights, any_arch, device)
    set_cpu_threads(threads)
    try:
        return mod.detector_from_model(net, ckpt)
    except FenestraError as e:  # name the file
        raise FenestraError(f"{Path(weights) if weights is not None else model.weights}: {e}") from None


def load_map_predictor(weights: str | Path | None = None):
    """(predict, PostConfig) of a weights file with void/core maps (default: the shipped default):
    predict(image (H, W, 3) uint8 RGB) -> (void, core) probability maps (H, W) float32, the inputs
    of winnet.instances_from_maps (post-processing tuning: lab/tune.py); the PostConfig is the
    file's (its architecture module's ``post_config``)."""
    mod, net, ckpt = load_model(DETECTORS["default"].model, weights, any_arch=True)
    if not hasattr(mod, "void_core_maps"):
        raise FenestraError(f"{weights}: a {ckpt['arch']!r} model has no void/core maps to tune")
    post = mod.post_config(ckpt)
    return (mod.void_core_maps(net, post.mirror) if post.mirror else mod.void_core_maps(net)), post


DETECTORS: Registry[DetectorEntry] = Registry("detector", [
    DetectorEntry("oracle", _oracle, "exact masks from the ground-truth instance map", needs_instances=True),
    DetectorEntry("oracle-degraded", _oracle_degraded, "the true masks spoiled as Mask R-CNN's would be: jittered "
                  "box, 28 x 28 grid, blurred, wobbly edges (DegradeConfig)", needs_instances=True),
    trainable("default", "effwin", "default", "learned, the shipped default: EffWin (pretrained "
              "EfficientNet-Lite encoder, corner head); loads any trainable detector's weights", any_arch=True),
    trainable("quadnet", "effwin", "quadnet", "learned, detector v8: the default's network (frozen) with a quad "
              "head: one instance per window centre, its four corners regressed and refined on the corner "
              "heatmaps (quad source `network`; measured by tools/seed_spread.py, not in `all`)", in_all=False),
    trainable("winnet", "winnet", "winnet", "learned from scratch: WinNet, a small U-Net (void and core maps)"),
    trainable("maskrcnn", "maskrcnn", "maskrcnn", "the paper's method's detector: Mask R-CNN (torchvision; RPN, RoIAlign, "
              "box and 28 x 28 mask heads) on an ImageNet-pretrained EfficientNet-Lite0 FPN instead of the "
              "paper's ResNet-50 FPN, trained on this project's CPU on Fenestra's renders and street photos"),
])


def detector_entry(name: str) -> DetectorEntry:
    """The registry entry of detector ``name``; ValueError (fenestra.registry.UnknownName) naming it
    and the choices if unknown."""
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
           instances: np.ndarray | None = None, max_side: int = LIMITS.detector_max_side_px,
           kinds: tuple[str, ...] = ("window",), **options: object) -> list[Detection]:
    """Detect window voids in one RGB photo (H, W, 3) uint8; Detections best first.

    kinds: the Detection.kind values returned (pipeline.types.DETECTION_KINDS; a detector with a
    box verifier also finds doors and signboards: ``kinds=DETECTION_KINDS`` returns them too).
    instances: (H, W) int instance map, required by the oracles only. max_side: a learned
    detector sees the photo with its long side at most this (px; :func:`input_scale`), its masks,
    boxes and corners mapped back (:func:`full_resolution`). options: the detector's build options
    (e.g. weights=PATH, config=DegradeConfig(...), threads=N).
    """
    image = check_image(image)
    if not set(kinds) <= set(DETECTION_KINDS):
        raise ValueError(f"kinds must be among {DETECTION_KINDS}, got {kinds!r}")
    if not 0.0 <= score_threshold <= 1.0:
        raise ValueError(f"score_threshold must be in [0, 1], got {score_threshold}")
    per_image = {} if instances is None else {"instances": instances}
    needs_instances = detector_entry(name).needs_instances
    if needs_instances and instances is None:
        raise ValueError(f"detector {name!r} needs instances= an (H, W) instance map")
    run = get_detector(name, **options)
    if not (isinstance(max_side, int) and max_side > 0):
        raise ValueError(f"max_side must be a positive number of pixels, got {max_side!r}")
    scale = 1.0 if needs_instances else input_scale(image.shape[:2], max_side)
    if scale == 1.0:
        dets = run(image, **per_image)
    else:  # bounded memory and time: the network sees a smaller copy, masks come back sparse
        dets = [full_resolution(d, scale, image.shape[:2]) for d in run(downscale(image, scale), **per_image)]
    return [d for d in dets if d.score >= score_threshold and d.kind in kinds]


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


__all__ = ["DETECTORS", "Checkpointed", "DetectorEntry", "trainable", "DegradeConfig", "Detection", "detect",
           "detector_entry", "get_detector"]
