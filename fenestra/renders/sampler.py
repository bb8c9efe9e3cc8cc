"""Camera samplers: per-window views and street-level views, deterministic by seed.

A candidate view is rejected, and the reason counted, when the camera is too low (below the
ground), a target window corner is behind the camera or outside the frame, or the target is less
visible than ``min_visible_fraction`` (needs a ``visibility`` function, usually a renderer's
exact occluder pass: see :func:`renders.dataset.render_dataset`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

from fenestra.conventions import LIMITS, look_at
from fenestra.renders.camera import Camera
from fenestra.renders.gt import WindowView
from fenestra.renders.materials import ground_z
from fenestra.scenes.model import Scene

REJECT_REASONS = ("below_ground", "behind_camera", "facing_away", "outside_frame", "low_visibility")


def _range(name: str, r) -> tuple[float, float]:
    lo, hi = (float(x) for x in r)
    if not np.isfinite(lo) or not np.isfinite(hi) or hi < lo:
        raise ValueError(f"{name} must be a (low, high) range with low <= high, got {r}")
    return lo, hi


@dataclass(frozen=True)
class SamplerConfig:
    """Ranges (low, high) of the sampled camera parameters; angles in degrees, lengths in m.

    Window views: the camera looks at one window from ``distance_m`` along a direction
    ``azimuth_deg`` (horizontal, from the window normal) and ``elevation_deg`` (vertical) away
    from it, rolled by ``roll_deg`` around its axis. Street views (``street_fraction`` of views):
    a camera ``street_height_m`` above the ground, ``street_distance_m`` from a facade, looking
    at it (several windows at once). ``k1_range``: radial distortion k1 (0 = pinhole).
    """

    width: int = 640
    height: int = 480
    hfov_deg: tuple[float, float] = (50.0, 70.0)
    azimuth_deg: tuple[float, float] = (-50.0, 50.0)
    elevation_deg: tuple[float, float] = (-10.0, 30.0)
    distance_m: tuple[float, float] = (3.0, 12.0)
    roll_deg: tuple[float, float] = (-5.0, 5.0)
    target_jitter_m: float = 0.5
    street_fraction: float = 0.3
    street_height_m: tuple[float, float] = (1.5, 1.8)
    street_distance_m: tuple[float, float] = (6.0, 18.0)
    k1_range: tuple[float, float] = (0.0, 0.0)
    min_visible_fraction: float = 0.5
    min_eye_height_m: float = 0.3
    max_tries: int = 200

    def __post_init__(self) -> None:
        if self.width < 16 or self.height < 16:
            raise ValueError(f"image size must be at least 16x16, got {self.width}x{self.height}")
        if max(self.width, self.height) > LIMITS.max_render_side_px:
            raise ValueError(f"image size {self.width}x{self.height}: a side may be at most "
                             f"{LIMITS.max_render_side_px} px (fenestra.conventions.LIMITS.max_render_side_px)")
        for name in ("hfov_deg", "azimuth_deg", "elevation_deg", "distance_m", "roll_deg", "street_height_m",
                     "street_distance_m", "k1_range"):
            object.__setattr__(self, name, _range(name, getattr(self, name)))
        if not 0 < self.hfov_deg[0] <= self.hfov_deg[1] < 180:
            raise ValueError(f"hfov_deg must lie in (0, 180), got {self.hfov_deg}")
        if self.distance_m[0] <= 0 or self.street_distance_m[0] <= 0:
            raise ValueError(f"distances must be positive, got {self.distance_m}, {self.street_distance_m}")
        if not 0 <= self.street_fraction <= 1:
            raise ValueError(f"street_fraction must be in [0, 1], got {self.street_fraction}")
        if not 0 <= self.min_visible_fraction <= 1:
            raise ValueError(f"min_visible_fraction must be in [0, 1], got {self.min_visible_fraction}")


@dataclass(frozen=True, eq=False)
class ViewSpec:
    """A sampled camera, how it was sampled ("window" | "street") and its target windows' ids."""

    camera: Camera
    mode: str
    targets: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class SamplingResult:
    views: tuple[ViewSpec, ...]
    rejected: dict[str, int] = field(default_factory=dict)
    tries: int = 0


def _horizontal(normal: np.ndarray) -> np.ndarray:
    h = np.array([normal[0], normal[1], 0.0])
    n = np.linalg.norm(h)
    return h / n if n > 1e-6 else np.array([1.0, 0.0, 0.0])


def _rotz(v: np.ndarray, deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


def _dist(cfg: SamplerConfig, rng) -> tuple[float, ...] | None:
    k1 = rng.uniform(*cfg.k1_range)
    return None if k1 == 0 else (k1, -0.3 * k1 * abs(k1), 0.0, 0.0, 0.0)


def propose(scene: Scene, cfg: SamplerConfig, rng: np.random.Generator, gz: float) -> ViewSpec:
    """One candidate view (not yet checked)."""
    street = rng.random() < cfg.street_fraction
    w = scene.windows[int(rng.integers(len(scene.windows)))]
    c, n = w.center, _horizontal(w.normal)
    along = np.cross([0.0, 0.0, 1.0], n)
    fov = rng.uniform(*cfg.hfov_deg)
    if street:
        d = _rotz(n, rng.uniform(*cfg.azimuth_deg)) * rng.uniform(*cfg.street_distance_m)
        eye = np.array([c[0] + d[0], c[1] + d[1], gz + rng.uniform(*cfg.street_height_m)])
        target = c + along * rng.uniform(-2, 2) * cfg.target_jitter_m
        target[2] = 0.5 * (c[2] + eye[2]) + 0.5
    else:
        el = np.radians(rng.uniform(*cfg.elevation_deg))
        d = np.cos(el) * _rotz(n, rng.uniform(*cfg.azimuth_deg)) + np.array([0, 0, np.sin(el)])
        eye = c + d * rng.uniform(*cfg.distance_m)
        target = c + (along * rng.uniform(-1, 1) + np.array([0, 0, rng.uniform(-1, 1)])) * cfg.target_jitter_m
    R, t = look_at(eye, target, roll_deg=rng.uniform(*cfg.roll_deg))
    cam = Camera.from_fov(cfg.width, cfg.height, fov, R, t, _dist(cfg, rng))
    return ViewSpec(cam, "street" if street else "window", (w.id,))


def faces_camera(cam: Camera, w) -> bool:
    """True when the camera is on the outer side of the window's wall face."""
    return float((cam.center - w.center) @ w.normal) > 0


def in_frame(cam: Camera, corners_world: np.ndarray) -> tuple[bool, bool]:
    """(all corners in front of the camera, all corners inside the image)."""
    if np.any(cam.depths(corners_world) <= 0.05):
        return False, False
    px = cam.project(corners_world)
    inside = np.all((px >= -0.5) & (px <= np.array([cam.width, cam.height]) - 0.5))
    return True, bool(inside)


def check(view: ViewSpec, scene: Scene, cfg: SamplerConfig, gz: float,
          visibility: Callable[[Camera], tuple[WindowView, ...]] | None) -> tuple[ViewSpec | None, str | None]:
    """Accept a candidate (possibly with updated targets) or return the reject reason."""
    cam = view.camera
    if cam.center[2] < gz + cfg.min_eye_height_m:
        return None, "below_ground"
    by_id = {w.id: w for w in scene.windows}
    if view.mode == "street":
        flags = {w.id: in_frame(cam, w.corners_world) for w in scene.windows if faces_camera(cam, w)}
        cands = [i for i, (front, inside) in flags.items() if front and inside]
        if not cands:
            if view.targets[0] not in flags:
                return None, "facing_away"
            front, _ = flags[view.targets[0]]
            return None, "outside_frame" if front else "behind_camera"
    else:
        if not faces_camera(cam, by_id[view.targets[0]]):
            return None, "facing_away"
        front, inside = in_frame(cam, by_id[view.targets[0]].corners_world)
        if not front:
            return None, "behind_camera"
        if not inside:
            return None, "outside_frame"
        cands = list(view.targets)
    if visibility is not None:
        vis = {v.id: v.visible_fraction for v in visibility(cam)}
        cands = [i for i in cands if vis[i] >= cfg.min_visible_fraction]
        if not cands:
            return None, "low_visibility"
    return ViewSpec(cam, view.mode, tuple(cands)), None


@dataclass(frozen=True, eq=False)
class Accepted:
    """A view as :func:`iter_views` yields it: the ``index``-th accepted view, and the sampler's
    counts so far (candidates tried, rejected by reason)."""

    index: int
    view: ViewSpec
    tries: int
    rejected: dict[str, int]


def iter_views(scene: Scene, cfg: SamplerConfig, n: int, seed: int,
               visibility: Callable[[Camera], tuple[WindowView, ...]] | None = None) -> Iterator[Accepted]:
    """The ``n`` accepted views of ``scene``, one at a time (a caller can render a view as soon as
    it is accepted, while its visibility pass is at hand); deterministic for a given seed (numpy
    Generator): the candidates do not depend on when the caller consumes them.

    Raises ValueError when the scene has no windows or ``n * max_tries`` candidates do not
    give ``n`` views (the message lists the reject counts).
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if not scene.windows:
        raise ValueError(f"scene {scene.name!r} has no windows to sample views of")
    rng = np.random.default_rng(seed)
    gz = ground_z(scene)
    rejected = {r: 0 for r in REJECT_REASONS}
    accepted = tries = 0
    while accepted < n:
        if tries >= max(1, n) * cfg.max_tries:
            raise ValueError(f"sampler found only {accepted}/{n} views of {scene.name!r} in {tries} tries; "
                             f"rejected: {rejected}")
        tries += 1
        view, reason = check(propose(scene, cfg, rng, gz), scene, cfg, gz, visibility)
        if view is None:
            rejected[reason] += 1
        else:
            yield Accepted(accepted, view, tries, dict(rejected))
            accepted += 1


def sample_views(scene: Scene, cfg: SamplerConfig, n: int, seed: int,
                 visibility: Callable[[Camera], tuple[WindowView, ...]] | None = None) -> SamplingResult:
    """``n`` accepted views of ``scene`` at once (:func:`iter_views`, collected)."""
    views: list[ViewSpec] = []
    last = None
    for last in iter_views(scene, cfg, n, seed, visibility):
        views.append(last.view)
    if last is None:
        return SamplingResult((), {r: 0 for r in REJECT_REASONS}, 0)
    return SamplingResult(tuple(views), last.rejected, last.tries)
