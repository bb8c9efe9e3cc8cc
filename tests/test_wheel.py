"""The wheel installs one top-level package, ``fenestra``, holding only what an allow-list names: no lab
script, tool or test fixture.

Built here from the checkout (``pip wheel --no-deps --no-build-isolation``, the setuptools of the
venv), its file list read with zipfile: what ``pip install .`` would put into site-packages.
"""
from __future__ import annotations

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# What the wheel may hold, and nothing else: the product's packages, the data they read, and the
# distribution's metadata. The lab (lab/: training scripts, data packing, tuning, weight shipping,
# the repository's docs writer), the tools and the tests stay in the checkout.
PACKAGES = ("", "app", "bench", "bench/real", "bench/real/adapters", "pipeline", "pipeline/detectors",
            "pipeline/export", "pipeline/intrinsics", "pipeline/snappers", "pipeline/walls", "renders", "reports",
            "scenes", "training", "training/recipes")
ALLOWED = (
    re.compile(r"fenestra-[\w.]+\.dist-info/[\w.]+"),
    re.compile(r"fenestra/(?:(?:%s)/)?[a-z_0-9]+\.py" % "|".join(p for p in PACKAGES if p)),
    re.compile(r"fenestra/bench/gates\.toml"),
    re.compile(r"fenestra/bench/profiles/[\w-]+\.toml"),
    re.compile(r"fenestra/training/configs/[\w-]+\.toml"),
    re.compile(r"fenestra/pipeline/models/(?:[\w-]+\.pt|README\.md)"),
    re.compile(r"fenestra/scenes/ifc/(?:[\w.-]+\.ifc|SOURCES\.md)"),
    re.compile(r"fenestra/pipeline/export/vendor/(?:three-viewer\.min\.js|three-viewer\.entry\.js|LICENSE|VERSION|README\.md)"),
)
LAB_NAMES = ("ship", "tune", "pack_data", "markdown", "make_data", "conftest", "timing", "synthetic")


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


def test_every_file_of_the_wheel_is_on_the_allow_list(wheel_names):
    """A file the list does not name (a lab script, a fixture, a stray data file) fails here."""
    bad = sorted(n for n in wheel_names if not any(a.fullmatch(n) for a in ALLOWED))
    assert not bad, bad


def test_no_lab_module_in_the_wheel(wheel_names):
    stems = sorted(n for n in wheel_names if n.endswith((".py", ".sh")) and Path(n).stem in LAB_NAMES)
    assert not stems, stems


def test_the_package_never_imports_the_lab():
    """No module of fenestra/ names the lab: the installed package runs without the checkout."""
    offenders = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "fenestra").rglob("*.py")
                       if re.search(r"^\s*(?:from|import)\s+lab\b", p.read_text(), re.M))
    assert not offenders, offenders


def test_the_wheel_carries_the_data_the_package_reads(wheel_names):
    """The bundled houses, the shipped weights, the profiles, the gates and the viewer's vendored
    three.js (with its licence) travel with the code."""
    names = set(wheel_names)
    assert any(n.startswith("fenestra/scenes/ifc/") and n.endswith(".ifc") for n in names)
    assert {"fenestra/pipeline/models/default.pt", "fenestra/bench/gates.toml",
            "fenestra/bench/profiles/default.toml"} <= names
    vendor = "fenestra/pipeline/export/vendor/"
    assert {vendor + f for f in ("three-viewer.min.js", "LICENSE", "VERSION", "README.md")} <= names
