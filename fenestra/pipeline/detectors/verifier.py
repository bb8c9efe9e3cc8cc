"""The box verifier: a logistic head on the detector's own features that tells a window from a
door or a signboard, applied in EffWin's post-processing.

For each detection, the network's feature maps are averaged inside its box and inside the box
grown by ``context`` (:func:`roi_align`: torchvision's RoIAlign in pure torch), beside a few
numbers about the box (aspect, position and size in the image, score, void/core evidence:
:func:`geometry_features`). A logistic regression on these (``VerifierHead``; fitted by
fenestra/training/verifier.py on the real train photos' doors and signboards) gives p(window); a detection
below the head's ``threshold`` is no window: a door when its box stands upright, else a signboard
(:func:`classified` sets ``Detection.kind``; pipeline.detectors.detect returns the kinds asked for).

The head ships inside the weights file (key ``"verifier"``, :func:`head_to_dict`), checked on
load (:func:`head_from_dict`: FenestraError naming what is wrong). It records the fingerprint of
the network it was fitted on (:func:`network_fingerprint`, the sha256 of the weights), and is refused
beside any other network: the features it reads are that network's. A weights file without the key
runs without a verifier.

    head = head_from_dict(ckpt["verifier"], where="fenestra/pipeline/models/default.pt")
    keep = head.window_probability(box_features(feats, boxes, shape, extras, head.spec)) >= head.threshold
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace

import numpy as np

from fenestra.errors import FenestraError

N_GEOMETRY = 10  # columns of geometry_features
VERSION = 1
DOOR_MIN_ASPECT = 1.0  # a no-window box at least as tall as wide is a door (not_window_kind; from spb train labels)


@dataclass(frozen=True)
class FeatureSpec:
    """Which feature maps are pooled (names of EffWin.forward_features, with their strides) and the
    context box: the detection's box grown by ``context`` times its size on every side (0: none)."""

    layers: tuple[str, ...]
    strides: tuple[int, ...]
    context: float = 1.0

    def __post_init__(self) -> None:
        if not self.layers or len(self.layers) != len(self.strides):
            raise ValueError(f"FeatureSpec needs one stride per layer, got {self.layers} and {self.strides}")
        if not 0.0 <= self.context <= 4.0:
            raise ValueError(f"FeatureSpec.context must be in [0, 4], got {self.context}")


@dataclass(frozen=True)
class VerifierHead:
    """p(window) = sigmoid(((x - mean) / std) . weight + bias) of box features x (D,); detections
    with p < threshold are dropped."""

    spec: FeatureSpec
    mean: np.ndarray
    std: np.ndarray
    weight: np.ndarray
    bias: float
    threshold: float

    def window_probability(self, x: np.ndarray) -> np.ndarray:
        """(N,) p(window) of box features (N, D)."""
        z = (np.asarray(x, np.float64) - self.mean) / self.std @ self.weight + self.bias
        return 1.0 / (1.0 + np.exp(-np.clip(z, -50.0, 50.0)))


def geometry_features(boxes: np.ndarray, shape: tuple[int, int], extras: np.ndarray) -> np.ndarray:
    """(N, N_GEOMETRY) per box (x0 y0 x1 y1 px, image (H, W)): log aspect h / w, top, bottom,
    left, right (fractions of the image), log of height and width over the image's, distance of
    the bottom to the image's bottom edge over the box height (clipped to 4), and ``extras``
    (N, 2): the detection's score and its mean void probability."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    H, W = shape
    w, h = np.maximum(b[:, 2] - b[:, 0], 1.0), np.maximum(b[:, 3] - b[:, 1], 1.0)
    cols = [np.log(h / w), b[:, 1] / H, b[:, 3] / H, b[:, 0] / W, b[:, 2] / W, np.log(h / H), np.log(w / W),
            np.clip((H - b[:, 3]) / h, 0.0, 4.0)]
    return np.concatenate([np.stack(cols, axis=1), np.asarray(extras, np.float64).reshape(-1, 2)], axis=1)


def _context_boxes(b: np.ndarray, shape: tuple[int, int], grow: float) -> np.ndarray:
    H, W = shape
    w, h = (b[:, 2] - b[:, 0])[:, None], (b[:, 3] - b[:, 1])[:, None]
    g = b + np.concatenate([-w, -h, w, h], axis=1) * grow
    return np.clip(g, [-0.5, -0.5, -0.5, -0.5], [W - 0.5, H - 0.5, W - 0.5, H - 0.5])


def _axis_taps(t, size: int):
    """Bilinear taps along one axis of length ``size`` at sample coordinates ``t`` (any shape):
    (low index, high index, low weight, high weight), both weights 0 where t < -1 or t > size
    (RoIAlign's out-of-map samples); t is clamped to 0 below and to the last index above."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    inside = (t >= -1.0) & (t <= size)
    t = t.clamp(min=0.0)
    low = t.floor().long()  # t >= 0: floor is the C++ int cast
    last = low >= size - 1
    low = torch.where(last, torch.full_like(low, size - 1), low)
    t = torch.where(last, low.to(t.dtype), t)
    high = torch.where(last, low, low + 1)
    frac = t - low.to(t.dtype)
    zero = torch.zeros_like(t)
    return low, high, torch.where(inside, 1.0 - frac, zero), torch.where(inside, frac, zero)


def roi_align(f, boxes: np.ndarray, scale: float, bins: int = 2, samples: int = 2):
    """(N, C, bins, bins) RoIAlign of (1, C, h, w) feature map ``f`` over N boxes (x0 y0 x1 y1 in
    input pixels, continuous, times ``scale`` to reach the map): torchvision.ops.roi_align(f, rois,
    (bins, bins), scale, sampling_ratio=samples, aligned=True) on the CPU, without importing
    torchvision.ops (its import pulls in torch._dynamo: seconds per process). Each bin is the mean
    of samples x samples bilinear samples at its sub-cell centres; the box is shifted by half a map
    pixel; samples more than one pixel off the map count as 0, the others are clamped to it.
    One sparse-as-dense pooling matrix times the map: memory N * bins**2 * h * w (the verifier's
    stride-32 and -64 maps are small); about as fast as torchvision's kernel there."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    _, C, H, W = f.shape
    dt, dev = f.dtype, f.device
    b = torch.as_tensor(np.asarray(boxes, np.float64).reshape(-1, 4), device=dev).to(dt)
    start = b * torch.tensor(scale, dtype=dt, device=dev) - 0.5  # in torchvision's order of float operations
    size = (start[:, 2:] - start[:, :2]) / bins  # (N, 2) bin width, height
    cell = torch.arange(bins, dtype=dt, device=dev).repeat_interleave(samples)  # bin of each sample, ...
    sub = (torch.arange(samples, dtype=dt, device=dev) + 0.5).repeat(bins)  # ... and its offset in the bin
    ys = (start[:, 1:2] + cell * size[:, 1:2]) + sub * size[:, 1:2] / samples  # (N, bins * samples)
    xs = (start[:, 0:1] + cell * size[:, 0:1]) + sub * size[:, 0:1] / samples
    y0, y1, wy0, wy1 = _axis_taps(ys, H)
    x0, x1, wx0, wx1 = _axis_taps(xs, W)
    # the pooling as one (N * bins * bins, h * w) matrix: row (box, bin y, bin x), column a map
    # pixel, entry the bilinear weights of the bin's samples on that pixel, summed
    n, k = ys.shape
    binof = torch.arange(k, device=dev) // samples  # bin of each sample along an axis
    rows = (torch.arange(n, device=dev)[:, None, None] * bins + binof[None, :, None]) * bins + binof[None, None, :]
    pool = torch.zeros(n * bins * bins * H * W, dtype=dt, device=dev)
    for yi, wy in ((y0, wy0), (y1, wy1)):
        for xi, wx in ((x0, wx0), (x1, wx1)):
            col = yi[:, :, None] * W + xi[:, None, :]
            pool.index_add_(0, (rows * (H * W) + col).reshape(-1), (wy[:, :, None] * wx[:, None, :]).reshape(-1))
    pooled = pool.reshape(n * bins * bins, H * W) @ f.reshape(C, H * W).t() / (samples * samples)
    return pooled.reshape(n, bins, bins, C).permute(0, 3, 1, 2).contiguous()


def box_features(feats: dict, boxes: np.ndarray, shape: tuple[int, int], extras: np.ndarray,
                 spec: FeatureSpec) -> np.ndarray:
    """(N, D) features of N boxes (x0 y0 x1 y1 px, pixel-edge outline) on an image of ``shape``:
    per layer of ``spec`` the mean feature inside the box (and inside its context box), then
    :func:`geometry_features`. feats: name -> (1, C, h, w) torch tensors (the padded input's)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    if not len(b):
        return np.zeros((0, feature_dim(feats, spec)), np.float64)
    edges = b + 0.5  # pixel-edge outline -> continuous coordinates with pixel i over [i, i + 1)
    sets = [edges] + ([_context_boxes(b, shape, spec.context) + 0.5] if spec.context > 0 else [])
    cols = []
    for name, stride in zip(spec.layers, spec.strides):
        for s in sets:
            pooled = roi_align(feats[name], s, 1.0 / stride)
            cols.append(pooled.mean(dim=(2, 3)).double().numpy())
    cols.append(geometry_features(b, shape, extras))
    return np.concatenate(cols, axis=1)


def feature_dim(feats: dict, spec: FeatureSpec) -> int:
    """D of :func:`box_features` for these feature maps."""
    per_set = 2 if spec.context > 0 else 1
    return sum(int(feats[n].shape[1]) for n in spec.layers) * per_set + N_GEOMETRY


def detection_extras(dets: list, void_p: np.ndarray) -> np.ndarray:
    """(N, 2) per detection (full masks on the void map's image, or crops at their origin): its
    score and the mean void probability over its mask (the non-feature inputs of :func:`geometry_features`)."""
    def mean_void(d) -> float:
        m = np.asarray(d.mask, bool)
        (x0, y0), (h, w) = d.origin, m.shape
        sub = void_p[y0:y0 + h, x0:x0 + w]
        return float(sub[m[:sub.shape[0], :sub.shape[1]]].mean()) if m.any() else 0.0
    return np.array([[d.score, mean_void(d)] for d in dets], np.float64).reshape(-1, 2)


def not_window_kind(box: np.ndarray, min_aspect: float = DOOR_MIN_ASPECT) -> str:
    """What a detection the verifier calls no window is, from its box (4,) x0 y0 x1 y1 px: a door
    when it stands at least ``min_aspect`` times as tall as it is wide, else a signboard (the
    labelled doors of the train photos stand upright, their signboards lie flat)."""
    x0, y0, x1, y1 = np.asarray(box, np.float64).reshape(4)
    return "door" if (y1 - y0) >= min_aspect * max(x1 - x0, 1.0) else "signboard"


def classified(dets: list, void_p: np.ndarray, feats: dict, head: VerifierHead) -> list:
    """The detections (full masks on the image of ``void_p``, (H, W)), each with its ``kind``: a
    window where ``head``'s p(window) reaches its threshold, else a door or a signboard
    (:func:`not_window_kind`); order kept, none dropped."""
    if not dets:
        return dets
    boxes = np.stack([np.asarray(d.box, np.float64) for d in dets])
    p = head.window_probability(box_features(feats, boxes, void_p.shape, detection_extras(dets, void_p), head.spec))
    return [d if q >= head.threshold else replace(d, kind=not_window_kind(d.box)) for d, q in zip(dets, p)]


# ---------------------------------------------------------------- in a weights file

def network_fingerprint(state_dict: dict) -> str:
    """sha256 (hex) of a network's weights (name -> torch tensor): every tensor's name, dtype, shape
    and bytes, in name order. The verifier records the one of the network it was fitted on."""
    h = hashlib.sha256()
    for name in sorted(state_dict):
        t = state_dict[name].detach().cpu().contiguous()
        h.update(f"{name}|{t.dtype}|{tuple(t.shape)}|".encode())
        h.update(_tensor_bytes(t))
    return h.hexdigest()


def _tensor_bytes(t) -> bytes:
    """The raw bytes of a contiguous CPU tensor of any dtype (bfloat16 included)."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    return t.reshape(-1).view(torch.uint8).numpy().tobytes()


def head_to_dict(head: VerifierHead, network: str, meta: dict | None = None) -> dict:
    """The weights file's ``"verifier"`` entry (plain lists and numbers: torch.load's safe loader
    reads it); network: the :func:`network_fingerprint` of the network it was fitted on."""
    return {"version": VERSION, "network_sha256": str(network), "layers": list(head.spec.layers), "strides": list(head.spec.strides),
            "context": float(head.spec.context), "mean": [float(v) for v in head.mean],
            "std": [float(v) for v in head.std], "weight": [float(v) for v in head.weight],
            "bias": float(head.bias), "threshold": float(head.threshold), "meta": dict(meta or {})}


def head_from_dict(d: object, where: str = "", channels: dict[str, int] | None = None,
                   network: str | None = None) -> VerifierHead:
    """The VerifierHead of a weights file's ``"verifier"`` entry, checked: version, the fingerprint
    of the network it was fitted on (equal to ``network``, when given), layer names (among
    ``channels``, name -> C, when given), vector lengths (D = the features those layers give),
    finite numbers, std > 0, threshold in [0, 1]. FenestraError naming ``where`` (the file, when
    known) and the bad field otherwise."""
    def bad(what: str) -> FenestraError:
        return FenestraError(f"{where + ': ' if where else ''}its box verifier is unusable: {what}; retrain it "
                             "with `fenestra train-verifier` (a step of `make train`)")

    if not isinstance(d, dict):
        raise bad(f"a {type(d).__name__}, not a dict")
    if d.get("version") != VERSION:
        raise bad(f"version {d.get('version')!r}, expected {VERSION}")
    if network is not None and d.get("network_sha256") != network:
        raise bad(f"it was fitted on network {str(d.get('network_sha256'))[:12]!r}, this file's network is "
                  f"{network[:12]!r}")
    try:
        spec = FeatureSpec(tuple(str(n) for n in d["layers"]), tuple(int(s) for s in d["strides"]), float(d["context"]))
        vecs = {k: np.asarray(d[k], dtype=np.float64) for k in ("mean", "std", "weight")}
        bias, threshold = float(d["bias"]), float(d["threshold"])
    except KeyError as e:
        raise bad(f"no {e.args[0]!r}") from None
    except (TypeError, ValueError) as e:
        raise bad(" ".join(str(e).split())[:120]) from None
    if channels is not None:
        unknown = [n for n in spec.layers if n not in channels]
        if unknown:
            raise bad(f"unknown feature layers {unknown} (the network has {sorted(channels)})")
        dim = sum(channels[n] for n in spec.layers) * (2 if spec.context > 0 else 1) + N_GEOMETRY
    else:
        dim = len(vecs["weight"])
    for k, v in vecs.items():
        if v.shape != (dim,):
            raise bad(f"{k} has shape {v.shape}, expected ({dim},)")
        if not np.isfinite(v).all():
            raise bad(f"{k} is not finite")
    if not (vecs["std"] > 0).all():
        raise bad("std has values <= 0")
    if not (np.isfinite(bias) and 0.0 <= threshold <= 1.0):
        raise bad(f"bias {bias} / threshold {threshold} (must be finite / in [0, 1])")
    return VerifierHead(spec, vecs["mean"], vecs["std"], vecs["weight"], bias, threshold)
