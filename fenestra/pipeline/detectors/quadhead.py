"""The quad head: every window a quadrilateral straight from the network (detector v8).

CenterNet's objects-as-points on EffWin's decoder (fenestra/pipeline/detectors/effwin.py): at stride
:data:`QUAD_STRIDE` of the network's input, one **centre heatmap** (a Gaussian at each window's
centre, the mean of its four true corners) and, at every cell, a regression of the **four corners**
(TL, TR, BR, BL, image order) as offsets from the cell's centre in units of :data:`OFFSET_SCALE_PX`,
free to point outside the image (a window cut by the photo's edge keeps its whole quad). Each
regressed corner is then refined onto EffWin's corner heatmaps (the peak within a small radius,
sub-pixel by a parabola through the log probabilities), where a peak is there.

Adjacent windows are separate by construction: two windows are two centres, however thin the
frame between them. The void mask becomes support: a detection's mask is its quad, rasterised
inside the image.

Geometry: pixel centres at integers (fenestra.conventions); cell (i, j) of a stride-s map covers
input pixels [s j, s j + s - 1] and is centred at (s j + (s - 1) / 2, s i + (s - 1) / 2).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from fenestra.pipeline.types import Detection

QUAD_STRIDE = 4  # the head's output stride (px of the network's input per cell)
OFFSET_SCALE_PX = 16.0  # a regressed offset of 1.0 is this many px
N_QUAD_MAPS = 9  # centre logit, then (dx, dy) of TL, TR, BR, BL
MIRRORED_OFFSETS = (2, 3, 0, 1, 6, 7, 4, 5)  # corner offset channels of a mirrored image, in the image's order


def _conv(cin: int, cout: int, k: int = 3, dilation: int = 1) -> nn.Sequential:
    pad = dilation * (k // 2)
    return nn.Sequential(nn.Conv2d(cin, cout, k, 1, pad, dilation=dilation, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))


class QuadHead(nn.Module):
    """Decoder maps at strides 16, 8 and 4 (B, c16 / c8 / c4, ...) -> (B, 9, H/4, W/4): the centre
    logit and eight corner offsets. The coarse maps are upsampled to stride 4 and joined; three 3x3
    convolutions (dilation 1, 2, 4) give each cell the context of a whole window."""

    def __init__(self, c16: int, c8: int, c4: int, width: int = 32):
        super().__init__()
        self.reduce = _conv(c16 + c8 + c4, width, k=1)
        self.body = nn.Sequential(_conv(width, width), _conv(width, width, dilation=2), _conv(width, width, dilation=4))
        self.out = nn.Conv2d(width, N_QUAD_MAPS, 1)
        with torch.no_grad():  # centres are rare: start their logit low (focal-loss prior 0.01), offsets at 0
            self.out.bias.zero_()
            self.out.bias[0].fill_(-4.6)

    def forward(self, d16: torch.Tensor, d8: torch.Tensor, d4: torch.Tensor) -> torch.Tensor:
        size = d4.shape[-2:]
        up = [F.interpolate(d, size=size, mode="bilinear", align_corners=False) for d in (d16, d8)]
        return self.out(self.body(self.reduce(torch.cat([*up, d4], dim=1))))


def quad_mirror_mean(q: torch.Tensor) -> torch.Tensor:
    """(B, 9, h, w) centre probability and offsets: for each of B images, the mean of its maps q[i]
    and of its left-right mirror's, q[B + i], mirrored back (x offsets negated, TL/TR and BR/BL
    swapped). q: (2B, 9, h, w), the B images, then their mirrors."""
    B = q.shape[0] // 2
    back = torch.flip(q[B:], dims=[3])
    off = back[:, 1:][:, list(MIRRORED_OFFSETS)].clone()
    off[:, 0::2] = -off[:, 0::2]
    return 0.5 * (q[:B] + torch.cat([back[:, :1], off], dim=1))


# ------------------------------------------------------------------ training targets (pure numpy)

def cell_centres(n: int, stride: int = QUAD_STRIDE) -> np.ndarray:
    """(n,) float64: the px coordinate of the centres of n cells along one axis."""
    return stride * np.arange(n) + (stride - 1) / 2.0


@dataclass(frozen=True)
class QuadTargets:
    """Targets of the quad head for one crop of (H, W) px, at (h, w) = (H, W) / stride cells.

    centre: (h, w) float32 in [0, 1], the max over windows of a Gaussian at each centre;
    offsets: (8, h, w) float32, in units of OFFSET_SCALE_PX, valid where ``reg`` is 1;
    reg: (h, w) float32 0/1, the cells whose offsets are trained (the 3 x 3 cells nearest each
    centre; a cell near two centres belongs to the nearer); ignore: (h, w) float32 0/1, cells whose
    centre loss is not counted (inside a window too little of which is seen to place its centre).
    """

    centre: np.ndarray
    offsets: np.ndarray
    reg: np.ndarray
    ignore: np.ndarray


def quad_targets(quads: np.ndarray, seen_px: np.ndarray, shape: tuple[int, int], stride: int = QUAD_STRIDE,
                 min_seen_px: int = 24, min_seen_frac: float = 0.35) -> QuadTargets:
    """The quad head's targets for windows with whole quads (N, 4, 2) px (TL TR BR BL, corners may
    lie outside the crop) and seen_px (N,), the count of each window's pixels visible in the crop,
    in a crop of (H, W) = shape px (multiples of ``stride``).

    A window is a positive when at least ``min_seen_px`` of its pixels, and ``min_seen_frac`` of its
    quad's area inside the crop, are seen; its centre is the mean of its corners, or, if that lies
    outside the crop, the point of the crop nearest to it (a window cut by the crop's edge still
    gets its whole quad). Windows seen less are ignored (their quads' cells), never negatives.
    Gaussian sigma: max(0.7, min side / (8 stride)) cells.
    """
    H, W = shape
    h, w = H // stride, W // stride
    cx, cy = cell_centres(w, stride), cell_centres(h, stride)
    centre = np.zeros((h, w), np.float32)
    offsets = np.zeros((8, h, w), np.float32)
    reg = np.zeros((h, w), np.float32)
    ignore = np.zeros((h, w), np.float32)
    best = np.full((h, w), np.inf)
    crop = np.array([[-0.5, -0.5], [W - 0.5, -0.5], [W - 0.5, H - 0.5], [-0.5, H - 0.5]], np.float32)
    for q, seen in zip(np.asarray(quads, np.float64).reshape(-1, 4, 2), np.asarray(seen_px).reshape(-1)):
        if not np.all(np.isfinite(q)):
            continue
        inside, _ = cv2.intersectConvexConvex(crop, q.astype(np.float32))
        if inside <= 0:
            continue
        if seen < min_seen_px or seen < min_seen_frac * inside:
            cells = ((q - (stride - 1) / 2.0) / stride).astype(np.float32).reshape(-1, 1, 2)
            cv2.fillConvexPoly(ignore, np.round(cells).astype(np.int32), 1.0)
            continue
        c = np.clip(q.mean(axis=0), [0.0, 0.0], [W - 1.0, H - 1.0])
        sides = np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1)
        sigma = max(0.7, float(sides.min()) / (8 * stride))
        gx = np.exp(-((cx - c[0]) / stride) ** 2 / (2 * sigma ** 2))
        gy = np.exp(-((cy - c[1]) / stride) ** 2 / (2 * sigma ** 2))
        np.maximum(centre, np.outer(gy, gx).astype(np.float32), out=centre)
        j0, i0 = int(np.clip(round((c[0] - (stride - 1) / 2) / stride), 0, w - 1)), \
            int(np.clip(round((c[1] - (stride - 1) / 2) / stride), 0, h - 1))
        for i in range(max(0, i0 - 1), min(h, i0 + 2)):
            for j in range(max(0, j0 - 1), min(w, j0 + 2)):
                d = float(np.hypot(cx[j] - c[0], cy[i] - c[1]))
                if d < best[i, j]:
                    best[i, j] = d
                    offsets[:, i, j] = ((q - [cx[j], cy[i]]) / OFFSET_SCALE_PX).reshape(-1)
                    reg[i, j] = 1.0
        centre[i0, j0] = 1.0  # the peak itself is a positive even for an off-grid centre
    ignore[centre >= 0.5] = 0.0
    return QuadTargets(centre, offsets, reg, ignore)


# ------------------------------------------------------------------ decoding (pure numpy)

@dataclass(frozen=True)
class QuadDecode:
    """Turning the head's maps into quads (probabilities in [0, 1], distances in px).

    centre_threshold: the least centre probability of a window; max_windows: at most this many
    peaks, best first; refine_radius_frac, refine_radius_px: a regressed corner moves to the peak
    of its corner heatmap within max(refine_radius_px[0], min(refine_radius_px[1],
    refine_radius_frac x the quad's shortest side)) px, if that peak reaches ``refine_min_peak``;
    min_side_px: a quad with a shorter side is no window; dedupe_iou: of two quads whose boxes
    overlap more than this (IoU), or of which one holds the other's centre or shares more than
    10 % of the smaller's area, the lower-scored is dropped; score_scale: a detection's score is
    min(1, score_scale x its centre probability), so that the detectors' operating threshold 0.5
    falls where the validation data put the centre threshold (tools/quad_threshold.py); the
    ranking, and so AP, is the centre probability's.
    """

    centre_threshold: float = 0.1
    max_windows: int = 300
    refine_radius_frac: float = 0.5
    refine_radius_px: tuple[float, float] = (4.0, 40.0)
    refine_min_peak: float = 0.1
    min_side_px: float = 3.0
    dedupe_iou: float = 0.6
    score_scale: float = 3.333


def centre_peaks(centre: np.ndarray, threshold: float, max_n: int) -> list[tuple[int, int, float]]:
    """(i, j, probability) of the local maxima (3 x 3) of a centre map (h, w) at or above
    ``threshold``, best first, at most ``max_n``."""
    dil = cv2.dilate(centre.astype(np.float32), np.ones((3, 3), np.uint8))
    ii, jj = np.nonzero((centre >= dil) & (centre >= threshold))
    order = np.argsort(-centre[ii, jj], kind="stable")[:max_n]
    return [(int(ii[k]), int(jj[k]), float(centre[ii[k], jj[k]])) for k in order]


def _peak_offset(lm: float, l0: float, lp: float) -> float:
    """Sub-pixel offset in [-0.5, 0.5] of the vertex of the parabola through (-1, lm), (0, l0), (1, lp)."""
    den = lm - 2.0 * l0 + lp
    return float(np.clip(0.5 * (lm - lp) / den, -0.5, 0.5)) if den < 0 else 0.0


def subpixel_peak(heat: np.ndarray, py: int, px: int) -> np.ndarray:
    """(x, y) px of a heatmap's (H, W) peak at pixel (px, py), refined by a parabola through the log
    probabilities of the peak and its neighbours along x and along y (exact for a Gaussian peak)."""
    H, W = heat.shape
    lg = lambda yy, xx: float(np.log(np.clip(float(heat[yy, xx]), 1e-6, 1.0)))  # noqa: E731
    dx = _peak_offset(lg(py, px - 1), lg(py, px), lg(py, px + 1)) if 0 < px < W - 1 else 0.0
    dy = _peak_offset(lg(py - 1, px), lg(py, px), lg(py + 1, px)) if 0 < py < H - 1 else 0.0
    return np.array([px + dx, py + dy])


def refine_corner(heat: np.ndarray, p: np.ndarray, radius: float, min_peak: float) -> np.ndarray:
    """A corner p (2,) px moved to the sub-pixel peak of its heatmap (H, W) within ``radius`` px
    (a square window), or p itself where the peak is below ``min_peak`` or p lies outside."""
    H, W = heat.shape
    x, y = float(p[0]), float(p[1])
    if not (0 <= x <= W - 1 and 0 <= y <= H - 1):
        return p
    r = int(np.ceil(radius))
    x0, x1 = max(0, int(round(x)) - r), min(W, int(round(x)) + r + 1)
    y0, y1 = max(0, int(round(y)) - r), min(H, int(round(y)) + r + 1)
    sub = heat[y0:y1, x0:x1]
    iy, ix = np.unravel_index(int(np.argmax(sub)), sub.shape)
    if sub[iy, ix] < min_peak:
        return p
    return subpixel_peak(heat, iy + y0, ix + x0)


def _convex(q: np.ndarray) -> bool:
    e = np.roll(q, -1, axis=0) - q
    cross = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
    return bool(np.all(cross > 0))  # clockwise on screen (y down): TL TR BR BL


def quad_mask(quad: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, tuple[int, int], np.ndarray] | None:
    """(mask crop (h, w) bool, origin (x0, y0), box (4,) x0 y0 x1 y1 px on its pixel-edge outline)
    of the pixels of an (H, W) image whose centres lie inside a quad (4, 2) px; None when none do."""
    H, W = shape
    lo = np.clip(np.floor(quad.min(axis=0)).astype(int), 0, [W, H])
    hi = np.clip(np.ceil(quad.max(axis=0)).astype(int) + 1, 0, [W, H])
    if np.any(hi <= lo):
        return None
    (x0, y0), (x1, y1) = lo, hi
    crop = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillConvexPoly(crop, np.round((quad - [x0, y0]) * 16).astype(np.int32).reshape(-1, 1, 2), 1, shift=4)
    ys, xs = np.nonzero(crop)
    if xs.size == 0:
        return None
    box = np.array([xs.min() + x0 - 0.5, ys.min() + y0 - 0.5, xs.max() + x0 + 0.5, ys.max() + y0 + 0.5])
    return crop.astype(bool), (int(x0), int(y0)), box


def _box_iou(a: np.ndarray, b: np.ndarray) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def quad_detections(centre: np.ndarray, offsets: np.ndarray, corner_p: np.ndarray | None,
                    shape: tuple[int, int], decode: QuadDecode = QuadDecode(),
                    stride: int = QUAD_STRIDE) -> list[Detection]:
    """Detections (best first) from the head's maps of one image of (H, W) = shape px.

    centre: (h, w) probabilities; offsets: (8, h, w) in OFFSET_SCALE_PX units; corner_p: EffWin's
    corner heatmaps (4, H, W) (None: no refinement). Each detection's ``corners`` (4, 2) px are its
    whole quad (TL TR BR BL, possibly outside the image), ``mask`` the quad's pixels inside the image
    (a sparse crop at ``origin``), ``box`` that mask's, ``score`` the centre probability.
    """
    H, W = shape
    quads, scores = [], []
    for i, j, s in centre_peaks(centre, decode.centre_threshold, decode.max_windows):
        c = np.array([stride * j + (stride - 1) / 2.0, stride * i + (stride - 1) / 2.0])
        q = c + offsets[:, i, j].astype(np.float64).reshape(4, 2) * OFFSET_SCALE_PX
        sides = np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1)
        if corner_p is not None:
            r = float(np.clip(decode.refine_radius_frac * sides.min(), *decode.refine_radius_px))
            q = np.stack([refine_corner(corner_p[k], q[k], r, decode.refine_min_peak) for k in range(4)])
            sides = np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1)
        if sides.min() < decode.min_side_px or not _convex(q):
            continue
        quads.append(q)
        scores.append(min(1.0, decode.score_scale * s))
    out: list[Detection] = []
    for q, s in zip(quads, scores):
        m = quad_mask(q, (H, W))
        if m is None:
            continue
        mask, origin, box = m
        if any(_box_iou(box, d.box) > decode.dedupe_iou or _nested(q, d.corners) for d in out):
            continue
        out.append(Detection(mask, box, s, origin=origin, corners=q))
    return out


def _inside(p: np.ndarray, quad: np.ndarray) -> bool:
    """Does point p (2,) lie inside a convex quad (4, 2) (TL TR BR BL, clockwise on screen)?"""
    e = np.roll(quad, -1, axis=0) - quad
    d = p - quad
    return bool(np.all(e[:, 0] * d[:, 1] - e[:, 1] * d[:, 0] >= 0))


def _nested(a: np.ndarray, b: np.ndarray, max_overlap: float = 0.1) -> bool:
    """Two quads (4, 2) that are one window: the centre of either lies inside the other, or they
    share more than ``max_overlap`` of the smaller one's area. Two windows never overlap, so a
    second peak on a window, whose corners regress to a part of it, is dropped."""
    if _inside(a.mean(axis=0), b) or _inside(b.mean(axis=0), a):
        return True
    inter, _ = cv2.intersectConvexConvex(a.astype(np.float32), b.astype(np.float32))
    return inter > max_overlap * min(cv2.contourArea(a.astype(np.float32)), cv2.contourArea(b.astype(np.float32)))
