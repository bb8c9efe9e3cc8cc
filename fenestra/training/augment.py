"""Domain randomisation for detector training: geometric (scale, oblique-view perspective, crop,
flip), photometric (colour jitter, white balance, blur, motion blur, low resolution, noise, JPEG)
and compositional (eave shadows, street occluders, a neighbouring facade pasted beside the crop)
augmentation, seeded by a numpy Generator. Every optional step draws nothing when it is off, so a
config without it keeps the same random stream.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class AugmentConfig:
    """Augmentation ranges. Scales are image-size factors; colours in [0, 255] units."""

    scale_range: tuple[float, float] = (0.5, 1.3)
    hflip_prob: float = 0.5
    brightness: float = 0.3  # multiply by U(1-b, 1+b)
    contrast: float = 0.3
    saturation: float = 0.4
    hue_deg: float = 12.0
    gamma: float = 0.25
    blur_prob: float = 0.3
    blur_sigma_max: float = 1.5
    noise_prob: float = 0.5
    noise_std_max: float = 8.0
    jpeg_prob: float = 0.4
    jpeg_quality: tuple[int, int] = (35, 95)
    grey_prob: float = 0.05
    shadow_prob: float = 0.0  # dark horizontal band (eave shadow) over the top of a window
    shadow_strength: tuple[float, float] = (0.15, 0.6)  # brightness factor inside the band
    occluder_prob: float = 0.0  # street occluders drawn over the crop (occluders()): trees, poles, cars, people
    occluder_max: int = 3  # at most this many per crop
    perspective_prob: float = 0.0  # a virtual camera rotation (oblique street view): perspective_homography
    yaw_deg: float = 40.0  # |yaw| <= this (turn about the vertical: one side of the facade recedes)
    pitch_deg: tuple[float, float] = (-5.0, 20.0)  # looking up (> 0) at the facade from the street
    roll_deg: float = 3.0
    focal_range: tuple[float, float] = (0.8, 1.6)  # virtual focal length / max(image h, w)
    white_balance: float = 0.0  # per-channel gain U(1-wb, 1+wb) (camera white balance)
    motion_blur_prob: float = 0.0  # a straight blur kernel 3-9 px long at a random angle
    lowres_prob: float = 0.0  # down- then up-sample by U(lowres_range): a small or upscaled photo
    lowres_range: tuple[float, float] = (0.3, 0.7)
    neighbour_prob: float = 0.0  # paste a vertical strip of another sample beside the crop: neighbour_strip
    neighbour_frac: tuple[float, float] = (0.2, 0.5)  # the strip's share of the crop width
    pad: str = "reflect"  # a crop larger than the scaled image: "reflect" it (mirrored windows carry
    # no label) or fill a flat random colour ("constant": no unlabelled window)

    def __post_init__(self) -> None:
        if self.pad not in ("reflect", "constant"):
            raise ValueError(f"augment pad must be 'reflect' or 'constant', got {self.pad!r}")


@dataclass(frozen=True, eq=False)
class CropWarp:
    """The geometry of one random_scale_crop: scale (sx, sy), then the homography H (3, 3) on the
    scaled image (None: none), crop origin (x0, y0), horizontal flip of a crop ``width`` px wide.
    Maps points like the pixels."""

    sx: float
    sy: float
    x0: int
    y0: int
    flip: bool
    width: int
    H: np.ndarray | None = None

    def points(self, p: np.ndarray) -> np.ndarray:
        """(..., 2) px on the original (pixel centres at integers) -> the same points on the crop."""
        p = np.asarray(p, dtype=np.float64)
        x = (p[..., 0] + 0.5) * self.sx - 0.5
        y = (p[..., 1] + 0.5) * self.sy - 0.5
        if self.H is not None:
            q = self.H @ np.stack([x, y, np.ones_like(x)]).reshape(3, -1)
            x, y = (q[:2] / q[2]).reshape(2, *x.shape)
        x, y = x - self.x0, y - self.y0
        if self.flip:
            x = self.width - 1 - x
        return np.stack([x, y], axis=-1)


def perspective_homography(h: int, w: int, cfg: AugmentConfig, rng: np.random.Generator) -> np.ndarray:
    """(3, 3) homography of a virtual camera rotation (yaw, pitch, roll drawn from cfg) about a
    pinhole with focal f = U(cfg.focal_range) * max(h, w) px at the centre of an (h, w) image: the
    view of a facade from further along the street or from below. Recentred so the image centre
    stays put and rescaled so the area near the centre keeps its size. Pixel centres at integers."""
    f = rng.uniform(*cfg.focal_range) * max(h, w)
    yaw, pitch, roll = np.radians([rng.uniform(-cfg.yaw_deg, cfg.yaw_deg), rng.uniform(*cfg.pitch_deg),
                                   rng.uniform(-cfg.roll_deg, cfg.roll_deg)])
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    K = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]])
    cy_, sy_ = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    R = (np.array([[cy_, 0, sy_], [0, 1, 0], [-sy_, 0, cy_]]) @ np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
         @ np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]]))
    H = K @ R @ np.linalg.inv(K)
    q = H @ np.array([cx, cy, 1.0])
    c = q[:2] / q[2]
    J = (H[:2, :2] - np.outer(c, H[2, :2])) / q[2]  # d(warped point)/d(point) at the centre
    k = 1.0 / np.sqrt(abs(np.linalg.det(J)))
    A = np.array([[k, 0, cx - k * c[0]], [0, k, cy - k * c[1]], [0, 0, 1.0]])
    return A @ H


def random_scale_crop(image: np.ndarray, instances: np.ndarray, crop_hw: tuple[int, int],
                      cfg: AugmentConfig, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, CropWarp]:
    """Rescale by a random factor, warp it as seen from an oblique virtual camera (with probability
    cfg.perspective_prob), take a random crop (H, W) = crop_hw (padded as cfg.pad says where the
    image is smaller), flip horizontally at random. Returns image (h, w, 3) uint8, instances (h, w) int32
    and the CropWarp that maps points (corners) the same way."""
    s = rng.uniform(*cfg.scale_range)
    H, W = instances.shape
    nh, nw = max(8, int(round(H * s))), max(8, int(round(W * s)))
    img = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
    inst = cv2.resize(instances.astype(np.int32), (nw, nh), interpolation=cv2.INTER_NEAREST)
    Hm = None
    if cfg.perspective_prob > 0 and rng.random() < cfg.perspective_prob:  # no draw when off: same stream
        Hm = perspective_homography(nh, nw, cfg, rng)
        fill = tuple(int(v) for v in rng.integers(0, 256, 3))  # outside the photo: a flat colour, no window
        img = cv2.warpPerspective(img, Hm, (nw, nh), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                  borderValue=fill)
        inst = cv2.warpPerspective(inst.astype(np.float32), Hm, (nw, nh), flags=cv2.INTER_NEAREST,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=0).astype(np.int32)
    ch, cw = crop_hw
    ph, pw = max(0, ch - nh), max(0, cw - nw)
    if (ph or pw) and cfg.pad == "constant":
        img = cv2.copyMakeBorder(img, 0, ph, 0, pw, cv2.BORDER_CONSTANT,
                                 value=tuple(int(v) for v in rng.integers(0, 256, 3)))
        inst = cv2.copyMakeBorder(inst, 0, ph, 0, pw, cv2.BORDER_CONSTANT, value=0)
    elif ph or pw:
        img = cv2.copyMakeBorder(img, 0, ph, 0, pw, cv2.BORDER_REFLECT)
        inst = cv2.copyMakeBorder(inst, 0, ph, 0, pw, cv2.BORDER_CONSTANT, value=0)
    # Prefer crops that contain windows: pick a centre on a window pixel half of the time.
    y0 = int(rng.integers(0, img.shape[0] - ch + 1))
    x0 = int(rng.integers(0, img.shape[1] - cw + 1))
    if rng.random() < 0.5:
        ys, xs = np.nonzero(inst)
        if ys.size:
            i = int(rng.integers(ys.size))
            y0 = int(np.clip(ys[i] - ch // 2, 0, img.shape[0] - ch))
            x0 = int(np.clip(xs[i] - cw // 2, 0, img.shape[1] - cw))
    img, inst = img[y0:y0 + ch, x0:x0 + cw], inst[y0:y0 + ch, x0:x0 + cw]
    flip = bool(rng.random() < cfg.hflip_prob)
    if flip:
        img, inst = img[:, ::-1], inst[:, ::-1]
    warp = CropWarp(nw / W, nh / H, x0, y0, flip, cw, Hm)
    return np.ascontiguousarray(img), np.ascontiguousarray(inst), warp


def photometric(image: np.ndarray, cfg: AugmentConfig, rng: np.random.Generator) -> np.ndarray:
    """Colour jitter, gamma, grey, blur, sensor noise, JPEG artefacts on an RGB uint8 image."""
    img = image.astype(np.float32)
    img = img * rng.uniform(1 - cfg.brightness, 1 + cfg.brightness)
    if cfg.white_balance > 0:
        img = img * rng.uniform(1 - cfg.white_balance, 1 + cfg.white_balance, 3).astype(np.float32)
    mean = img.mean()
    img = (img - mean) * rng.uniform(1 - cfg.contrast, 1 + cfg.contrast) + mean
    img = np.clip(img, 0, 255)
    hsv = cv2.cvtColor(img.astype(np.uint8), cv2.COLOR_RGB2HSV).astype(np.float32)
    hsv[..., 0] = (hsv[..., 0] + rng.uniform(-cfg.hue_deg, cfg.hue_deg) / 2.0) % 180.0
    hsv[..., 1] = np.clip(hsv[..., 1] * rng.uniform(1 - cfg.saturation, 1 + cfg.saturation), 0, 255)
    lut = (255.0 * (np.arange(256) / 255.0) ** np.exp(rng.uniform(-cfg.gamma, cfg.gamma))).astype(np.float32)
    img = lut[cv2.cvtColor(hsv.astype(np.uint8), cv2.COLOR_HSV2RGB)]  # gamma, via a lookup table
    if rng.random() < cfg.grey_prob:
        img = np.repeat(img.mean(axis=2, keepdims=True), 3, axis=2)
    if rng.random() < cfg.blur_prob:
        img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.3, cfg.blur_sigma_max))
    if cfg.motion_blur_prob > 0 and rng.random() < cfg.motion_blur_prob:
        img = cv2.filter2D(img, -1, motion_kernel(int(rng.integers(3, 10)), rng.uniform(0, 180)))
    if cfg.lowres_prob > 0 and rng.random() < cfg.lowres_prob:
        f = rng.uniform(*cfg.lowres_range)
        h, w = img.shape[:2]
        small = cv2.resize(img, (max(8, int(w * f)), max(8, int(h * f))), interpolation=cv2.INTER_AREA)
        img = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    if rng.random() < cfg.noise_prob:
        img = img + np.float32(rng.uniform(0, cfg.noise_std_max)) * rng.standard_normal(img.shape, dtype=np.float32)
    img = np.clip(img, 0, 255).astype(np.uint8)
    if rng.random() < cfg.jpeg_prob:
        q = int(rng.integers(cfg.jpeg_quality[0], cfg.jpeg_quality[1] + 1))
        ok, buf = cv2.imencode(".jpg", img[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, q])
        if ok:
            img = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1]
    return np.ascontiguousarray(img)


def motion_kernel(length: int, angle_deg: float) -> np.ndarray:
    """(length, length) float32 kernel summing to 1: a line ``length`` px long through the centre at
    ``angle_deg`` (0 = horizontal), as a camera shake of that length smears a point."""
    k = np.zeros((length, length), np.float32)
    c = (length - 1) / 2.0
    dx, dy = np.cos(np.radians(angle_deg)) * c, np.sin(np.radians(angle_deg)) * c
    cv2.line(k, (int(round(c - dx)), int(round(c - dy))), (int(round(c + dx)), int(round(c + dy))), 1.0, 1)
    return k / k.sum()


def shadow_band(image: np.ndarray, instances: np.ndarray, cfg: AugmentConfig,
                rng: np.random.Generator) -> np.ndarray:
    """With probability cfg.shadow_prob, darken a full-width horizontal band, like an eave's shadow.

    Most bands start above a random window's top edge and end inside the window (hiding that edge);
    a quarter lie anywhere, so a dark band alone does not mean "window below". The labels are
    unchanged. image (h, w, 3) uint8, instances (h, w) int; returns a new image.
    """
    if cfg.shadow_prob <= 0 or rng.random() >= cfg.shadow_prob:  # no draw when off: same stream
        return image
    h = image.shape[0]
    ids = np.unique(instances)
    ids = ids[ids > 0]
    if ids.size and rng.random() < 0.75:
        ys = np.nonzero(np.any(instances == ids[int(rng.integers(ids.size))], axis=1))[0]
        top, height = int(ys[0]), int(ys[-1] - ys[0] + 1)
        y1 = top + int(rng.uniform(0.0, 0.6) * height)
        y0 = top - int(rng.uniform(3, 40))
    else:
        y0 = int(rng.integers(0, h))
        y1 = y0 + int(rng.uniform(5, 60))
    y0, y1 = max(0, y0), min(h, max(y1, y0 + 2))
    if y1 <= y0:
        return image
    f = np.ones(h, dtype=np.float32)
    f[y0:y1] = rng.uniform(*cfg.shadow_strength)
    soft = int(rng.integers(0, 6))
    if soft:  # soft lower edge (penumbra)
        f = cv2.GaussianBlur(f[:, None], (1, 2 * soft + 1), 0)[:, 0]
    out = image.astype(np.float32) * f[:, None, None]
    return np.clip(out, 0, 255).astype(np.uint8)


OCCLUDER_KINDS = ("tree", "pole", "car", "person")


def _occluder_mask(kind: str, h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """(h, w) bool silhouette of one street occluder, placed at random (sizes relative to the crop)."""
    m = np.zeros((h, w), np.uint8)
    if kind == "tree":  # a crown of overlapping discs on a trunk
        cx, cy, r = int(rng.integers(0, w)), int(rng.integers(0, h)), int(rng.uniform(0.08, 0.3) * min(h, w)) + 2
        for _ in range(int(rng.integers(4, 10))):
            c = (cx + int(rng.normal(0, r * 0.6)), cy + int(rng.normal(0, r * 0.4)))
            cv2.circle(m, c, max(2, int(r * rng.uniform(0.4, 0.8))), 1, -1)
        cv2.rectangle(m, (cx - max(1, r // 8), cy), (cx + max(1, r // 8), h), 1, -1)
    elif kind == "pole":  # a lamp or sign post, maybe with a cable
        x, t = int(rng.integers(0, w)), int(rng.integers(1, max(2, w // 40) + 2))
        cv2.rectangle(m, (x, int(rng.integers(0, h // 2))), (x + t, h), 1, -1)
        if rng.random() < 0.5:
            cv2.line(m, (0, int(rng.integers(0, h))), (w, int(rng.integers(0, h))), 1, 1)
    elif kind == "car":  # a rounded box with a cabin, at the bottom
        cw, ch = int(rng.uniform(0.3, 0.8) * w), int(rng.uniform(0.12, 0.3) * h)
        x0, y1 = int(rng.integers(-cw // 2, w)), h - int(rng.integers(0, h // 6 + 1))
        cv2.rectangle(m, (x0, y1 - ch // 2), (x0 + cw, y1), 1, -1)
        cv2.rectangle(m, (x0 + cw // 5, y1 - ch), (x0 + 4 * cw // 5, y1 - ch // 2), 1, -1)
    else:  # person: head, body, legs
        ph = int(rng.uniform(0.2, 0.6) * h)
        x, y1 = int(rng.integers(0, w)), h - int(rng.integers(0, h // 5 + 1))
        cv2.circle(m, (x, y1 - ph + ph // 10), max(1, ph // 10), 1, -1)
        cv2.rectangle(m, (x - ph // 8, y1 - ph + ph // 5), (x + ph // 8, y1 - ph // 2), 1, -1)
        cv2.rectangle(m, (x - ph // 10, y1 - ph // 2), (x + ph // 10, y1), 1, -1)
    return m.astype(bool)


def occluders(image: np.ndarray, instances: np.ndarray, cfg: AugmentConfig,
              rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """With probability cfg.occluder_prob, draw 1..occluder_max street occluders (tree, pole, car,
    person as simple shapes, flat or noisy colour) over the image. A window is a void *seen*, so
    occluded pixels leave the instance map (as in a render, where an occluder hides the void).

    image (h, w, 3) uint8, instances (h, w) int -> new image, new instances, occluded (h, w) bool.
    """
    h, w = instances.shape
    occ = np.zeros((h, w), bool)
    if cfg.occluder_prob <= 0 or rng.random() >= cfg.occluder_prob:  # no draw when off: same stream
        return image, instances, occ
    img = image.copy()
    for _ in range(int(rng.integers(1, cfg.occluder_max + 1))):
        kind = OCCLUDER_KINDS[int(rng.integers(len(OCCLUDER_KINDS)))]
        m = _occluder_mask(kind, h, w, rng)
        base = {"tree": (50, 90, 40), "pole": (60, 60, 60)}.get(kind, tuple(int(v) for v in rng.integers(20, 235, 3)))
        col = np.clip(np.asarray(base, np.float32) * rng.uniform(0.5, 1.3), 0, 255)
        tex = rng.normal(0, 25 if kind == "tree" else 8, (h, w, 1)).astype(np.float32)
        img[m] = np.clip(col + tex[m], 0, 255).astype(np.uint8)
        occ |= m
    return img, np.where(occ, 0, instances), occ


def neighbour_strip(image: np.ndarray, instances: np.ndarray, other: np.ndarray, other_instances: np.ndarray,
                    cfg: AugmentConfig, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """With probability cfg.neighbour_prob, replace a full-height strip at the left or right edge
    (U(cfg.neighbour_frac) of the width) by the same strip of another augmented crop of the same
    size, with its windows: a neighbouring facade, as along a street of joined houses.

    image, other (h, w, 3) uint8; instances, other_instances (h, w) int. The other crop's ids are
    shifted past this crop's. Returns image, instances, pasted (h, w) bool (where the strip is).
    """
    h, w = instances.shape
    pasted = np.zeros((h, w), bool)
    if cfg.neighbour_prob <= 0 or rng.random() >= cfg.neighbour_prob:  # no draw when off: same stream
        return image, instances, pasted
    if other.shape[:2] != (h, w) or other_instances.shape != (h, w):
        raise ValueError(f"neighbour_strip: other crop {other.shape[:2]} differs from {(h, w)}")
    sw = max(1, int(round(rng.uniform(*cfg.neighbour_frac) * w)))
    cols = slice(0, sw) if rng.random() < 0.5 else slice(w - sw, w)
    pasted[:, cols] = True
    img, inst = image.copy(), instances.copy()
    img[:, cols] = other[:, cols]
    shift = int(instances.max()) if instances.size else 0
    inst[:, cols] = np.where(other_instances[:, cols] > 0, other_instances[:, cols] + shift, 0)
    return img, inst, pasted
