"""The wheel installs one top-level package, ``fenestra``, and holds no lab script or test fixture.

Built here from the checkout (``pip wheel --no-deps --no-build-isolation``, the setuptools of the
venv), its file list read with zipfile: what ``pip install .`` would put into site-packages.
"""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LAB_OR_FIXTURE = ("benchmark", "timing", "synthetic", "quad_image", "wall_scenes", "photoreal_cost",
                  "render_speed", "scene_load_speed", "conftest", "test_")


@pytest.fixture(scope="module")
def wheel_names(tmp_path_factory) -> list[str]:
    out = tmp_path_factory.mktemp("wheel")
    build = tmp_path_factory.mktemp("build")  # setuptools' build folder, outside the checkout
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                        "-w", str(out), str(ROOT)], capture_output=True, text=True, timeout=600,
                       env={"PATH": "/usr/bin:/bin", "HOME": str(build), "TMPDIR": str(build)})
    assert r.returncode == 0, r.stderr[-2000:]
    wheels = list(out.glob("fenestra-*.whl"))
    assert len(wheels) == 1, wheels
    with zipfile.ZipFile(wheels[0]) as z:
        return z.namelist()


def test_one_top_level_package(wheel_names):
    tops = {n.split("/")[0] for n in wheel_names}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"fenestra"}, sorted(tops)


def test_no_lab_scripts_or_fixtures(wheel_names):
    stems = [Path(n).stem for n in wheel_names if n.endswith(".py")]
    bad = sorted(n for n, s in zip([n for n in wheel_names if n.endswith(".py")], stems)
                 if any(s == k or s.startswith(k) for k in LAB_OR_FIXTURE))
    assert not bad, bad


def test_the_wheel_carries_the_data_the_package_reads(wheel_names):
    """The bundled houses, the shipped weights, the profiles, the gates and the viewer's vendored
    three.js (with its licence) travel with the code."""
    names = set(wheel_names)
    assert any(n.startswith("fenestra/scenes/ifc/") and n.endswith(".ifc") for n in names)
    assert {"fenestra/pipeline/models/default.pt", "fenestra/bench/gates.toml",
            "fenestra/bench/profiles/default.toml"} <= names
    vendor = "fenestra/pipeline/export/vendor/"
    assert {vendor + f for f in ("three-viewer.min.js", "LICENSE", "VERSION", "README.md")} <= names
