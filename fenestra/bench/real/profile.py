"""A profile of labelled photos: which datasets, which methods (``fenestra/bench/profiles/real.toml``); a
bench.profiles.Profile whose ``source`` is :class:`Datasets`.

    name = "real"
    kind = "real"                       # marks a real-photo profile (fenestra bench routes on it)
    detector_long_side = 640            # learned detectors see the photo at this long side
    [detector_options.default]          # build options of a detector, e.g. weights = "out/x.pt"
    min_window_px = 12.0
    data = "PATH"                       # shorthand for one dataset (with format = "coco" | ...)
    [methods]                           # as the synthetic profiles (bench.profiles.MethodsSpec)
    [[datasets]]
    name = "curtainwall"; format = "curtainwall"; path = "data/real/curtainwall"
    optional = false                    # true: skipped (and recorded) when the folder is absent
    kfree_only = false                  # true: measured only by [kfree], not by the method grid
    options = {...}                     # keyword options of the adapter (bench.real.adapters)
    [kfree]                             # optional: the K-free single-photo path (bench.photo_eval.KfreeSpec)
    datasets = ["spb_facades"]          # profile datasets run through pipeline.photo.reconstruct_photo without K
    transform_datasets = ["spb_facades"]  # ... also under transforms (gray, jpeg, exif_rot, mirror, crop)
    max_photos = 0                      # per dataset (0: all); match_iou = 0.3 (export precision)

Relative dataset paths in a profile file are resolved against the repository root (so
``../shared/real`` is the shared folder beside the checkout); paths given on the command line
against the current directory.
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from fenestra.bench.evaluate import EvalOptions
from fenestra.bench.photo_eval import KfreeSpec
from fenestra.bench.profiles import PROFILE_DIR, EvalSpec, MethodsSpec, Profile, ProfileError, check_methods
from fenestra.bench.real.adapters import ADAPTERS
from fenestra.bench.views import LabelledView
from fenestra.config import from_table, read_toml
from fenestra.userfiles import resolved, utf8_name

KIND = "real"


@dataclass(frozen=True)
class DatasetSpec:
    """One labelled dataset: a name, an adapter format (a key of ADAPTERS), a folder, options."""

    name: str
    format: str
    path: str
    optional: bool = False
    options: tuple[tuple[str, Any], ...] = ()
    kfree_only: bool = False  # measured only by [kfree] (bench.photo_eval), not by the method grid

    def folder(self) -> Path:
        """The dataset folder: absolute, or relative to the working directory (as every path a
        command is given; the bundled profiles name folders of a checkout, run from its root)."""
        return Path(os.path.normpath(Path(self.path).expanduser().absolute()))

    def views(self) -> Iterator[LabelledView]:
        """Its LabelledViews, read by its adapter (bench.real.adapters) with its options."""
        return ADAPTERS[self.format](self.folder(), **{"dataset": self.name, **dict(self.options)})


@dataclass(frozen=True)
class Datasets:
    """A profile's views when they are labelled photos (bench.profiles.Profile's ``source``; see
    the module docstring): the datasets, the resolution learned detectors see them at
    (detector_long_side, px; 0: the CLI's), the smallest evaluable window (min_window_px), the
    detectors' build options, and the K-free block ([kfree], bench.photo_eval) or None."""

    datasets: tuple[DatasetSpec, ...]
    detector_long_side: int = 640
    min_window_px: float = 12.0
    detector_options: tuple[tuple[str, tuple[tuple[str, Any], ...]], ...] = ()
    kfree: KfreeSpec | None = None  # [kfree]: the K-free single-photo path measured (bench.photo_eval)

    def to_dict(self) -> dict:
        """Its keys as plain JSON-able values (options as dicts), as in the profile's TOML."""
        d = asdict(self)
        for ds in d["datasets"]:
            ds["options"] = dict(ds["options"])
        d["detector_options"] = {k: dict(v) for k, v in self.detector_options}
        return d

    def eval_options(self, height_m: float) -> EvalOptions:
        """How its views are evaluated (bench.evaluate.EvalOptions): windows below min_window_px
        are not evaluable; learned detectors see photos at detector_long_side; height_m: the
        pose's scale parameter (the profile's methods.height_m)."""
        return EvalOptions(evaluation=EvalSpec(min_window_px=self.min_window_px), height_m=height_m,
                           detector_long_side=self.detector_long_side, detector_options=self.detector_options)

    def kfree_views(self) -> Iterator[LabelledView]:
        """The views of the available datasets [kfree] names (none without [kfree])."""
        names = set(self.kfree.datasets) if self.kfree is not None else set()
        return (v for ds in self.available(kfree=True)[0] if ds.name in names for v in ds.views())

    def available(self, kfree: bool = False) -> tuple[list[DatasetSpec], dict[str, str]]:
        """(datasets whose folder exists, {skipped optional dataset: reason}); FileNotFoundError
        naming a required dataset's missing folder. kfree: include the kfree_only datasets."""
        ok, skipped = [], {}
        for ds in (d for d in self.datasets if kfree or not d.kfree_only):
            if ds.folder().is_dir():
                ok.append(ds)
            elif ds.optional:
                skipped[ds.name] = f"folder {ds.folder()} not present"
            else:
                raise FileNotFoundError(f"dataset {ds.name!r}: folder {ds.folder()} not found")
        return ok, skipped


def _dataset(t: dict, where: str) -> DatasetSpec:
    """DatasetSpec from a TOML table (fenestra.config.from_table); ProfileError naming the bad key or value."""
    if not isinstance(t, dict):
        raise ProfileError(f"{where} must be a table, got {t!r}")
    if t.get("format") not in ADAPTERS:
        raise ProfileError(f"{where}: format {t.get('format')!r} unknown; choose from {sorted(ADAPTERS)}")
    if not isinstance(t.get("path"), str) or not t["path"]:
        raise ProfileError(f"{where}: dataset needs a string 'path', got {t.get('path')!r}")
    return from_table(DatasetSpec, {**t, "name": str(t.get("name") or Path(t["path"]).name)}, where, ProfileError)


def real_profile_from_dict(data: dict, where: str = "profile") -> Profile:
    """A Profile of labelled datasets (source :class:`Datasets`) from a parsed TOML dict;
    ProfileError naming the file, key and value."""
    top = {"name", "kind", "description", "seed", "methods", "datasets", "data", "format",
           "options", "detector_long_side", "min_window_px", "detector_options", "kfree"}
    unknown = sorted(set(data) - top)
    if unknown:
        raise ProfileError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(top)}")
    if data.get("kind") != KIND:
        raise ProfileError(f"{where}: kind must be {KIND!r}, got {data.get('kind')!r}")
    tables = list(data.get("datasets", []))
    if "data" in data:
        tables.append({"path": data["data"], "format": data.get("format", "coco"), "options": data.get("options", {})})
    datasets = tuple(_dataset(t, f"{where} dataset #{i + 1}") for i, t in enumerate(tables))
    if not datasets:
        raise ProfileError(f"{where}: no datasets: give [[datasets]] tables or data = \"PATH\"")
    long_side, min_px = data.get("detector_long_side", 640), data.get("min_window_px", 12.0)
    if not isinstance(long_side, int) or long_side < 0 or not isinstance(min_px, (int, float)) or min_px < 0:
        raise ProfileError(f"{where}: detector_long_side {long_side!r} / min_window_px {min_px!r} must be >= 0")
    dopts = data.get("detector_options", {})
    if not isinstance(dopts, dict) or not all(isinstance(v, dict) for v in dopts.values()):
        raise ProfileError(f"{where}: detector_options must be tables per detector, got {dopts!r}")
    methods = from_table(MethodsSpec, data.get("methods", {}), f"{where} [methods]", ProfileError)
    check_methods(methods, where)
    kfree = _kfree(data.get("kfree"), datasets, where)
    source = Datasets(datasets, long_side, float(min_px),
                      tuple(sorted((k, tuple(sorted(v.items()))) for k, v in dopts.items())), kfree)
    return Profile(str(data.get("name") or "real"), source, str(data.get("description", "")), int(data.get("seed", 0)),
                   methods)


def _kfree(t, datasets: tuple[DatasetSpec, ...], where: str) -> KfreeSpec | None:
    """KfreeSpec from the [kfree] table (None when absent); ProfileError naming a bad key, value or
    a dataset name the profile lacks."""
    if t is None:
        return None
    spec = from_table(KfreeSpec, t, f"{where} [kfree]", ProfileError)
    unknown = sorted(set(spec.datasets) - {d.name for d in datasets})
    if unknown:
        raise ProfileError(f"{where} [kfree]: datasets {unknown} are not datasets of the profile "
                           f"({[d.name for d in datasets]})")
    return spec


def _profile_path(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    return PROFILE_DIR / f"{name_or_path}.toml" if not p.suffix else p


def is_real_profile(name_or_path: str | Path) -> bool:
    """True if the profile file exists and says ``kind = "real"``."""
    p = _profile_path(name_or_path)
    return p.is_file() and read_toml(p, ProfileError, "profile file").get("kind") == KIND


def load_real_profile(name_or_path: str | Path) -> Profile:
    """A real profile by bundled name (``real``) or TOML path."""
    p = _profile_path(name_or_path)
    return real_profile_from_dict(read_toml(p, ProfileError, "profile file"), where=str(p))


def with_user_data(profile: Profile, data: str | Path, fmt: str, options: dict | None = None) -> Profile:
    """The profile's methods on one user dataset instead of its own (``--data DIR --format F``);
    the path is made absolute against the current directory. Its [kfree] block, which names the
    profile's own datasets, is dropped."""
    if fmt not in ADAPTERS:
        raise ProfileError(f"--format {fmt!r} unknown; choose from {sorted(ADAPTERS)}")
    p = resolved(Path(data).expanduser(), f"--data {str(data)!r}")
    utf8_name(p.name, "--data folder")
    ds = DatasetSpec(name=p.name, format=fmt, path=str(p), options=tuple(sorted((options or {}).items())))
    source = replace(profile.source, datasets=(ds,), kfree=None)  # [kfree] names its own datasets
    return replace(profile, name=f"{profile.name}-{p.name}", source=source)
