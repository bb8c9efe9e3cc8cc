"""Training recipes: what ``train`` does differently for each trainable detector.

A trainable detector is its inference file (``fenestra/pipeline/detectors/<arch>.py``), its registry line
(``pipeline.detectors.trainable(...)`` in ``pipeline.detectors.DETECTORS``, which names the arch, the
shipped weights file and the training config) and its recipe here, ``fenestra/training/recipes/<arch>.py``,
which defines ``RECIPE``. There is no list of recipes: the registry's trainable detectors name the
archs (:func:`trainable_archs`) and :func:`recipe` imports the module of that name.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from fenestra.pipeline.detectors import trainable_archs as archs


@dataclass(frozen=True)
class Recipe:
    """build(cfg) -> (model, optimizer); batch(data, cfg, rng) -> one augmented batch on the CPU (data:
    training.train.load_views' list); losses(model, batch, cfg) -> {part: scalar tensor, ...,
    "loss": their sum}, the batch moved to cfg.device; checkpoint(model, cfg) -> the weights file's
    architecture keys ("arch", its parameters, "state_dict"), which the detector's
    ``model_from_checkpoint`` reads back; check(cfg): ValueError for a TrainConfig this
    architecture cannot train (None: any)."""

    build: Callable
    batch: Callable
    losses: Callable
    checkpoint: Callable
    check: Callable | None = None


def trainable_archs() -> list[str]:
    """The archs of the registered trainable detectors (pipeline.detectors.DETECTORS)."""

    return archs()


def recipe(arch: str) -> Recipe:
    """The RECIPE of fenestra/training/recipes/<arch>.py; ValueError naming the trainable archs otherwise."""
    if arch not in trainable_archs():
        raise ValueError(f"arch must be one of {tuple(trainable_archs())}, got {arch!r}")
    return importlib.import_module(f"fenestra.training.recipes.{arch}").RECIPE
