"""Plug-ins cannot take the CLI down (issue 37: 8).

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fault_helpers import (ROOT, env, fenestra)


# ---------------------------------------------------------------- 8. plug-ins cannot take the CLI down

def plugin(d: Path, code: str, name: str = "badplug") -> Path:
    """An installed plug-in distribution, as pip leaves one (a module and its dist-info with a
    ``fenestra.plugins`` entry point), in d/site: put that folder on PYTHONPATH."""
    site = d / "site"
    info = site / f"{name}-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[fenestra.plugins]\n{name} = {name}\n")
    (site / f"{name}.py").write_text(code)
    return site


ENTRY = 'class E:\n    name = "lsd"\n    description = "a plug-in lsd"\n'
# (case, the plug-in's code, the one warning line's needles): `fenestra --version` still prints the
# version and exits 0, with that one warning line naming the plug-in, and the built-in 'lsd' stays
PLUGINS = [
    ("raises at import", 'raise ImportError("no module named fancy")\n',
     ["fenestra plug-in 'badplug' (badplug) failed to load and is ignored: ImportError: no module named fancy"]),
    ("calls sys.exit(0) at import", "import sys\nsys.exit(0)\n", ["'badplug'", "it called sys.exit(0)"]),
    ("raises its own BaseException subclass with a long message", 'class Boom(BaseException):\n    pass\n'
     'raise Boom("x" * 100000)\n', ["'badplug'", "failed to load and is ignored: Boom: xxx", "... (100000 characters)"]),
    ("registers a built-in's name", "from fenestra.pipeline.snappers import SNAPPERS\n" + ENTRY + "SNAPPERS.register(E())\n",
     ["'badplug'", "snapper 'lsd' is already registered"]),
    ("replaces a built-in without override", "from fenestra.pipeline.snappers import SNAPPERS\n" + ENTRY
     + 'SNAPPERS["lsd"] = E()\n', ["'badplug'", "a plug-in replaces it only with an explicit override = True"]),
    ("replaces a built-in, then fails", "from fenestra.pipeline.snappers import SNAPPERS\n" + ENTRY
     + 'E.override = True\nSNAPPERS["lsd"] = E()\nraise RuntimeError("half done")\n', ["RuntimeError: half done"]),
]
SHOW_LSD = ["-c", "from fenestra.pipeline.snappers import SNAPPERS; from fenestra.registry import plugin_metadata; "
                  "print(SNAPPERS['lsd'].description); print(plugin_metadata())"]


@pytest.mark.parametrize("case, code, needles", PLUGINS, ids=[c for c, _, _ in PLUGINS])
def test_a_failing_plugin_is_one_warning(case, code, needles, tmp_path):
    site = plugin(tmp_path, code)
    r = fenestra("--version", cwd=tmp_path, pythonpath=(site,))
    assert r.returncode == 0 and r.stdout.startswith("fenestra "), (r.returncode, r.stdout, r.stderr[-2000:])
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr[-2000:]
    for n in needles:
        assert n in r.stderr, r.stderr
    shown = subprocess.run([sys.executable, *SHOW_LSD], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                           env={**env(), "PYTHONPATH": f"{ROOT}{os.pathsep}{site}"})
    assert shown.returncode == 0 and "a plug-in lsd" not in shown.stdout, shown.stdout + shown.stderr[-2000:]
    assert "'overrides': {}" in shown.stdout and "'badplug'" in shown.stdout.splitlines()[1]  # named as failed


def test_a_plugin_replaces_a_builtin_only_with_override_and_is_recorded(tmp_path):
    code = "from fenestra.pipeline.snappers import SNAPPERS\n" + ENTRY + 'E.override = True\nSNAPPERS["lsd"] = E()\n'
    site = plugin(tmp_path, code, name="goodplug")
    shown = subprocess.run([sys.executable, *SHOW_LSD], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                           env={**env(), "PYTHONPATH": f"{ROOT}{os.pathsep}{site}"})
    assert shown.returncode == 0 and shown.stderr == "", shown.stderr[-2000:]
    lsd, meta = shown.stdout.splitlines()
    assert lsd == "a plug-in lsd"
    assert meta == str({"loaded": ["goodplug"], "failed": {}, "overrides": {"snapper lsd": "goodplug"}})
