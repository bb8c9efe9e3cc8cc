"""The dataset writer: sampled views of a scene rendered to the DESIGN.md data contract.

    out/renders/<scene>-<renderer>-<hash>/
        config.json  sampling.json  coco.json
        views/000000/image.png  instances.png (16-bit)  [ignore.png (16-bit)]  view.json

The folder name is a hash of the config that changes the output (scene sha256, sampler config,
renderer + settings, sensor config, seed, number of views) and FORMAT_VERSION, so re-running a
config reuses the views already there. The renderers' code is not hashed: a change to what a
backend draws must bump FORMAT_VERSION (or the cached views are reused as they are). Ignore
regions (renders.gt: curtain-wall glazing, glazed doors) came later without a bump: every view.json
now lists ``ignore`` (maybe empty); a cached view without the key gets them from the occluder pass
alone (ignore.png and view.json added, image and instances untouched: they are the same). Python API:
:func:`render_dataset`; read a view with fenestra.data.read_view.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fenestra import data, files
from renders.backends import RENDERERS, make_renderer, visibility_function
from renders.base import RenderSettings
from renders.sampler import SamplerConfig, sample_views
from renders.sensor import SensorConfig, apply_sensor
from scenes.model import Scene

FORMAT_VERSION = 2  # 2: GL raster backend rewrite (shader shadows, per-pixel sky, FXAA default)


@dataclass(frozen=True)
class DatasetConfig:
    """What to render. scene: bundled name or IFC path (or pass a Scene to render_dataset)."""

    scene: str
    n_views: int = 20
    seed: int = 0
    renderer: str = "pyrender"
    sampler: SamplerConfig = field(default_factory=SamplerConfig)
    settings: RenderSettings = field(default_factory=RenderSettings)
    sensor: SensorConfig = field(default_factory=SensorConfig)
    out_root: str = "out/renders"

    def __post_init__(self) -> None:
        if self.n_views < 1:
            raise ValueError(f"n_views must be >= 1, got {self.n_views}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")
        if self.renderer not in RENDERERS:
            raise ValueError(f"unknown renderer {self.renderer!r}; choose one of {sorted(RENDERERS)}")


def config_hash(config: DatasetConfig, scene: Scene) -> str:
    """12 hex digits identifying the output of (config, scene); out_root excluded.

    ``settings.denoise`` counts only for mitsuba and only when not "none", so the folders of raster
    datasets and of undenoised mitsuba ones keep the names they had before the option existed.
    """
    d = dataclasses.asdict(config)
    d.pop("out_root")
    if config.renderer != "mitsuba" or config.settings.denoise == "none":
        d["settings"].pop("denoise")
    d["settings"]["seed"] = config.seed
    d["scene_sha256"] = scene.sha256
    d["format"] = FORMAT_VERSION
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=list).encode()).hexdigest()[:12]


def dataset_dir(config: DatasetConfig, scene: Scene) -> Path:
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in scene.name)
    return Path(config.out_root) / f"{safe}-{config.renderer}-{config_hash(config, scene)}"


def coco_from_views(root: Path, n_views: int) -> dict:
    """coco.json of the views under root/views (image ids from 0): fenestra.data.view_annotations
    of each view (RLE masks, COCO boxes; ignore regions as ``iscrowd`` annotations)."""
    images, anns = [], []
    for i in range(n_views):
        key = f"views/{i:06d}/image.png"
        view = data.read_view(root / "views" / f"{i:06d}")
        images.append((key, view.meta["height"], view.meta["width"]))
        anns += data.view_annotations(view, key)
    return data.coco_ground_truth(images, anns, first_image_id=0)


def _load_scene(config: DatasetConfig) -> Scene:
    from scenes import load_scene

    return load_scene(config.scene)


def render_dataset(config: DatasetConfig, scene: Scene | None = None, progress: bool = True,
                   only: range | None = None) -> Path:
    """Render (or reuse) the dataset of ``config``; return its folder.

    Views already written by an earlier run of the same config are kept, missing ones rendered.
    only: render just these view indices (a shard of a distributed run: the views are identical to
    those of a whole run); the dataset-wide files (coco.json, stats.json) are then left to a
    later call without ``only``.
    """
    scene = _load_scene(config) if scene is None else scene
    root = dataset_dir(config, scene)
    root.mkdir(parents=True, exist_ok=True)
    indices = range(config.n_views) if only is None else only
    if indices.start < 0 or indices.stop > config.n_views:
        raise ValueError(f"only={indices} is outside the dataset's views 0..{config.n_views - 1}")
    files.write_text(root / "config.json", json.dumps({"config": dataclasses.asdict(config), "scene": scene.name,
                                                  "scene_sha256": scene.sha256}, indent=1, default=list))
    missing = [i for i in indices if not _reusable(root / "views" / f"{i:06d}")]
    stats = {"rendered": 0, "reused": config.n_views - len(missing), "seconds": 0.0}
    todo = set(missing)
    stale = [i for i in indices if i not in todo and "ignore" not in data.read_meta(root / "views" / f"{i:06d}")]
    if stale:
        add_ignore_regions(scene, [root / "views" / f"{i:06d}" for i in stale])
        stats["ignore_added"] = len(stale)
    if missing:
        settings = dataclasses.replace(config.settings, seed=config.seed)
        renderer = make_renderer(config.renderer, scene, settings)
        try:
            vis = visibility_function(config.renderer, renderer) if config.sampler.min_visible_fraction > 0 else None
            sampling = sample_views(scene, config.sampler, config.n_views, config.seed, visibility=vis)
            files.write_text(root / "sampling.json", json.dumps({"rejected": sampling.rejected, "tries": sampling.tries,
                                                            "accepted": len(sampling.views)}, indent=1))
            t0 = time.perf_counter()
            for i in _progress(missing, progress, f"render {scene.name} ({config.renderer})"):
                spec = sampling.views[i]
                out = renderer.render(spec.camera)
                if config.sensor.active:
                    rgb = apply_sensor(out.rgb, config.sensor, np.random.default_rng([config.seed, i]))
                    out = dataclasses.replace(out, rgb=rgb)
                meta = {**spec.camera.to_dict(), "renderer": config.renderer, "seed": config.seed, "view_index": i,
                        "mode": spec.mode, "targets": list(spec.targets), "scene": scene.name,
                        "scene_sha256": scene.sha256, "windows": [w.to_dict() for w in out.windows],
                        "ignore": list(out.ignore_regions)}
                data.write_view(root / "views" / f"{i:06d}", out.rgb, out.instances, meta, ignore=out.ignore)
            stats["seconds"] = time.perf_counter() - t0
            stats["rendered"] = len(missing)
        finally:
            renderer.close()
    if only is None:
        files.write_text(root / "coco.json", json.dumps(coco_from_views(root, config.n_views)))
        files.write_text(root / "stats.json", json.dumps(stats))
    return root


def add_ignore_regions(scene: Scene, view_dirs: list[Path]) -> None:
    """Give views rendered before the renderers drew ignore regions their ignore.png and view.json
    ``ignore`` list, from the exact occluder pass of each view's camera (no RGB rendering)."""
    from renders.camera import Camera  # noqa: PLC0415
    from renders.raster import OccluderPass, ground_truth  # noqa: PLC0415 - GL

    occ = OccluderPass(scene)
    try:
        for d in view_dirs:
            _, _, _, (ign, regions) = ground_truth(occ, Camera.from_dict(data.read_meta(d)))
            data.write_ignore(d, ign, regions)
    finally:
        occ.close()


def _reusable(view_dir: Path) -> bool:
    """True if the cached view can be reused; a broken one is reported on stderr (re-rendered)."""
    if not (view_dir / "view.json").is_file():
        return False
    reason = data.check_view(view_dir)
    if reason is not None:
        print(f"warning: cached view {view_dir} is damaged ({reason}); re-rendering it", file=sys.stderr)
    return reason is None


def _progress(items, enabled: bool, label: str):
    if not enabled:
        yield from items
        return
    from rich.progress import track

    yield from track(items, description=label)
