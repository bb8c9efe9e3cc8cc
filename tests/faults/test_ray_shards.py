"""A bench run on the Ray executor, on a live local Ray cluster (the executor's own
``ray.init(num_cpus=1)``: one worker CPU), lists every shard file in its run folder's manifest
as the shards are written; after a shard's entries are gone from the manifest (a driver killed
between a shard's end and its listing), the next run of the profile recognises the shard by
name and digest and reuses it, computing nothing again.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py). Two
shards of two views of the smoke house, one method, one Ray start (the second run finds every
shard and starts no Ray): 7 CPU seconds in the test's process, under two minutes of wall time on
a shared 2-core machine, most of it Ray's start. Not marked slow, as the Ray executor's own tests
(tests/test_bench_executors.py) are not.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from fenestra import outputs
from fenestra.bench.executors import SHARD_DIR
from fenestra.bench.profiles import load_profile
from fenestra.bench.runner import run_benchmark
from fenestra.files import file_sha256, write_json
from fenestra.methods import Method


def _run(tmp_path: Path):
    p = load_profile("smoke")
    src = p.source
    profile = dataclasses.replace(p, source=dataclasses.replace(src, render=dataclasses.replace(src.render, views_per_house=4)))
    return run_benchmark(profile, out_dir=tmp_path / "run", workers=1, progress=False, report=False,
                         methods=(Method("oracle", "none", "lm"),), renders_dir=tmp_path / "renders",
                         executor="ray", executor_options={"shard_views": 2})


def _stage(run: Path) -> dict:
    return json.loads((run / "summary.json").read_text())["metadata"]["stage_time_s"]


def test_a_ray_run_lists_its_shards_and_recognises_an_unlisted_one_by_digest(tmp_path):
    _run(tmp_path)
    run = tmp_path / "run"
    shards = sorted(p.relative_to(run).as_posix() for p in (run / SHARD_DIR).iterdir())
    assert len(shards) == 4 and {Path(s).suffix for s in shards} == {".json", ".parquet"}  # two shards, two files each
    listed = outputs.read_manifest(run)
    assert {s: listed.get(s) for s in shards} == {s: file_sha256(run / s) for s in shards}
    assert _stage(run)["shards_reused"] == 0

    before = {s: (run / s).read_bytes() for s in shards}
    doc = json.loads((run / outputs.MANIFEST).read_text())
    for s in shards[:2]:  # one shard's index and rows: written, never listed
        del doc["files"][s]
    write_json(run / outputs.MANIFEST, doc)
    _run(tmp_path)
    assert _stage(run)["shards_reused"] == 2  # both shards recognised: nothing computed again
    assert {s: (run / s).read_bytes() for s in shards} == before
    listed = outputs.read_manifest(run)
    assert {s: listed.get(s) for s in shards} == {s: file_sha256(run / s) for s in shards}
