"""Mask R-CNN (ResNet-50 FPN), the paper's architecture, from torchvision, trained from scratch.

No pretrained weights anywhere (weights=None, weights_backbone=None). Two classes: background and
window void. ``build_maskrcnn`` is shared by training (fenestra/training/train.py) and inference.
"""
from __future__ import annotations

import numpy as np
import torch

from fenestra.pipeline.detectors.oracle import mask_box
from fenestra.pipeline.types import Detection



def build_maskrcnn(min_size: int = 480, max_size: int = 640) -> torch.nn.Module:
    """Untrained torchvision Mask R-CNN ResNet-50 FPN with 2 classes (background, window)."""
    from torchvision.models.detection import maskrcnn_resnet50_fpn  # noqa: PLC0415

    return maskrcnn_resnet50_fpn(weights=None, weights_backbone=None, num_classes=2,
                                 min_size=min_size, max_size=max_size)


def model_from_checkpoint(ckpt: dict) -> torch.nn.Module:
    """The Mask R-CNN of a weights file's dict (``model_kw``, fp32 ``state_dict``), in eval mode on the CPU."""
    model = build_maskrcnn(**ckpt.get("model_kw", {}))
    model.load_state_dict(ckpt["state_dict"])
    return model.eval()


def detector_from_model(model: torch.nn.Module, ckpt: dict):
    """image (H, W, 3) uint8 RGB -> Detections (all scores), best first."""
    return lambda image, **_: maskrcnn_detect(model, image)


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
