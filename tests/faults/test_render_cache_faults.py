"""The render cache: a full disk, a poisoned view or a SIGTERM mid-render is resumed, never trusted.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import signal
import subprocess
import sys
import time

from fault_helpers import (RENDER_ARGS, env, fenestra, one_line_error, view_dirs)


# ---------------------------------------------------------------- 2. the render cache

def test_disk_full_mid_render_then_resume(tmp_path):
    r = fenestra(*RENDER_ARGS, cwd=tmp_path, limit_bytes=5_000)  # a 160x120 render PNG is larger (~26 kB)
    one_line_error(r, "cannot write", "image.png")
    assert not list(tmp_path.glob("out/renders/*/views/*/view.json"))  # no view counts as done
    assert not list(tmp_path.glob("out/renders/**/.*tmp*"))  # no temporary file left
    r = fenestra(*RENDER_ARGS, cwd=tmp_path)
    assert r.returncode == 0 and "3 views rendered, 0 reused" in r.stdout, r.stderr[-2000:]


def test_poisoned_cache_is_rerendered_with_a_message(tmp_path):
    assert fenestra(*RENDER_ARGS, cwd=tmp_path).returncode == 0
    v0, v1, v2 = view_dirs(tmp_path)
    good = (v0 / "image.png").read_bytes()
    (v0 / "image.png").write_bytes(good[: len(good) // 2])  # truncated
    (v1 / "image.png").unlink()  # view.json without its image
    (v2 / "instances.png").write_bytes(b"not a png")
    r = fenestra(*RENDER_ARGS, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "3 views rendered, 0 reused" in r.stdout
    for v in (v0, v1, v2):
        assert f"cached view {v.relative_to(tmp_path)} is damaged" in r.stderr
    assert (v0 / "image.png").read_bytes() == good  # renders are deterministic
    r = fenestra(*RENDER_ARGS, cwd=tmp_path)
    assert "0 views rendered, 3 reused" in r.stdout and "damaged" not in r.stderr


def test_sigterm_mid_render_then_resume(tmp_path):
    args = [*RENDER_ARGS[:2], "40", *RENDER_ARGS[3:]]
    p = subprocess.Popen([sys.executable, "-m", "fenestra", *args], cwd=tmp_path, env=env(),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not list(tmp_path.glob("out/renders/*/views/000001/view.json")) and time.time() < deadline:
        time.sleep(0.02)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 128 + signal.SIGTERM, err[-2000:]
    done = len(list(tmp_path.glob("out/renders/*/views/*/view.json")))
    assert 2 <= done < 40
    assert not list(tmp_path.glob("out/renders/**/.*tmp*"))
    r = fenestra(*args, cwd=tmp_path)
    assert r.returncode == 0 and f"{40 - done} views rendered, {done} reused" in r.stdout, r.stderr[-2000:]


def test_negative_seed_leaves_no_folder(tmp_path):
    one_line_error(fenestra(*RENDER_ARGS, "--seed", "-5", cwd=tmp_path), "seed must be >= 0, got -5")
    assert not (tmp_path / "out").exists()
