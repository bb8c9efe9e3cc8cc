"""Oracle detectors: exact masks from an instance map, and a degraded copy imitating a network.

:func:`detections_from_instance_map` is the one instance map -> detections helper (the ``oracle``
detector and ``fenestra reconstruct --masks``). Boxes follow fenestra.masks: (x0, y0, x1, y1) on the
pixel-edge outline, pixel centres at integers (:func:`fenestra.masks.mask_box`).

``oracle`` isolates the downstream stages from detection errors; ``oracle-degraded`` gives them the
kind of mask a Mask R-CNN head produces (a 28x28 soft mask inside a slightly wrong box, upsampled:
rounded corners, wobbly edges) with a known, seeded amount of error.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fenestra.checks import check_instances
from fenestra.conventions import LIMITS
from fenestra.masks import mask_box
from fenestra.errors import PipelineError
from fenestra.pipeline.types import Detection


def detections_from_instance_map(instances: np.ndarray, max_windows: int = LIMITS.max_windows_per_photo,
                                 full_masks: bool = False) -> list[Detection]:
    """One Detection per non-zero id of an (H, W) integer instance map, in increasing id order:
    the ``oracle`` detector (full masks) and ``fenestra reconstruct --masks`` (sparse).

    Score 1, label ``"window:<id>"``, ``instance_id`` the id; box (x0, y0, x1, y1) on the
    pixel-edge outline (fenestra.masks.mask_box); mask: the id's bounding-box crop at ``origin``
    (memory O(H W) once, plus the crops), or with ``full_masks`` the (H, W) mask at origin (0, 0)
    (the quad fit of a crop equals the full mask's to ~1e-14 px, not bit for bit: the bench's
    oracle rows keep the full-mask figures). An id with two separate blobs still gives one
    Detection (mask_to_quad then reports ``multiple_blobs``). Negative ids: ValueError; more than
    ``max_windows`` ids: PipelineError.
    """
    from scipy import ndimage  # noqa: PLC0415 (SciPy: imported when first used, not at the package's import)

    inst = np.asarray(instances)
    if inst.ndim != 2 or not np.issubdtype(inst.dtype, np.integer):
        raise ValueError(f"instance map must be a 2-D integer array, got shape {inst.shape}, dtype {inst.dtype}")
    if inst.size and inst.min() < 0:
        raise ValueError(f"instance map has negative ids (min {inst.min()})")
    boxes = ndimage.find_objects(inst) if inst.size and inst.max() > 0 else []
    ids = [i + 1 for i, sl in enumerate(boxes) if sl is not None]
    if len(ids) > max_windows:
        raise PipelineError(f"instance map has {len(ids)} window ids, more than the {max_windows} per photo "
                            "this pipeline handles (fenestra.conventions.LIMITS.max_windows_per_photo)")
    dets = []
    for iid in ids:
        ys, xs = boxes[iid - 1]
        box = np.array([xs.start - 0.5, ys.start - 0.5, xs.stop - 0.5, ys.stop - 0.5])
        if full_masks:
            dets.append(Detection(mask=inst == iid, box=box, score=1.0, label=f"window:{iid}", instance_id=iid))
        else:
            dets.append(Detection(mask=inst[ys, xs] == iid, box=box, score=1.0, label=f"window:{iid}",
                                  origin=(xs.start, ys.start), instance_id=iid))
    return dets


def oracle_detections(instances: np.ndarray) -> list[Detection]:
    """The ``oracle`` detector: :func:`detections_from_instance_map` of a checked instance map,
    full masks."""
    return detections_from_instance_map(check_instances(instances), full_masks=True)


@dataclass(frozen=True)
class DegradeConfig:
    """How ``oracle-degraded`` spoils the true mask (all lengths relative to the box size).

    mask_res: side of the low-resolution mask grid (Mask R-CNN: 28).
    box_jitter: std of each box edge's shift, as a fraction of the box width/height (proposal error).
    box_margin: the grid covers the box grown by this fraction on each side (as a RoI around it).
    blur_cells: Gaussian blur sigma in grid cells (soft edges; thresholding at 0.5 rounds corners).
    edge_noise: amplitude of smooth random noise added to the soft mask (boundary wobble).
    seed: base seed; instance k uses seed + k, so results do not depend on the other windows.
    """

    mask_res: int = 28
    box_jitter: float = 0.02
    box_margin: float = 0.1
    blur_cells: float = 1.0
    edge_noise: float = 0.15
    seed: int = 0

    def __post_init__(self) -> None:
        if self.mask_res < 4:
            raise ValueError(f"mask_res must be >= 4, got {self.mask_res}")
        for name in ("box_jitter", "box_margin", "blur_cells", "edge_noise"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")


def _degrade_one(mask: np.ndarray, cfg: DegradeConfig, rng: np.random.Generator) -> np.ndarray:
    """Degraded copy (H, W) bool of one true mask, imitating a RoI mask head."""
    H, W = mask.shape
    x0, y0, x1, y1 = mask_box(mask)
    bw, bh = x1 - x0, y1 - y0
    # The RoI: the box grown by the margin, edges jittered like a regressed proposal.
    jit = rng.normal(0.0, cfg.box_jitter, 4) * np.array([bw, bh, bw, bh])
    rx0 = x0 - cfg.box_margin * bw + jit[0]
    ry0 = y0 - cfg.box_margin * bh + jit[1]
    rx1 = x1 + cfg.box_margin * bw + jit[2]
    ry1 = y1 + cfg.box_margin * bh + jit[3]
    n = cfg.mask_res
    # Sample the true mask on an n x n grid of cell centres over the RoI (area-averaged: 4x4 taps).
    sub = 4
    t = (np.arange(n * sub) + 0.5) / (n * sub)
    xs = rx0 + t * (rx1 - rx0)
    ys = ry0 + t * (ry1 - ry0)
    mapx, mapy = np.meshgrid(xs.astype(np.float32), ys.astype(np.float32))
    fine = cv2.remap(mask.astype(np.float32), mapx, mapy, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    grid = fine.reshape(n, sub, n, sub).mean(axis=(1, 3))
    if cfg.blur_cells > 0:
        grid = cv2.GaussianBlur(grid, (0, 0), cfg.blur_cells)
    if cfg.edge_noise > 0:
        noise = cv2.GaussianBlur(rng.normal(0.0, 1.0, (n, n)).astype(np.float32), (0, 0), 2.0)
        noise /= max(float(noise.std()), 1e-6)
        grid = grid + cfg.edge_noise * noise
    # Paste back: bilinear upsampling of the grid to the image pixels the RoI covers, threshold 0.5.
    c0, c1 = max(0, int(np.floor(rx0))), min(W, int(np.ceil(rx1)) + 1)
    r0, r1 = max(0, int(np.floor(ry0))), min(H, int(np.ceil(ry1)) + 1)
    out = np.zeros((H, W), dtype=bool)
    if c1 <= c0 or r1 <= r0:
        return out
    gx = ((np.arange(c0, c1) - rx0) / (rx1 - rx0) * n - 0.5).astype(np.float32)
    gy = ((np.arange(r0, r1) - ry0) / (ry1 - ry0) * n - 0.5).astype(np.float32)
    gmx, gmy = np.meshgrid(gx, gy)
    soft = cv2.remap(grid.astype(np.float32), gmx, gmy, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    out[r0:r1, c0:c1] = soft >= 0.5
    return out


def degraded_detections(instances: np.ndarray, config: DegradeConfig = DegradeConfig()) -> list[Detection]:
    """Degraded oracle: per id of the instance map, a Mask R-CNN-like mask (score 1), by id.

    Deterministic for a given config.seed. Instances whose degraded mask comes out empty are
    dropped (a miss), as a network would miss them.
    """
    inst = check_instances(instances)
    dets = []
    for k in np.unique(inst):
        if k == 0:
            continue
        rng = np.random.default_rng([config.seed, int(k)])
        m = _degrade_one(inst == k, config, rng)
        if m.any():
            dets.append(Detection(mask=m, box=mask_box(m), score=1.0))
    return dets
