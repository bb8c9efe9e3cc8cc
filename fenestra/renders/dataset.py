"""The dataset writer: sampled views of a scene rendered to the DESIGN.md data contract.

    out/renders/<scene>-<renderer>-<hash>/
        config.json  sampling.json  coco.json
        views/000000/image.png  instances.png (16-bit)  [ignore.png (16-bit)]  view.json

The folder name is a hash of the config that changes the output (scene sha256, sampler config,
renderer + settings (the look and whether it is drawn per view), sensor config, seed, number of
views) and FORMAT_VERSION, so re-running a
config reuses the views already there. The renderers' code is not hashed: a change to what a
backend draws must bump FORMAT_VERSION (or the cached views are reused as they are). Ignore
regions (renders.gt: curtain-wall glazing, glazed doors) came later without a bump: every view.json
now lists ``ignore`` (maybe empty); a cached view without the key gets them from the occluder pass
alone (ignore.png and view.json added, image and instances untouched: they are the same).
Looks: ``settings.look_per = "set"`` draws one look from the seed for every view (as
always); ``"view"`` gives each view its own look, drawn from its own stream (:func:`view_settings`),
rendered by a renderer built for that look, and recorded in its view.json (``look``). Python API:
:func:`render_dataset`; read a view with fenestra.rendered_view.read_view.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fenestra import files, outputs
from fenestra.coco import coco_ground_truth
from fenestra.rendered_view import View, check_view, read_meta, read_view, view_annotations, write_ignore, write_view
from fenestra.checks import INSTANCE_DTYPE
from fenestra.conventions import LIMITS
from fenestra.renders.backends import RENDERERS, make_renderer, occluder_visibility, visibility_function
from fenestra.renders.base import RenderSettings
from fenestra.renders.sampler import SamplerConfig, ViewSpec, iter_views
from fenestra.renders.sensor import SensorConfig, apply_sensor
from fenestra.scenes.model import Scene
from fenestra.scenes import load_scene
from fenestra.renders.camera import Camera
from rich.progress import track

FORMAT_VERSION = 2  # 2: GL raster backend rewrite (shader shadows, per-pixel sky, FXAA default)
LOOK_STREAM = 0x6C6F6F6B  # "look": a per-view look's stream, [seed, view, LOOK_STREAM] (the sensor's is [seed, view])


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
        LIMITS.check("max_views_per_dataset", self.n_views, "n_views (views of one dataset)")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")
        if self.renderer not in RENDERERS:
            raise ValueError(f"unknown renderer {self.renderer!r}; choose one of {sorted(RENDERERS)}")


def config_hash(config: DatasetConfig, scene: Scene) -> str:
    """12 hex digits identifying the output of (config, scene); out_root excluded.

    ``settings.denoise`` counts only for mitsuba and only when not "none", so the folders of raster
    datasets and of undenoised mitsuba ones keep the names they had before the option existed;
    likewise ``settings.look`` counts only when not "classic" and ``settings.look_per`` only when
    not "set" (a look drawn per view changes every view: another folder).
    """
    d = dataclasses.asdict(config)
    d.pop("out_root")
    if config.renderer != "mitsuba" or config.settings.denoise == "none":
        d["settings"].pop("denoise")
    if config.settings.look == "classic":
        d["settings"].pop("look")
    if config.settings.look_per == "set":
        d["settings"].pop("look_per")
    d["settings"]["seed"] = config.seed
    d["scene_sha256"] = scene.sha256
    d["format"] = FORMAT_VERSION
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=list).encode()).hexdigest()[:12]


def view_settings(config: DatasetConfig, i: int) -> RenderSettings:
    """The render settings of view ``i``: ``config.settings`` whose ``seed`` (what the renderers draw
    the look from, and mitsuba its samples) is the dataset's seed when the look is drawn per set, and
    with ``look_per = "view"`` an int drawn from view ``i``'s own stream
    ``SeedSequence([config.seed, i, LOOK_STREAM])``: every view its own look, the same on every run."""
    if config.settings.look_per == "set":
        return dataclasses.replace(config.settings, seed=config.seed)
    seed = int(np.random.SeedSequence([config.seed, i, LOOK_STREAM]).generate_state(1, np.uint32)[0])
    return dataclasses.replace(config.settings, seed=seed)


def dataset_dir(config: DatasetConfig, scene: Scene) -> Path:
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in scene.name)
    return Path(config.out_root) / f"{safe}-{config.renderer}-{config_hash(config, scene)}"


def coco_from_views(root: Path, n_views: int, known: dict[int, tuple[tuple, list[dict]]] | None = None) -> dict:
    """coco.json of the views under root/views (image ids from 0): fenestra.rendered_view.view_annotations
    of each view (RLE masks, COCO boxes; ignore regions as ``iscrowd`` annotations).

    known: view index -> :func:`view_coco` of the views this run wrote (from the arrays it wrote,
    which read back the same: PNG is lossless); the other views are read from their files."""
    known = known or {}
    images, anns = [], []
    for i in range(n_views):
        image, ann = known[i] if i in known else view_coco(i, read_view(root / "views" / f"{i:06d}"))
        images.append(image)
        anns += ann
    return coco_ground_truth(images, anns, first_image_id=0)


def view_coco(i: int, view: View) -> tuple[tuple[str, int, int], list[dict]]:
    """View ``i``'s coco.json image entry (key, height, width) and annotations."""
    key = f"views/{i:06d}/image.png"
    return (key, view.meta["height"], view.meta["width"]), view_annotations(view, key)


def _load_scene(config: DatasetConfig) -> Scene:

    return load_scene(config.scene)


def render_dataset(config: DatasetConfig, scene: Scene | None = None, progress: bool = True,
                   only: range | None = None) -> Path:
    """Render (or reuse) the dataset of ``config``; return its folder.

    Views already written by an earlier run of the same config are kept, missing ones rendered.
    only: render just these view indices (a shard of a distributed run: the views are identical to
    those of a whole run); the dataset-wide files (coco.json, stats.json) are then left to a
    later call without ``only``.

    Each view is rendered as soon as the sampler accepts it, so that the occluder pass its
    visibility test drew gives the view's ground truth (renders.raster.OccluderPass.truth), and
    written by a background thread (PNG encoding) while the next one renders.
    """
    scene = _load_scene(config) if scene is None else scene
    root = dataset_dir(config, scene)
    indices = range(config.n_views) if only is None else only
    if indices.start < 0 or indices.stop > config.n_views:
        raise ValueError(f"only={indices} is outside the dataset's views 0..{config.n_views - 1}")
    claim_dataset(config, scene, root)
    root.mkdir(parents=True, exist_ok=True)
    files.write_text(root / "config.json", json.dumps({"config": dataclasses.asdict(config), "scene": scene.name,
                                                  "scene_sha256": scene.sha256}, indent=1, default=list))
    missing = [i for i in indices if not _reusable(root / "views" / f"{i:06d}")]
    stats = {"rendered": 0, "reused": config.n_views - len(missing), "seconds": 0.0}
    todo = set(missing)
    stale = [i for i in indices if i not in todo and "ignore" not in read_meta(root / "views" / f"{i:06d}")]
    if stale:
        add_ignore_regions(scene, [root / "views" / f"{i:06d}" for i in stale])
        stats["ignore_added"] = len(stale)
    known: dict[int, tuple[tuple, list[dict]]] = {}
    if missing:
        t0 = time.perf_counter()
        per_view = config.settings.look_per == "view"
        renderer = make_renderer(config.renderer, scene, view_settings(config, 0) if per_view else
                                 dataclasses.replace(config.settings, seed=config.seed))
        try:
            vis = None
            if config.sampler.min_visible_fraction > 0:  # per view: the occluder pass alone (no RGB of another look)
                vis = (functools.partial(occluder_visibility, renderer) if per_view else
                       visibility_function(config.renderer, renderer))
            with ViewWriter() as writer:
                last = None
                for last in _progress(iter_views(scene, config.sampler, config.n_views, config.seed, visibility=vis),
                                      progress, f"render {scene.name} ({config.renderer})", config.n_views):
                    if last.index in todo:
                        writer.submit(last.index, root / "views" / f"{last.index:06d}",
                                      render_view(renderer, config, scene, last.index, last.view) if not per_view
                                      else render_own_look(config, scene, last.index, last.view, renderer))
                known = writer.results()
            files.write_text(root / "sampling.json", json.dumps({"rejected": last.rejected, "tries": last.tries,
                                                            "accepted": config.n_views}, indent=1))
            stats["seconds"] = time.perf_counter() - t0
            stats["rendered"] = len(missing)
        finally:
            renderer.close()
    if only is None:
        files.write_text(root / "coco.json", json.dumps(coco_from_views(root, config.n_views, known)))
        files.write_text(root / "stats.json", json.dumps(stats))
        record_dataset(root, [*missing, *stale])
    return root


KIND = "dataset"  # the kind of output a dataset folder is (fenestra.outputs.KINDS)
DATASET_FILES = ("config.json", "sampling.json", "coco.json", "stats.json")  # rewritten whole by a render


def _same_config(root: Path, config: DatasetConfig, scene: Scene) -> bool:
    """True if ``root/config.json`` says this config and scene rendered it (out_root aside): a
    dataset an older Fenestra rendered, before dataset folders listed their files."""
    want = json.loads(json.dumps(dataclasses.asdict(config), default=list))
    try:
        doc = json.loads((root / "config.json").read_bytes())
        have = dict(doc["config"])
    except (OSError, ValueError, KeyError, TypeError):
        return False
    want.pop("out_root")
    have.pop("out_root", None)
    return have == want and doc.get("scene_sha256") == scene.sha256


def claim_dataset(config: DatasetConfig, scene: Scene, root: Path, option: str = "--out") -> None:
    """OwnershipError (one line) unless ``root`` (the config's dataset folder) may receive this
    render (fenestra.outputs' rule): ``config.out_root`` is a folder (or none yet) that neither
    holds nor lies inside another kind of output (a bench run, a reconstruction; a folder of loose
    files may hold datasets); ``root`` is new, or a dataset whose manifest lists its top-level
    files (DATASET_FILES) as they are, or (an older Fenestra's, no manifest) one whose config.json
    is this config's. A view's files are recognised by their names in a dataset of this config."""
    out_root = Path(config.out_root)
    if out_root.exists() and not out_root.is_dir():
        raise outputs.OwnershipError(f"{option} {out_root} is an existing file, not a folder")
    outputs.check_kind(out_root, KIND, option, hosts=(outputs.FILES_KIND,))
    if not root.is_dir():
        return
    outputs.check_kind(root, KIND, option)
    if outputs.read_manifest(root) is not None:  # config.json names out_root: this config's under another spelling is ours
        same = _same_config(root, config, scene)
        outputs.check_names(root, [n for n in DATASET_FILES if not (same and n == "config.json")], option)
    elif outputs.files_in(root) and not _same_config(root, config, scene):
        raise outputs.OwnershipError(f"{option} {out_root}: {root.name} holds files Fenestra did not render for this "
                                     "config; move them away or choose another folder")


def record_dataset(root: Path, touched: list[int]) -> None:
    """List in ``root``'s manifest (kind KIND) its top-level files, the files of the views
    ``touched`` (rendered or completed now) and any file not listed yet: the next render checks
    them (:func:`claim_dataset`)."""
    owned = outputs.read_manifest(root) or {}
    views = {f"views/{i:06d}/" for i in touched}
    names = [f for f in outputs.files_in(root) if f not in owned or f in DATASET_FILES or f[:13] in views]
    outputs.record(root, names, kind=KIND)


def render_view(renderer, config: DatasetConfig, scene: Scene, i: int, spec: ViewSpec) -> View:
    """View ``i`` (sampled as ``spec``) rendered: its files' contents as fenestra.rendered_view.read_view
    reads them back (image RGB, instances int32, view.json dict without ``files``, ignore map or None)."""
    out = renderer.render(spec.camera)
    if config.sensor.active:
        rgb = apply_sensor(out.rgb, config.sensor, np.random.default_rng([config.seed, i]))
        out = dataclasses.replace(out, rgb=rgb)
    meta = {**spec.camera.to_dict(), "renderer": config.renderer, "seed": config.seed, "view_index": i,
            "mode": spec.mode, "targets": list(spec.targets), "scene": scene.name,
            "scene_sha256": scene.sha256, "windows": [w.to_dict() for w in out.windows],
            "ignore": list(out.ignore_regions)}
    ignore = None if out.ignore is None else out.ignore.astype(INSTANCE_DTYPE)
    return View(out.rgb, out.instances.astype(INSTANCE_DTYPE), meta, ignore)


def render_own_look(config: DatasetConfig, scene: Scene, i: int, spec: ViewSpec, like=None) -> View:
    """View ``i`` rendered in its own look (``look_per = "view"``): a renderer built for
    :func:`view_settings` of the view (the look is baked into its geometry, textures and shadow
    map), closed after it; the look drawn goes to view.json (``look``). like: the dataset's renderer
    (the sampler's), whose look-free parts it shares (renders.backends.make_renderer): its occluder
    pass, whose ground truth of the view the sampler's visibility test drew, is then not drawn again."""
    renderer = make_renderer(config.renderer, scene, view_settings(config, i), like)
    try:
        view = render_view(renderer, config, scene, i, spec)
        view.meta["look"] = {"seed": renderer.settings.seed, **dataclasses.asdict(renderer.look)}
        return view
    finally:
        renderer.close()


class ViewWriter:
    """Writes views (fenestra.rendered_view.write_view) on one background thread, in submission order, at
    most ``depth`` pending (bounded memory), and keeps each written view's :func:`view_coco`.
    A failed write raises from the next submit() or from results(); use as a context manager
    (leaving it waits for the pending writes)."""

    def __init__(self, depth: int = 2):

        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="view-writer")
        self._pending: list = []
        self._depth = depth
        self._done: dict[int, tuple[tuple, list[dict]]] = {}

    def submit(self, i: int, view_dir: Path, view: View) -> None:
        while len(self._pending) >= self._depth:
            self._finish_one()
        self._pending.append((i, self._pool.submit(_write_view, i, view_dir, view)))

    def _finish_one(self) -> None:
        i, fut = self._pending.pop(0)
        self._done[i] = fut.result()

    def results(self) -> dict[int, tuple[tuple, list[dict]]]:
        """Wait for every pending write; view index -> view_coco of each view written."""
        while self._pending:
            self._finish_one()
        return dict(self._done)

    def __enter__(self) -> "ViewWriter":
        return self

    def __exit__(self, *exc) -> None:
        self._pool.shutdown(wait=True)


def _write_view(i: int, view_dir: Path, view: View) -> tuple[tuple, list[dict]]:
    write_view(view_dir, view.image, view.instances, view.meta, ignore=view.ignore)
    return view_coco(i, view)


def add_ignore_regions(scene: Scene, view_dirs: list[Path]) -> None:
    """Give views rendered before the renderers drew ignore regions their ignore.png and view.json
    ``ignore`` list, from the exact occluder pass of each view's camera (no RGB rendering)."""
    from fenestra.renders.raster import OccluderPass, ground_truth  # noqa: PLC0415 - GL

    occ = OccluderPass(scene)
    try:
        for d in view_dirs:
            _, _, _, (ign, regions) = ground_truth(occ, Camera.from_dict(read_meta(d)))
            write_ignore(d, ign, regions)
    finally:
        occ.close()


def _reusable(view_dir: Path) -> bool:
    """True if the cached view can be reused; a broken one is reported on stderr (re-rendered)."""
    if not (view_dir / "view.json").is_file():
        return False
    reason = check_view(view_dir)
    if reason is not None:
        print(f"warning: cached view {view_dir} is damaged ({reason}); re-rendering it", file=sys.stderr)
    return reason is None


def _progress(items, enabled: bool, label: str, total: int | None = None):
    if not enabled:
        yield from items
        return

    yield from track(items, description=label, total=total)
