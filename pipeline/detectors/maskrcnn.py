"""Mask R-CNN (ResNet-50 FPN), the paper's architecture, from torchvision, trained from scratch.

No pretrained weights anywhere (weights=None, weights_backbone=None). Two classes: background and
window void. ``build_maskrcnn`` is shared by training (training/train.py) and inference.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from fenestra.errors import FenestraError
from pipeline.detectors.oracle import mask_box
from pipeline.types import Detection

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"
DEFAULT_MASKRCNN_WEIGHTS = MODELS_DIR / "maskrcnn.pt"
TRAIN_HINT = ("train it with `fenestra train --config training/configs/maskrcnn.toml --data DIR`, then "
              "`fenestra ship-weights out/train/maskrcnn.pt` (a GPU machine is advised; see docs/experiments.md)")


def build_maskrcnn(min_size: int = 480, max_size: int = 640) -> torch.nn.Module:
    """Untrained torchvision Mask R-CNN ResNet-50 FPN with 2 classes (background, window)."""
    from torchvision.models.detection import maskrcnn_resnet50_fpn  # noqa: PLC0415

    return maskrcnn_resnet50_fpn(weights=None, weights_backbone=None, num_classes=2,
                                 min_size=min_size, max_size=max_size)


def load_maskrcnn(weights: str | Path | None = None, device: str = "cpu") -> torch.nn.Module:
    """Mask R-CNN with trained weights (default pipeline/models/maskrcnn.pt), in eval mode on device."""
    path = Path(weights) if weights is not None else DEFAULT_MASKRCNN_WEIGHTS
    if not path.is_file():
        raise FenestraError(f"no Mask R-CNN weights at {path}: {TRAIN_HINT}")
    from pipeline.detectors.checkpoint import check_device, read_checkpoint  # noqa: PLC0415

    ckpt = read_checkpoint(path, "maskrcnn")
    model = build_maskrcnn(**ckpt.get("model_kw", {}))
    model.load_state_dict(ckpt["state_dict"])
    return model.eval().to(check_device(device))


def maskrcnn_targets(instances: np.ndarray) -> dict[str, torch.Tensor]:
    """torchvision training target from an instance map (H, W): boxes, labels, masks."""
    ids = [k for k in np.unique(instances) if k != 0]
    masks = np.stack([instances == k for k in ids]) if ids else np.zeros((0, *instances.shape), bool)
    boxes = []
    for m in masks:
        x0, y0, x1, y1 = mask_box(m)
        boxes.append([x0 + 0.5, y0 + 0.5, x1 + 0.5, y1 + 0.5])  # torchvision: pixel edges from 0
    return {"boxes": torch.tensor(boxes, dtype=torch.float32).reshape(-1, 4),
            "labels": torch.ones(len(ids), dtype=torch.int64),
            "masks": torch.from_numpy(masks.astype(np.uint8))}


@torch.no_grad()
def maskrcnn_detect(model: torch.nn.Module, image: np.ndarray) -> list[Detection]:
    """Detections (all scores) from Mask R-CNN for one RGB image (H, W, 3) uint8, best first."""
    device = next(model.parameters()).device
    x = torch.from_numpy(np.ascontiguousarray(image)).to(device).permute(2, 0, 1).float() / 255.0
    out = {k: v.cpu() for k, v in model([x])[0].items()}
    dets = []
    for score, m in zip(out["scores"].numpy(), out["masks"][:, 0].numpy()):
        mask = m >= 0.5
        if mask.any():
            dets.append(Detection(mask=mask, box=mask_box(mask), score=float(score)))
    dets.sort(key=lambda d: -d.score)
    return dets
