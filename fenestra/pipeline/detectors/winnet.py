"""WinNet: the CPU-fast default detector. A small U-Net predicting two maps per pixel:

- ``void``: is this pixel inside a window void?
- ``core``: is it inside a void *and* away from its outline (the void shrunk by a few pixels)?

Instances come from the core map: each connected core blob seeds one window, and every void pixel
joins its nearest seed. Cores of neighbouring windows stay apart even where the voids nearly touch.
The network runs at half resolution (stride-2 stem) and its logits are upsampled bilinearly, which
keeps a 640x480 view well under 150 ms on two CPU cores.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from scipy import ndimage
from torch import nn

from fenestra.pipeline.detectors.oracle import mask_box
from fenestra.pipeline.types import Detection

# Input normalisation (ImageNet statistics; any fixed values would do: trained from scratch).
MEAN = np.array([0.485, 0.456, 0.406], dtype=np.float32) * 255.0
STD = np.array([0.229, 0.224, 0.225], dtype=np.float32) * 255.0
STRIDE = 32  # inputs are padded to a multiple of this


def _block(cin: int, cout: int, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    """Two 3x3 conv-BN-ReLU layers; the first may stride, the second may dilate."""
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True),
        nn.Conv2d(cout, cout, 3, 1, dilation, dilation=dilation, bias=False), nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True))


@dataclass(frozen=True)
class WinNetConfig:
    """Architecture: channel widths per level (stride 2, 4, 8, 16, 32)."""

    widths: tuple[int, ...] = (16, 24, 48, 64, 96)


class WinNet(nn.Module):
    """U-Net: image (B, 3, H, W) normalised -> logits (B, 2, H, W) [void, core]; H, W % 32 == 0."""

    def __init__(self, config: WinNetConfig = WinNetConfig()):
        super().__init__()
        w = config.widths
        self.enc = nn.ModuleList([_block(3, w[0], 2)] + [_block(w[i - 1], w[i], 2, 2 if i >= 3 else 1)
                                                          for i in range(1, len(w))])
        self.dec = nn.ModuleList([_block(w[i + 1] + w[i], w[i]) for i in range(len(w) - 2, -1, -1)])
        self.head = nn.Conv2d(w[0], 2, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        size = x.shape[-2:]
        skips = []
        for layer in self.enc:
            x = layer(x)
            skips.append(x)
        x = skips.pop()
        for layer in self.dec:
            s = skips.pop()
            x = F.interpolate(x, size=s.shape[-2:], mode="bilinear", align_corners=False)
            x = layer(torch.cat([x, s], dim=1))
        return F.interpolate(self.head(x), size=size, mode="bilinear", align_corners=False)


def to_tensor(images: np.ndarray) -> torch.Tensor:
    """(B, H, W, 3) or (H, W, 3) uint8 RGB -> normalised float32 tensor (B, 3, H, W), contiguous."""
    a = np.ascontiguousarray(images)
    if a.ndim == 3:
        a = a[None]
    t = torch.from_numpy(a).permute(0, 3, 1, 2).float()
    t = (t - torch.from_numpy(MEAN).view(1, 3, 1, 1)) / torch.from_numpy(STD).view(1, 3, 1, 1)
    return t.contiguous()


def pad_to_stride(t: torch.Tensor, stride: int = STRIDE) -> tuple[torch.Tensor, int, int]:
    """Pad (B, C, H, W) bottom/right by reflection to multiples of stride; return it and H, W."""
    H, W = t.shape[-2:]
    ph, pw = (-H) % stride, (-W) % stride
    if ph or pw:
        t = F.pad(t, (0, pw, 0, ph), mode="replicate")
    return t, H, W


SEPARATIONS = ("nearest", "nearest-blob", "watershed")


@dataclass(frozen=True)
class PostConfig:
    """Turning probability maps into instances (probabilities in [0, 1], areas in px).

    separation: how void pixels join the seeds: ``nearest`` seed (Euclidean; a void blob without
    a seed of its own joins a neighbouring blob's seed: one instance of disconnected pieces, the
    former behaviour), ``nearest-blob`` (the nearest seed inside the pixel's own void
    blob; seedless blobs become their own instances), or ``watershed``: flooded from the seeds over
    1 - void probability, so two touching voids part where the void map dips (the frame or mullion
    between them), each within its own void blob.
    split_levels: increasing core thresholds above ``core_threshold``; a core blob that holds two
    or more blobs (each >= ``min_core_px``) at the next level is split into them, recursively
    (a component tree of the core map: neighbours whose cores merged at the base threshold);
    split_map: the map whose levels split (``core`` or ``void``); split_min_px: the least size of
    a sub-blob that counts.
    Empty: no splitting (the former detector).
    min_area_px, min_side_px: an instance with fewer pixels, or whose box is narrower or lower
    (network px), is dropped (0: no side limit; EffWin ships 4: a mullion strip left between two
    corner cuts is no window).
    corner_cuts: cut void blobs along the separators that corner heatmaps (EffWin's TL, TR, BR, BL)
    draw between neighbouring windows (:func:`separator_cuts`); needs the corner maps, ignored
    without them (WinNet). cut_min_peak: the least corner probability of a peak; cut_max_gap_px:
    the widest gap (px) between one window's corner and its neighbour's facing corner;
    cut_align_px: how far (px) the two corners of a pair, and the two ends of a separator, may be
    off the separator's line (plus ``cut_slope`` px per px of its length); cut_min_void_frac: the
    least share of a separator's length with void on both its sides (a separator runs between two
    windows, not across the wall between windows far apart); cut_min_dip: the least dip of the void or the core
    map along the separator below both its sides (:func:`separator_dip`: a frame between two
    windows dims the maps a little, a real window's own mullion or transom hardly);
    cut_min_height_frac: a horizontal separator is kept only when the void above and below it
    (:func:`void_extent`, from its midpoint) reaches at least this fraction of its length (a
    transom leaves a short top light above its sash: a real window's transom is not cut).
    mirror: EffWin only (ignored by WinNet, like the corner cuts): the maps are the mean of the
    network's maps of the image and of its left-right mirror, mirrored back (the TL/TR and BR/BL
    corner maps swapped); one more network pass, in the same batch.
    """

    void_threshold: float = 0.5
    core_threshold: float = 0.5
    min_area_px: int = 30
    min_side_px: int = 0  # an instance whose box is narrower or lower than this (network px) is dropped
    min_core_px: int = 4
    separation: str = "nearest"
    split_levels: tuple[float, ...] = ()
    split_map: str = "core"
    split_min_px: int = 4
    corner_cuts: bool = False
    cut_min_peak: float = 0.2
    cut_max_gap_px: float = 10.0
    cut_align_px: float = 4.0
    cut_slope: float = 0.25
    cut_min_void_frac: float = 0.0
    cut_min_dip: float = 0.0
    cut_min_height_frac: float = 0.0
    mirror: bool = False

    def __post_init__(self) -> None:
        if self.split_map not in ("core", "void"):
            raise ValueError(f"split_map must be 'core' or 'void', got {self.split_map!r}")
        if self.separation not in SEPARATIONS:
            raise ValueError(f"separation must be one of {SEPARATIONS}, got {self.separation!r}")
        levels = (self.core_threshold, *self.split_levels)
        if any(not b > a for a, b in zip(levels, levels[1:])) or not all(0.0 <= v <= 1.0 for v in levels):
            raise ValueError(f"split_levels must increase above core_threshold {self.core_threshold} "
                             f"within [0, 1], got {self.split_levels}")
        object.__setattr__(self, "split_levels", tuple(float(v) for v in self.split_levels))
        if not (0.0 < self.cut_min_peak <= 1.0 and self.cut_max_gap_px >= 1.0 and self.cut_align_px >= 0.0
                and self.cut_slope >= 0.0 and 0.0 <= self.cut_min_void_frac <= 1.0
                and -1.0 <= self.cut_min_dip <= 1.0 and self.cut_min_height_frac >= 0.0):
            raise ValueError(f"cut_min_peak must lie in (0, 1], cut_max_gap_px >= 1, cut_align_px and "
                             f"cut_slope >= 0, cut_min_void_frac in [0, 1], cut_min_dip in [-1, 1], "
                             f"cut_min_height_frac >= 0; got {self.cut_min_peak}, {self.cut_max_gap_px}, "
                             f"{self.cut_align_px}, {self.cut_slope}, {self.cut_min_void_frac}, {self.cut_min_dip}, "
                             f"{self.cut_min_height_frac}")


def core_targets(instances: np.ndarray, shrink_px: float = 3.0, shrink_frac: float = 0.15) -> np.ndarray:
    """Core map (H, W) bool: each instance shrunk by min(shrink_px, shrink_frac * its half-size).

    Shrinking by a fraction too keeps a core in thin windows; the distance is measured inside the
    instance (its own outline, including edges shared with neighbours, counts as outline).
    """
    inst = np.asarray(instances)
    core = np.zeros(inst.shape, dtype=bool)
    for k in np.unique(inst):
        if k == 0:
            continue
        m = inst == k
        ys, xs = np.nonzero(m)
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
        sub = np.pad(m[y0:y1, x0:x1], 1)
        d = ndimage.distance_transform_edt(sub)[1:-1, 1:-1]
        r = min(shrink_px, shrink_frac * 2.0 * d.max())  # d.max() ~ half the short side
        core[y0:y1, x0:x1] |= d > r
    return core


def split_seeds(prob: np.ndarray, base: np.ndarray, levels: tuple[float, ...], min_px: int,
                split_min_px: int) -> np.ndarray:
    """(H, W) int32 seed labels (0 = none): the connected components (4-connected) of ``base``
    (bool), each replaced by its sub-blobs at ``prob >= levels[0]`` when it holds two or more
    of at least ``split_min_px`` px, recursively over ``levels``; components under ``min_px`` dropped."""
    seeds = np.zeros(base.shape, dtype=np.int32)
    n_seeds = 0
    stack = [(base, 0)]
    while stack:
        region, depth = stack.pop()
        n, lab = cv2.connectedComponents(region.astype(np.uint8), connectivity=4)
        sizes = np.bincount(lab.ravel(), minlength=n)
        for k in range(1, n):
            if sizes[k] < min_px:
                continue
            blob = lab == k
            if depth < len(levels):
                sub = blob & (prob >= levels[depth])
                m, sl = cv2.connectedComponents(sub.astype(np.uint8), connectivity=4)
                if m > 2 and np.count_nonzero(np.bincount(sl.ravel(), minlength=m)[1:] >= split_min_px) >= 2:
                    stack.append((sub, depth + 1))
                    continue
                if m > 1:  # one blob at this level: look deeper inside it
                    stack.append((blob, depth + 1))
                    continue
            n_seeds += 1
            seeds[blob] = n_seeds
    return seeds


def corner_peaks(corner_p: np.ndarray, min_peak: float, radius: int = 2) -> list[np.ndarray]:
    """Per corner map of ``corner_p`` (4, H, W) in [0, 1]: its local maxima (over a (2 radius + 1)
    square) at or above ``min_peak``, as (N, 2) float px (x, y; pixel centres at integers)."""
    kernel = np.ones((2 * radius + 1, 2 * radius + 1), np.uint8)
    out = []
    for c in np.asarray(corner_p, dtype=np.float32):
        ys, xs = np.nonzero((c >= min_peak) & (c >= cv2.dilate(c, kernel)))
        out.append(np.stack([xs, ys], axis=1).astype(np.float64))
    return out


def facing_pairs(ends: np.ndarray, starts: np.ndarray, axis: int, max_gap: float, align: float) -> np.ndarray:
    """Midpoints (M, 2) px of the pairs (one window's corner in ``ends``, its neighbour's facing corner
    in ``starts``, each (N, 2) px) with 1 <= start - end <= ``max_gap`` along ``axis`` (0: x, 1: y)
    and at most ``align`` apart across it; each end takes its nearest start."""
    if len(ends) == 0 or len(starts) == 0:
        return np.zeros((0, 2))
    d = starts[None, :, axis] - ends[:, None, axis]
    ok = (d >= 1.0) & (d <= max_gap) & (np.abs(starts[None, :, 1 - axis] - ends[:, None, 1 - axis]) <= align)
    i, = np.nonzero(ok.any(axis=1))
    j = np.argmin(np.where(ok, d, np.inf), axis=1)[i]
    return 0.5 * (ends[i] + starts[j])


def separator_segments(first: np.ndarray, last: np.ndarray, axis: int, align: float, slope: float,
                       min_len: float = 8.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """Separators running along ``axis`` (1: a vertical one, from its top pair to its bottom pair; 0:
    a horizontal one, left to right): each pair midpoint of ``first`` (M, 2) px joined to the nearest
    midpoint of ``last`` at least ``min_len`` px further along ``axis`` and within ``align`` +
    ``slope`` x length across it. (start, end) px each."""
    out = []
    for p in first:
        along = last[:, axis] - p[axis]
        ok = (along >= min_len) & (np.abs(last[:, 1 - axis] - p[1 - axis]) <= align + slope * along)
        if ok.any():
            out.append((p, last[int(np.argmin(np.where(ok, along, np.inf)))]))
    return out


def line_pixels(p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) int of the pixels on the segment p -> q (px, x y), one per px of its length."""
    n = int(np.ceil(np.linalg.norm(q - p))) + 1
    pts = np.round(p + (q - p) * np.linspace(0.0, 1.0, n)[:, None]).astype(int)
    return pts[:, 1], pts[:, 0]


def separator_profiles(prob: np.ndarray, p: np.ndarray, q: np.ndarray, inner_px: int = 1,
                       side_px: tuple[int, ...] = (3, 4)) -> tuple[np.ndarray, np.ndarray]:
    """(centre, sides), each (N,) over the segment p -> q (px) of the probability map ``prob``
    (H, W): the centre is the least value within ``inner_px`` across the segment, ``sides`` the
    lesser of its two sides, each side the largest value at ``side_px`` px from it."""
    H, W = prob.shape
    u = (q - p) / np.linalg.norm(q - p)
    n = np.array([-u[1], u[0]])

    def profile(off: float) -> np.ndarray:
        r, c = line_pixels(p + off * n, q + off * n)
        return prob[np.clip(r, 0, H - 1), np.clip(c, 0, W - 1)]

    centre = np.min([profile(o) for o in range(-inner_px, inner_px + 1)], axis=0)
    left = np.max([profile(-o) for o in side_px], axis=0)
    right = np.max([profile(o) for o in side_px], axis=0)
    return centre, np.minimum(left, right)


def separator_dip(prob: np.ndarray, p: np.ndarray, q: np.ndarray) -> float:
    """How far ``prob`` (H, W) dips along the segment p -> q below both its sides: the median of
    sides - centre (:func:`separator_profiles`; positive: a valley, as the frame between two
    windows draws)."""
    centre, sides = separator_profiles(prob, p, q)
    return float(np.median(sides - centre))


def separator_cuts(corner_p: np.ndarray, post: PostConfig, void_p: np.ndarray | None = None,
                   core_p: np.ndarray | None = None, extend_px: float = 3.0) -> np.ndarray:
    """(H, W) bool: lines (8-connected, 1 px) between neighbouring windows, found on the corner
    heatmaps ``corner_p`` (4, H, W) [TL, TR, BR, BL] in [0, 1]; with the void and core probability
    maps (H, W), only those with void on both sides along at least ``post.cut_min_void_frac`` of
    their length and a dip of at least ``post.cut_min_dip`` in either map (:func:`separator_dip`).

    Two windows side by side show a top pair (the left one's TR, the right one's TL, a few px apart)
    and a bottom pair (BR, BL) below it; two stacked windows a left pair (the upper one's BL, the
    lower one's TL) and a right pair (BR, TR). The line joins the two pairs' midpoints, extended by
    ``extend_px`` at both ends so that it crosses the void blob's outline. On real photos the corner
    head also fires at a window's own transoms and mullions (it was trained on renders only); the
    gates of :func:`_separator_holds` keep those whole (real validation AP).
    """
    tl, tr, br, bl = corner_peaks(corner_p, post.cut_min_peak)
    g, a = post.cut_max_gap_px, post.cut_align_px
    segments = (separator_segments(facing_pairs(tr, tl, 0, g, a), facing_pairs(br, bl, 0, g, a), 1, a, post.cut_slope)
                + separator_segments(facing_pairs(bl, tl, 1, g, a), facing_pairs(br, tr, 1, g, a), 0, a,
                                     post.cut_slope))
    cut = np.zeros(corner_p.shape[1:], dtype=np.uint8)
    for p, q in segments:
        if void_p is not None and not _separator_holds(void_p, core_p, p, q, post):
            continue
        u = (q - p) / np.linalg.norm(q - p)
        p0, p1 = np.round(p - extend_px * u).astype(int), np.round(q + extend_px * u).astype(int)
        cv2.line(cut, (int(p0[0]), int(p0[1])), (int(p1[0]), int(p1[1])), 1, 1, lineType=cv2.LINE_8)
    return cut.astype(bool)


def void_extent(void: np.ndarray, start: np.ndarray, direction: np.ndarray, skip_px: int = 6) -> int:
    """Px from ``start`` (x, y) along the unit ``direction`` to the first pixel off the void mask
    ``void`` (H, W) bool or off the image, the first ``skip_px`` px (the gap between two windows)
    not looked at."""
    H, W = void.shape
    d = skip_px
    while True:
        x, y = np.round(start + (d + 1) * direction).astype(int)
        if not (0 <= x < W and 0 <= y < H and void[y, x]):
            return d
        d += 1


def _separator_holds(void_p: np.ndarray, core_p: np.ndarray, p: np.ndarray, q: np.ndarray, post: PostConfig) -> bool:
    """The separator p -> q runs inside a void blob (``post.cut_min_void_frac``) along a valley of
    the void or the core map (``post.cut_min_dip``) and, if horizontal, leaves parts tall enough
    (``post.cut_min_height_frac``)."""
    if (separator_profiles(void_p, p, q)[1] >= post.void_threshold).mean() < post.cut_min_void_frac:
        return False
    length = float(np.linalg.norm(q - p))
    if post.cut_min_height_frac > 0.0 and abs(q[0] - p[0]) > abs(q[1] - p[1]):
        void, mid = void_p >= post.void_threshold, 0.5 * (p + q)
        if min(void_extent(void, mid, np.array([0.0, -1.0])), void_extent(void, mid, np.array([0.0, 1.0]))) \
                < post.cut_min_height_frac * length:
            return False
    return post.cut_min_dip <= 0.0 or max(separator_dip(void_p, p, q), separator_dip(core_p, p, q)) >= post.cut_min_dip


def _join_nearest(void: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    if seeds.max() == 0:
        return np.zeros(void.shape, dtype=np.int32)
    _, (iy, ix) = ndimage.distance_transform_edt(seeds == 0, return_indices=True)
    return np.where(void, seeds[iy, ix], 0)


def _fill_nearest(labels: np.ndarray, fill: np.ndarray, margin_px: int = 8) -> np.ndarray:
    """``labels`` (H, W) int with the ``fill`` (H, W) bool pixels given their nearest label within
    ``margin_px`` of the pixels' bounding box (0 where none is)."""
    if not fill.any() or not labels.any():
        return labels
    ys, xs = np.nonzero(fill)
    y0, x0 = max(0, ys.min() - margin_px), max(0, xs.min() - margin_px)
    y1, x1 = ys.max() + margin_px + 1, xs.max() + margin_px + 1
    out = labels.copy()
    crop = out[y0:y1, x0:x1]
    crop[fill[y0:y1, x0:x1]] = _join_nearest(np.ones(crop.shape, bool), crop)[fill[y0:y1, x0:x1]]
    return out


def _own_blob(void: np.ndarray, seeds: np.ndarray, flooded: np.ndarray) -> np.ndarray:
    """``flooded`` (a seed label per pixel) kept where the pixel is void and in its seed's void blob."""
    _, blobs = cv2.connectedComponents(void.astype(np.uint8), connectivity=4)
    seed_blob = np.zeros(seeds.max() + 1, dtype=np.int32)
    seed_blob[seeds[seeds > 0]] = blobs[seeds > 0]  # a seed lies inside one void blob
    return np.where(void & (blobs == seed_blob[flooded]) & (flooded > 0), flooded, 0).astype(np.int32)


def _join_watershed(void: np.ndarray, void_p: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """Seeds flooded over 1 - void probability, kept inside the void blob that holds the seed."""
    if seeds.max() == 0:
        return np.zeros(void.shape, dtype=np.int32)
    height = np.round(255.0 * (1.0 - np.clip(void_p, 0.0, 1.0))).astype(np.uint8)
    return _own_blob(void, seeds, ndimage.watershed_ift(height, seeds))


def instances_from_maps(void_p: np.ndarray, core_p: np.ndarray, post: PostConfig = PostConfig(),
                        corner_p: np.ndarray | None = None) -> list[Detection]:
    """Instances from void/core probability maps (H, W) in [0, 1]; sorted by score, best first.

    With ``post.corner_cuts`` and corner heatmaps ``corner_p`` (4, H, W) [TL, TR, BR, BL], the void
    map is first cut along the separators between neighbouring windows (:func:`separator_cuts`);
    the cut's own void pixels join the nearest instance at the end.
    Seeds = connected components of (core & void), split where a blob holds several blobs at the
    higher ``post.split_levels``; every void pixel joins a seed (``post.separation``: the nearest,
    or by watershed on the void map); void blobs without any seed become their own instance.
    Score = mean void probability over the mask times the peak core probability.
    """
    whole = void_p >= post.void_threshold
    cut = separator_cuts(corner_p, post, void_p, core_p) if post.corner_cuts and corner_p is not None else None
    void = whole if cut is None else whole & ~cut
    base = (core_p >= post.core_threshold) & void
    seeds = split_seeds(void_p if post.split_map == "void" else core_p, base, post.split_levels,
                        post.min_core_px, post.split_min_px)
    if post.separation == "watershed":
        labels = _join_watershed(void, void_p, seeds)
    elif post.separation == "nearest-blob":
        labels = _own_blob(void, seeds, _join_nearest(np.ones_like(void), seeds))
    else:
        labels = _join_nearest(void, seeds)
    if cut is not None:  # the cut's void pixels join their nearest instance
        labels = _fill_nearest(labels, whole & cut & (labels == 0))
    # Void blobs that no seed reached get their own label.
    n_blobs, blobs = cv2.connectedComponents((void & (labels == 0)).astype(np.uint8), connectivity=4)
    nxt = labels.max() + 1
    labels = np.where(blobs > 0, blobs + nxt - 1, labels)
    dets = []
    for k in np.unique(labels):
        if k == 0:
            continue
        m = labels == k
        area = int(m.sum())
        if area < post.min_area_px:
            continue
        box = mask_box(m)
        if min(box[2] - box[0], box[3] - box[1]) < post.min_side_px:
            continue
        score = float(void_p[m].mean() * core_p[m].max())
        dets.append(Detection(mask=m, box=box, score=score))
    dets.sort(key=lambda d: -d.score)
    return dets


@torch.no_grad()
def predict_maps(model: WinNet, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Void and core probability maps (H, W) float32 for one RGB image (H, W, 3) uint8."""
    model.eval()
    x, H, W = pad_to_stride(to_tensor(image))
    x = x.to(next(model.parameters()).device).contiguous(memory_format=torch.channels_last)
    p = torch.sigmoid(model(x).float())[0, :, :H, :W].cpu().numpy()
    return p[0], p[1]


# ---------------------------------------------------------------- from a weights file (the registry's Checkpointed)

def model_from_checkpoint(ckpt: dict) -> WinNet:
    """The WinNet of a weights file's dict (``widths``, ``state_dict``), in eval mode on the CPU."""
    return load_state(WinNet(WinNetConfig(tuple(ckpt["widths"]))), ckpt)


def load_state(model: nn.Module, ckpt: dict) -> nn.Module:
    """``model`` with the checkpoint's weights (fp16 stored, fp32 used), channels-last (faster
    convolutions on the CPU, oneDNN), in eval mode."""
    model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in ckpt["state_dict"].items()})
    model.to(memory_format=torch.channels_last)
    return model.eval()


def post_from_checkpoint(ckpt: dict, defaults: dict | None = None) -> PostConfig:
    """The PostConfig of a weights file: its ``post`` dict over the architecture's ``defaults``
    over PostConfig's own (a file written before a field existed gets the architecture's choice)."""
    return PostConfig(**{**(defaults or {}), **ckpt.get("post", {})})


def post_config(ckpt: dict) -> PostConfig:
    """A WinNet weights file's post-processing (PostConfig's defaults under the file's own)."""
    return post_from_checkpoint(ckpt)


def detector_from_model(model: WinNet, ckpt: dict):
    """image (H, W, 3) uint8 RGB -> Detections, with the checkpoint's post-processing (PostConfig)."""
    post = post_config(ckpt)
    return lambda image, **_: instances_from_maps(*predict_maps(model, image), post)


def void_core_maps(model: WinNet):
    """image -> (void, core) probability maps (H, W) float32 (post-processing tuning: lab/tune.py)."""
    return lambda image: predict_maps(model, image)
