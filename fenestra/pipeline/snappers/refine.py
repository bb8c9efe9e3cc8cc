"""``refine``: a small CNN moves each corner to the window void's corner it sees in a patch around it.

Learned corner refinement. For each corner of the incoming quad (the mask-fit
quad of a detection) a PATCH x PATCH gray patch is sampled around it (bilinear, sub-pixel:
``cv2.remap``), mirrored so that every corner looks like a TL corner (window interior towards +x,
+y): TR flips x, BR both, BL y. The four patches go through :class:`RefineNet` in one forward pass:
a heatmap at half the patch resolution, soft-argmax (its expectation) = the corner, its spread
(square root of the heatmap's variance, px) = the uncertainty. ``iterations`` > 1 samples the
patches again around the last estimate (measured on the default detector's mask-fit quads of new
views of the training houses: no gain, p90 worse, so 1). A second input channel, the same corner
sampled twice as wide (80 px of context), measured worse on the validation views (corner error
median 1.08 px against 0.99 px, same training), so one scale. A corner keeps its input (``moved`` False) when the spread
exceeds ``max_spread_px`` or the move exceeds ``max_move_px``: a corner the net is unsure of stays
where the mask put it.

Scale: patches are sampled at the detector's working resolution (long side ``working_long_side``,
as pipeline.detectors' input size): a larger photo is first shrunk (``cv2.INTER_AREA``, only the
part around the quad) so a pixel of the patch is a pixel of what the net was trained on; renders
(640x480) are sampled at native resolution. Corners come back in the photo's pixels.

Weights: ``fenestra/pipeline/models/refine.pt`` (trained by ``fenestra train-refine``, fenestra/training/refine.py),
read with torch's restricted unpickler; a file of another kind, another patch size or layer shapes
is refused with a one-line FenestraError naming it.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from fenestra.errors import FenestraError
from fenestra.pipeline.snappers.base import Snapper, check_inputs, keep_if_far
from fenestra.pipeline.detectors.checkpoint import read_checkpoint

ARCH = "corner-refine"
PATCH = 40  # patch side (px at the working resolution); the heatmap is PATCH // 2
WIDTHS = (16, 24, 32)
SHIPPED = Path(__file__).resolve().parent.parent / "models" / "refine.pt"
# (sign x, sign y) per corner TL TR BR BL: the mirror that makes each corner a TL corner
FLIPS = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])


@dataclass(frozen=True)
class RefineParams:
    """weights: the weights file ("" = the shipped fenestra/pipeline/models/refine.pt); iterations: forward
    passes, each around the last estimate; max_spread_px: corners whose heatmap spread (px) is
    larger keep their input; max_move_px: corners moving further keep their input; min_contrast:
    corners whose patch has a smaller standard deviation (grey levels) keep theirs (nothing to see);
    working_long_side: photos with a longer side are sampled at this scale (the detector's)."""

    weights: str = ""
    iterations: int = 1
    max_spread_px: float = 2.0
    max_move_px: float = 6.0
    min_contrast: float = 3.0
    working_long_side: int = 1024


def build_net(widths: tuple[int, int, int] = WIDTHS):
    """The refinement CNN (untrained): (N, 1, PATCH, PATCH) normalised patches -> heatmap logits
    (N, PATCH/2, PATCH/2). A stride-2 and a stride-4 stage, a dilated convolution, the stride-4
    features upsampled and joined with the stride-2 ones (receptive field ~33 px)."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)
    from torch import nn  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    a, b, c = widths

    def conv(cin, cout, stride=1, dil=1):
        return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, dil, dilation=dil, bias=False),
                             nn.BatchNorm2d(cout), nn.ReLU(inplace=True))

    class RefineNet(nn.Module):
        def __init__(self):
            super().__init__()
            self.stem = conv(1, a)
            self.s2 = nn.Sequential(conv(a, b, 2), conv(b, b))
            self.s4 = nn.Sequential(conv(b, c, 2), conv(c, c, dil=2))
            self.fuse = conv(b + c, b)
            self.head = nn.Conv2d(b, 1, 1)

        def forward(self, x):
            f2 = self.s2(self.stem(x))
            f4 = nn.functional.interpolate(self.s4(f2), size=f2.shape[-2:], mode="bilinear", align_corners=False)
            return self.head(self.fuse(torch.cat([f2, f4], 1)))[:, 0]

    return RefineNet()


def heatmap(logits):
    """(N, h, w) heatmap logits -> (probabilities (N, h, w), cell centres x (w,), y (h,)) in patch
    pixels (heatmap cell i covers patch pixels 2i, 2i+1: its centre is 2i + 0.5)."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    n, h, w = logits.shape
    p = torch.softmax(logits.reshape(n, -1), 1).reshape(n, h, w)
    return p, torch.arange(w, dtype=p.dtype) * 2 + 0.5, torch.arange(h, dtype=p.dtype) * 2 + 0.5


def soft_argmax(logits):
    """(N, h, w) heatmap logits -> (N, 2) expected (x, y) and (N,) spread (px), in patch pixels
    (:func:`heatmap`)."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    p, xs, ys = heatmap(logits)
    px, py = p.sum(1), p.sum(2)  # marginals over x and y
    mx, my = px @ xs, py @ ys
    var = px @ xs ** 2 - mx ** 2 + py @ ys ** 2 - my ** 2
    return torch.stack([mx, my], 1), torch.sqrt(var.clamp_min(1e-6))


def normalise(patches: np.ndarray) -> np.ndarray:
    """(N, P, P) float patches -> zero mean, unit contrast per patch (std floored at 4 grey levels)."""
    m = patches.mean(axis=(1, 2), keepdims=True)
    s = patches.std(axis=(1, 2), keepdims=True)
    return ((patches - m) / np.maximum(s, 4.0)).astype(np.float32)


def sample_patches(g: np.ndarray, centres: np.ndarray, flips: np.ndarray, step: float = 1.0) -> np.ndarray:
    """(N, PATCH, PATCH) float32 patches of the float32 image g (H, W): patch pixel (j, i) is the
    image point centre + flip * step * ((j, i) - c), c = (PATCH - 1) / 2 (pixel centres at
    integers, bilinear, borders replicated); one cv2.remap for all N."""
    c = (PATCH - 1) / 2.0
    r = (np.arange(PATCH, dtype=np.float64) - c) * step
    mx = centres[:, 0, None, None] + flips[:, 0, None, None] * r[None, None, :]
    my = centres[:, 1, None, None] + flips[:, 1, None, None] * r[None, :, None]
    mx, my = np.broadcast_to(mx, (len(centres), PATCH, PATCH)), np.broadcast_to(my, (len(centres), PATCH, PATCH))
    out = cv2.remap(g, mx.reshape(-1, PATCH).astype(np.float32), my.reshape(-1, PATCH).astype(np.float32),
                    cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(len(centres), PATCH, PATCH)


def from_patch(centres: np.ndarray, flips: np.ndarray, uv: np.ndarray, step: float = 1.0) -> np.ndarray:
    """Patch coordinates uv (N, 2) -> image points (N, 2) (the inverse of :func:`sample_patches`' map)."""
    return centres + flips * step * (uv - (PATCH - 1) / 2.0)


def to_patch(centres: np.ndarray, flips: np.ndarray, xy: np.ndarray, step: float = 1.0) -> np.ndarray:
    """Image points xy (N, 2) -> patch coordinates (N, 2) of patches sampled at ``centres``."""
    return (xy - centres) * flips / step + (PATCH - 1) / 2.0


def predict(net, patches: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Patch coordinates (N, 2) and spreads (N,) px of the corner in each TL-mirrored patch (N, P, P)."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    with torch.inference_mode():
        uv, spread = soft_argmax(net(torch.from_numpy(normalise(patches))[:, None]))
    return uv.double().numpy(), spread.double().numpy()


def check_checkpoint(ckpt: dict, path: Path) -> dict:
    """``ckpt`` if it is a corner-refinement checkpoint of this PATCH whose tensors fit the net of
    its widths; FenestraError naming the file and what differs otherwise."""
    if ckpt.get("patch") != PATCH:
        raise FenestraError(f"{path}: corner-refinement weights for {ckpt.get('patch')!r} px patches, "
                            f"this version samples {PATCH} px")
    try:
        widths = tuple(int(w) for w in ckpt["widths"])
        want = {k: tuple(v.shape) for k, v in build_net(widths).state_dict().items()}
        got = {k: tuple(v.shape) for k, v in ckpt["state_dict"].items()}
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise FenestraError(f"{path}: not a corner-refinement weights file ({type(e).__name__}: {e})") from e
    if want != got:
        bad = sorted(set(want.items()) ^ set(got.items()))[:2]
        raise FenestraError(f"{path}: corner-refinement weights do not fit the net of widths {widths} "
                            f"(differ: {bad})")
    return ckpt


@functools.lru_cache(maxsize=4)
def load_refiner(path: str = ""):
    """The net of a weights file ("" = the shipped one), in eval mode on the CPU (cached: loads once)."""

    p = Path(path) if path else SHIPPED
    if not p.is_file():
        raise FenestraError(f"corner-refinement weights {p} not found (train them: fenestra train-refine)")
    ckpt = check_checkpoint(read_checkpoint(p, ARCH), p)
    net = build_net(tuple(ckpt["widths"]))
    net.load_state_dict(ckpt["state_dict"])
    return net.eval()


def working_view(g: np.ndarray, q: np.ndarray, long_side: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(image, origin (2,), step) in which to sample: g itself (origin 0, step 1) when its long side
    is at most ``long_side``, else the part around quad q shrunk by INTER_AREA to that scale; an
    image point x of g is (x - origin) / step in the returned image."""
    H, W = g.shape
    s = max(H, W) / float(long_side)
    if s <= 1.0:
        return g, np.zeros(2), 1.0
    m = PATCH * s
    x0, y0 = (int(max(np.floor(v - m), 0)) for v in q.min(axis=0))
    x1, y1 = int(min(np.ceil(q[:, 0].max() + m) + 1, W)), int(min(np.ceil(q[:, 1].max() + m) + 1, H))
    if x1 - x0 < 2 or y1 - y0 < 2:
        return g, np.zeros(2), 1.0
    dw, dh = max(int(round((x1 - x0) / s)), 1), max(int(round((y1 - y0) / s)), 1)
    small = cv2.resize(np.ascontiguousarray(g[y0:y1, x0:x1]), (dw, dh), interpolation=cv2.INTER_AREA)
    step = np.array([(x1 - x0) / dw, (y1 - y0) / dh])
    # pixel u of small covers [x0 - 0.5 + u * step, ...): its centre is x0 - 0.5 + (u + 0.5) * step
    origin = np.array([x0, y0]) - 0.5 + 0.5 * step
    return small, origin, step


def refine_corners(net, g: np.ndarray, q: np.ndarray, p: RefineParams) -> tuple[np.ndarray, np.ndarray]:
    """Refined corners (4, 2) px of g and their spreads (4,) px after ``p.iterations`` passes
    (spread inf where a patch has less than ``p.min_contrast``)."""
    img, origin, step = working_view(g, q, p.working_long_side)
    cur = (q - origin) / step
    spread = np.full(4, np.inf)
    for _ in range(max(p.iterations, 1)):
        patches = sample_patches(img, cur, FLIPS)
        uv, spread = predict(net, patches)
        spread = np.where(patches.std(axis=(1, 2)) >= p.min_contrast, spread, np.inf)
        cur = from_patch(cur, FLIPS, uv)
    return cur * step + origin, spread * float(np.max(step))


def snap_refine(gray: np.ndarray, quad: np.ndarray, params: RefineParams = RefineParams()) -> tuple[np.ndarray, dict]:
    """Move each corner to the CNN's sub-pixel estimate in a TL-mirrored patch around it, unless unsure."""
    g, q = check_inputs(gray, quad)
    if not np.isfinite(q).all():
        return q.copy(), {"moved": [False] * 4, "spread_px": [float("nan")] * 4}
    new, spread = refine_corners(load_refiner(params.weights), g, q, params)
    new = np.where((spread <= params.max_spread_px)[:, None], new, q)
    out, ok = keep_if_far(q, new, params.max_move_px)
    moved = [bool(o and s <= params.max_spread_px) for o, s in zip(ok, spread)]
    return out, {"moved": moved, "spread_px": [round(float(s), 3) for s in spread]}


# test_median_px: on tests/pipeline/test_pipeline_snappers.py's synthetic quads (flat polygons, noise sigma 2)
# it measures 0.79 px median (max 0.99) where the mask-fit start is already 0.02 px off: the net
# learned the renders' voids (reveal, frame, exterior-face corner) and places a bare polygon's corner
# ~0.4 px outwards. On renders of the training houses' new views it is unbiased (median offset
# < 0.1 px); the bench measures it on the unseen houses.
REFINE = Snapper("refine", snap_refine, RefineParams, test_median_px=0.9,
                 description="learned: a small CNN's sub-pixel corner in a patch around each corner (fenestra/pipeline/models/refine.pt)")
