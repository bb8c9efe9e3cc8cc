"""The Ray executor on a real local Ray cluster gives the local executor's results table, bit for bit.

The cluster is two Ray node processes started with the `ray` CLI (a head and one more worker node,
one CPU each), as a user would start a cluster; the bench connects to it by address. Views of the
smoke house are rendered inside the Ray actors (shards of 2 views) into a render cache of their
own, so rendering is distributed too, and the table must equal the local process pool's.
"""
from __future__ import annotations

import dataclasses
import os
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from fenestra.methods import Method
from fenestra.bench.executors import EXECUTORS, plan_shards
from fenestra.bench.profiles import load_profile
from fenestra.bench.results import load_results
from fenestra.bench.runner import make_plan, run_benchmark
from fenestra.errors import FenestraError

METHODS = (Method("oracle", "none", "lm"), Method("oracle-degraded", "hough", "ippe"),
           Method("default", "linefit", "lm"))


def _profile():
    p = load_profile("smoke")
    return dataclasses.replace(p, source=dataclasses.replace(p.source, render=dataclasses.replace(p.source.render,
                                                                                                 views_per_house=6)))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def ray_cluster():
    ray_cli = str(Path(sys.executable).with_name("ray"))
    env = {**os.environ, "RAY_AUTH_MODE": "disabled", "RAY_USAGE_STATS_ENABLED": "0"}
    port = _free_port()
    # a short folder of its own: Ray's socket paths (<temp>/session_<date>_<pid>/sockets/plasma_store.1)
    # must fit AF_UNIX's 107 bytes, which a pytest-xdist worker's tmp_path (.../popen-gw1/ray0) exceeds
    temp = Path(tempfile.mkdtemp(prefix="ray-", dir="/tmp"))
    head = [ray_cli, "start", "--head", "--node-ip-address=127.0.0.1", f"--port={port}", "--num-cpus=1",
            "--include-dashboard=false", "--disable-usage-stats", f"--temp-dir={temp}"]
    worker = [ray_cli, "start", f"--address=127.0.0.1:{port}", "--num-cpus=1", "--disable-usage-stats"]
    try:
        for cmd in (head, worker):
            subprocess.run(cmd, env=env, check=True, capture_output=True, timeout=120)
        yield f"127.0.0.1:{port}"
    finally:
        subprocess.run([ray_cli, "stop", "--force"], env=env, capture_output=True, timeout=120)
        shutil.rmtree(temp, ignore_errors=True)


def test_ray_cluster_matches_local_executor(ray_cluster, tmp_path, monkeypatch):
    import ray

    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    local = run_benchmark(_profile(), out_dir=tmp_path / "local", workers=2, progress=False, report=False,
                          methods=METHODS, renders_dir=tmp_path / "renders-local")
    remote = run_benchmark(_profile(), out_dir=tmp_path / "ray", workers=2, progress=False, report=False,
                           methods=METHODS, renders_dir=tmp_path / "renders-ray", executor="ray",
                           executor_options={"address": ray_cluster, "shard_views": 2})
    assert not ray.is_initialized()  # the executor disconnects after the run
    a, b = load_results(local.run_dir), load_results(remote.run_dir)
    assert len(a) == len(b) > 0 and a["evaluable"].sum() > 0
    assert a.equals(b)
    # the shards rendered every view into their own cache: the same images as the local renders
    la = sorted((tmp_path / "renders-local").rglob("image.png"))
    lb = sorted((tmp_path / "renders-ray").rglob("image.png"))
    assert len(la) == len(lb) == 6
    assert all(x.read_bytes() == y.read_bytes() for x, y in zip(la, lb))
    # resumable: a rerun reuses every shard written by the first one, and gives the same table
    again = run_benchmark(_profile(), out_dir=tmp_path / "ray", workers=2, progress=False, report=False,
                          methods=METHODS, renders_dir=tmp_path / "renders-ray", executor="ray",
                          executor_options={"address": ray_cluster, "shard_views": 2})
    assert again.stage_time_s["shards_reused"] == 3
    assert load_results(again.run_dir).equals(a)


def test_shards_cover_every_view_once(tmp_path):
    plan = make_plan(_profile(), METHODS, tmp_path / "renders", tmp_path / "run")
    for size in (1, 4, 6, 50):
        shards = plan_shards(plan, size)
        views = [v for s in shards for v in s.views]
        assert views == list(range(6)), size
        assert len({s.out for s in shards}) == len(shards)  # one file per shard
    with pytest.raises(ValueError, match="shard_views must be >= 1, got 0"):
        plan_shards(plan, 0)


def test_unknown_executor_is_named(tmp_path):
    assert set(EXECUTORS) == {"local", "ray"}
    with pytest.raises(FenestraError, match="unknown executor 'spark'.*local.*ray"):
        run_benchmark(_profile(), out_dir=tmp_path / "x", methods=METHODS, executor="spark",
                      renders_dir=tmp_path / "r", progress=False, report=False)


def _shard_worker_pids() -> list[int]:
    """PIDs of the processes running a Ray _ShardWorker actor (Ray names them in their cmdline)."""
    pids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                cmd = (d / "cmdline").read_bytes()
            except OSError:
                continue
            if b"_ShardWorker" in cmd:
                pids.append(int(d.name))
    return pids


def test_a_killed_ray_worker_is_retried_once(ray_cluster, tmp_path, monkeypatch, capsys):
    """A worker killed mid-run (SIGKILL, as the OOM killer would): its shard runs again on a new
    worker, with a warning naming it, and the table equals the local executor's."""
    import signal
    import threading
    import time

    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    killed: list[int] = []
    stale = set(_shard_worker_pids())  # an earlier test's actors, on their way out

    def kill_one() -> None:
        deadline = time.monotonic() + 120
        while not killed and time.monotonic() < deadline:
            pids = [p for p in _shard_worker_pids() if p not in stale]
            if pids:
                time.sleep(1.0)  # let it start on a shard
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])
            time.sleep(0.05)

    killer = threading.Thread(target=kill_one, daemon=True)
    killer.start()
    remote = run_benchmark(_profile(), out_dir=tmp_path / "ray", workers=2, progress=False, report=False,
                           methods=METHODS[:2], renders_dir=tmp_path / "renders-ray", executor="ray",
                           executor_options={"address": ray_cluster, "shard_views": 2})
    killer.join()
    assert killed, "no Ray worker was found to kill"
    err = capsys.readouterr().err
    assert "its Ray worker died" in err and "running it again on a new worker" in err, err[-2000:]
    local = run_benchmark(_profile(), out_dir=tmp_path / "local", workers=2, progress=False, report=False,
                          methods=METHODS[:2], renders_dir=tmp_path / "renders-local")
    assert load_results(remote.run_dir).equals(load_results(local.run_dir))
