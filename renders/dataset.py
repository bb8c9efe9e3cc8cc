"""The dataset writer: sampled views of a scene rendered to the DESIGN.md data contract.

    out/renders/<scene>-<renderer>-<hash>/
        config.json  sampling.json  coco.json
        views/000000/image.png  instances.png (16-bit)  view.json

The folder name is a hash of the config that changes the output (scene sha256, sampler config,
renderer + settings, sensor config, seed, number of views) and FORMAT_VERSION, so re-running a
config reuses the views already there. The renderers' code is not hashed: a change to what a
backend draws must bump FORMAT_VERSION (or the cached views are reused as they are). Python API: :func:`render_dataset`, :func:`load_view`.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from renders.backends import RENDERERS, make_renderer, visibility_function
from renders.base import RenderOutput, RenderSettings
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


def write_file_atomic(path: Path, write) -> None:
    """Call ``write(tmp_path) -> bool`` on a temporary name beside ``path``, then rename it over
    ``path``; an OSError naming the file when the writer reports failure or raises."""
    tmp = path.with_name(f".{path.stem}.tmp{os.getpid()}{path.suffix}")
    try:
        ok = write(tmp)
        if ok is False or not tmp.is_file():
            raise OSError(f"cannot write {path} (disk full or not writable?)")
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


def _write_text(path: Path, text: str) -> None:
    write_file_atomic(path, lambda p: p.write_text(text) == len(text))


def _imwrite(img: np.ndarray):
    return lambda p: bool(cv2.imwrite(str(p), img))


def write_view(view_dir: Path, out: RenderOutput, meta: dict) -> None:
    """Write image.png, instances.png (16-bit) and view.json of one view.

    Every file goes to a temporary name first and is renamed into place; view.json, the view's
    completion marker, comes last and records the image size and each PNG's byte size (checked
    on reuse by :func:`check_view`). Any failed write raises OSError naming the file.
    """
    view_dir.mkdir(parents=True, exist_ok=True)
    (view_dir / "view.json").unlink(missing_ok=True)  # not complete until rewritten last
    files = {"image.png": out.rgb[..., ::-1], "instances.png": out.instances.astype(np.uint16)}
    for name, img in files.items():
        write_file_atomic(view_dir / name, _imwrite(img))
    meta = {**meta, "files": {name: (view_dir / name).stat().st_size for name in files}}
    _write_text(view_dir / "view.json", json.dumps(meta, indent=1))


def check_view(view_dir: Path) -> str | None:
    """Why a cached view folder cannot be reused (None if it can): view.json missing or unreadable,
    a PNG missing, of another byte size than recorded, or not decodable at the recorded size."""
    try:
        meta = json.loads((view_dir / "view.json").read_text())
    except FileNotFoundError:
        return "no view.json"
    except (OSError, ValueError) as e:
        return f"unreadable view.json ({e})"
    sizes = meta.get("files", {})
    for name, flag in (("image.png", cv2.IMREAD_COLOR), ("instances.png", cv2.IMREAD_UNCHANGED)):
        p = view_dir / name
        if not p.is_file():
            return f"{name} missing"
        if name in sizes and p.stat().st_size != sizes[name]:
            return f"{name} is {p.stat().st_size} bytes, view.json recorded {sizes[name]}"
        img = cv2.imread(str(p), flag)
        if img is None or img.shape[:2] != (meta.get("height"), meta.get("width")):
            return f"{name} does not decode to {meta.get('width')}x{meta.get('height')} px"
    return None


def load_view(view_dir: str | Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """(image (H, W, 3) uint8 RGB, instances (H, W) uint16, view.json dict) of one view folder."""
    view_dir = Path(view_dir)
    if not (view_dir / "view.json").is_file():
        raise FileNotFoundError(f"{view_dir}: no view.json (not a rendered view folder)")
    img = cv2.imread(str(view_dir / "image.png"), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(f"{view_dir / 'image.png'}: missing or not decodable (delete the view to re-render it)")
    inst = cv2.imread(str(view_dir / "instances.png"), cv2.IMREAD_UNCHANGED)
    if inst is None or inst.dtype != np.uint16:
        raise ValueError(f"{view_dir / 'instances.png'}: expected a 16-bit PNG")
    return img[..., ::-1].copy(), inst, json.loads((view_dir / "view.json").read_text())


def coco_from_views(root: Path, n_views: int) -> dict:
    """COCO instance annotations (RLE masks) of the views under root/views."""
    from pycocotools import mask as mask_utils

    images, anns = [], []
    for i in range(n_views):
        vdir = root / "views" / f"{i:06d}"
        _, inst, meta = load_view(vdir)
        images.append({"id": i, "file_name": f"views/{i:06d}/image.png", "width": meta["width"], "height": meta["height"]})
        for w in meta["windows"]:
            m = inst == w["instance_id"]
            if not m.any():
                continue
            rle = mask_utils.encode(np.asfortranarray(m.astype(np.uint8)))
            bbox = mask_utils.toBbox(rle).tolist()
            rle["counts"] = rle["counts"].decode("ascii")
            anns.append({"id": len(anns) + 1, "image_id": i, "category_id": 1, "segmentation": rle,
                         "area": float(m.sum()), "bbox": bbox, "iscrowd": 0, "window_id": w["id"],
                         "visible_fraction": w["visible_fraction"]})
    return {"images": images, "annotations": anns, "categories": [{"id": 1, "name": "window"}]}


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
    _write_text(root / "config.json", json.dumps({"config": dataclasses.asdict(config), "scene": scene.name,
                                                  "scene_sha256": scene.sha256}, indent=1, default=list))
    missing = [i for i in indices if not _reusable(root / "views" / f"{i:06d}")]
    stats = {"rendered": 0, "reused": config.n_views - len(missing), "seconds": 0.0}
    if missing:
        settings = dataclasses.replace(config.settings, seed=config.seed)
        renderer = make_renderer(config.renderer, scene, settings)
        try:
            vis = visibility_function(config.renderer, renderer) if config.sampler.min_visible_fraction > 0 else None
            sampling = sample_views(scene, config.sampler, config.n_views, config.seed, visibility=vis)
            _write_text(root / "sampling.json", json.dumps({"rejected": sampling.rejected, "tries": sampling.tries,
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
                        "scene_sha256": scene.sha256, "windows": [w.to_dict() for w in out.windows]}
                write_view(root / "views" / f"{i:06d}", out, meta)
            stats["seconds"] = time.perf_counter() - t0
            stats["rendered"] = len(missing)
        finally:
            renderer.close()
    if only is None:
        _write_text(root / "coco.json", json.dumps(coco_from_views(root, config.n_views)))
        _write_text(root / "stats.json", json.dumps(stats))
    return root


def _reusable(view_dir: Path) -> bool:
    """True if the cached view can be reused; a broken one is reported on stderr (re-rendered)."""
    if not (view_dir / "view.json").is_file():
        return False
    reason = check_view(view_dir)
    if reason is not None:
        print(f"warning: cached view {view_dir} is damaged ({reason}); re-rendering it", file=sys.stderr)
    return reason is None


def _progress(items, enabled: bool, label: str):
    if not enabled:
        yield from items
        return
    from rich.progress import track

    yield from track(items, description=label)
