"""One registry type: entries added at run time, or by another installed package, reach everything.

A dummy detector, a dummy pose strategy and a dummy dataset adapter registered at run time reach
the CLI's --help, a profile that says "all", the gates' capability selection and the report's
method lists (docs/EXTENDING.md). A plug-in package installed into a temporary environment
registers a snapper through the ``fenestra.plugins`` entry points and the bench gives it rows.
"""
from __future__ import annotations

import dataclasses
import re
import site
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from fenestra.methods import Method, read_methods
from fenestra.registry import ALL, Registry, UnknownName, capabilities

ROOT = Path(__file__).resolve().parent.parent


@dataclasses.dataclass(frozen=True)
class Thing:
    name: str
    description: str
    per_wall: bool = False
    in_all: bool = True


def test_registry_lookup_select_describe_register():
    reg = Registry("thing", [Thing("a", "first"), Thing("b", "second", per_wall=True), Thing("c", "third", in_all=False)])
    assert list(reg) == ["a", "b", "c"] and reg["b"].description == "second"
    with pytest.raises(UnknownName, match=r"unknown thing 'z'; choose from \['a', 'b', 'c'\]") as e:
        reg["z"]
    assert isinstance(e.value, KeyError) and isinstance(e.value, ValueError)
    assert reg.select(ALL) == reg.select([ALL]) == ["a", "b"]  # in_all False: only by name
    assert reg.select(["c", "a"]) == ["c", "a"]
    assert reg.select({"per_wall": False}) == ["a"] and reg.where(per_wall=False) == ["a", "c"]
    with pytest.raises(ValueError, match=r"unknown capability \['colour'\]"):
        reg.select({"colour": "red"})
    with pytest.raises(ValueError, match="empty thing selection"):
        reg.select([])
    assert reg.describe() == "a: first; b: second; c: third"
    assert capabilities(reg["b"])["per_wall"] and not capabilities(reg["b"])["needs_instances"]
    with pytest.raises(ValueError, match="'a' is already registered"):
        reg.register(Thing("a", "again"))
    with pytest.raises(ValueError, match="needs a description"):
        reg.register(Thing("d", " "))
    with pytest.raises(ValueError, match="must be named so"):
        reg["e"] = Thing("f", "misnamed")
    reg.register(Thing("d", "fourth"))
    assert reg.unregister("d").name == "d" and "d" not in reg


def test_every_registry_is_one_type_of_named_described_entries():
    from fenestra.bench.real.adapters import ADAPTERS
    from fenestra.registry import Entry
    from fenestra.pipeline.detectors import DETECTORS
    from fenestra.pipeline.pose import SOLVERS
    from fenestra.pipeline.poses import POSES
    from fenestra.pipeline.snappers import SNAPPERS
    from fenestra.renders.backends import RENDERERS

    for reg in (ADAPTERS, DETECTORS, POSES, SNAPPERS, RENDERERS):
        assert isinstance(reg, Registry) and len(reg) >= 2
        for name, entry in reg.items():
            assert isinstance(entry, Entry) and entry.name == name and entry.description.strip(), (reg.kind, name)
            assert set(capabilities(entry)) == {"in_all", "needs_instances", "trainable", "per_wall", "fits_focal"}
    assert POSES.where(per_wall=True) == POSES.where(fits_focal=True) and POSES.where(per_wall=False) == [s.name for s in SOLVERS]
    assert DETECTORS.where(needs_instances=True) == ["oracle", "oracle-degraded"]


def test_method_is_typed_and_labelled_as_the_tables_are():
    m = Method("default", "lsd", "wall", withhold_K=True)
    assert m.label == m.name == "default/lsd/wall+noK"
    assert m.row() == {"detector": "default", "snapper": "lsd", "pose": "wall+noK", "method": "default/lsd/wall+noK"}
    assert Method("oracle", "none", "lm", quad_source="corners").label == "oracle/none/lm/corners"
    labels = ["default/lsd/wall+noK", "oracle/none/lm", "oracle/none/lm/corners"]
    assert list(read_methods(labels).values()) == [m, Method("oracle", "none", "lm"),
                                                   Method("oracle", "none", "lm", quad_source="corners")]
    with pytest.raises(ValueError, match="withhold_K=True instead"):
        Method("oracle", "none", "wall+noK")
    with pytest.raises(ValueError, match="Method.snapper"):
        Method("oracle", "a/b", "lm")


# ---------------------------------------------------------------- dummies registered at run time

def _dummy_solve(obj, img, K):
    """The per-window IPPE solver under another name (a new strategy, as far as the registry knows)."""
    from fenestra.pipeline.pose import solve_ippe

    return solve_ippe(obj, img, K)


def _dummy_detector(**_):
    from fenestra.pipeline.detectors.oracle import check_instances, oracle_detections

    return lambda image, instances=None: oracle_detections(check_instances(instances, image.shape))


def _read_dummy(path, dataset="dummy-format"):
    """One photo (a grey 32 x 48 image) with one window box, from nothing on disk."""
    from fenestra.bench.views import LabelledView, LabelledWindow

    yield LabelledView(dataset=dataset, name="only", image=np.full((32, 48, 3), 128, np.uint8),
                       windows=(LabelledWindow(id="w0", box=np.array([9.5, 7.5, 29.5, 21.5])),))


@pytest.fixture
def dummies():
    """A detector, a per-window pose strategy and a dataset format registered, removed afterwards."""
    from fenestra.bench.real.adapters import ADAPTERS, Adapter
    from fenestra.pipeline.detectors import DETECTORS, DetectorEntry
    from fenestra.pipeline.pose import PoseSolver
    from fenestra.pipeline.reconstruct import POSES, PoseStrategy

    det = DETECTORS.register(DetectorEntry("dummy-det", _dummy_detector, "test: the oracle's masks again",
                                           needs_instances=True))
    pose = POSES.register(PoseStrategy.per_window(PoseSolver("dummy-pose", _dummy_solve, "test: IPPE again")))
    fmt = ADAPTERS.register(Adapter("dummy-format", _read_dummy, "test: one grey photo with one box"))
    try:
        yield det, pose, fmt
    finally:
        DETECTORS.unregister("dummy-det")
        POSES.unregister("dummy-pose")
        ADAPTERS.unregister("dummy-format")


def _help(app, *command: str) -> str:
    from typer.testing import CliRunner

    out = CliRunner().invoke(app, [*command, "--help"], env={"COLUMNS": "400"}).output
    return " ".join(re.sub("[\u2500-\u257f]", " ", out).split())  # without rich's box drawing


def test_dummies_reach_cli_profiles_gates_and_report(dummies, tmp_path):
    import typer

    from fenestra.bench import cli as bench_cli
    from fenestra.pipeline import cli as pipeline_cli
    from fenestra.reports import cli as reports_cli
    from fenestra.bench import gates
    from fenestra.bench.profiles import profile_from_dict
    from fenestra.bench.real.profile import load_real_profile
    from fenestra.bench.runner import plan_methods, run_benchmark
    from fenestra.reports.build import build_report

    det, pose, fmt = dummies
    # the CLI, as the composition root builds it: choices and their descriptions from the registries
    app = typer.Typer()
    pipeline_cli.register(app)
    bench_cli.register(app, write_report=reports_cli.write_report)
    text = _help(app, "reconstruct")
    assert f"dummy-det: {det.description}" in text and f"dummy-pose: {pose.description}" in text
    assert f"dummy-format: {fmt.description}" in _help(app, "bench")

    # a profile that says "all" runs them; a real profile accepts the format
    spec = {"name": "tiny", "scenes": {"houses": ["fzk-haus"]},
            "render": {"views_per_house": 1, "width": 160, "height": 120},
            "methods": {"detectors": ["all"], "snappers": ["none"], "pose_solvers": ["all"]}}
    methods, _ = plan_methods(profile_from_dict(spec))
    labels = {m.label for m in methods}
    assert {"dummy-det/none/dummy-pose", "dummy-det/none/lm", "oracle/none/dummy-pose"} <= labels
    toml = tmp_path / "real.toml"
    toml.write_text('name = "r"\nkind = "real"\n[methods]\ndetectors = ["oracle"]\n'
                    f'[[datasets]]\nname = "d"\nformat = "dummy-format"\npath = "{tmp_path}"\n')
    assert load_real_profile(toml).source.datasets[0].format == "dummy-format"

    # one rendered view through the bench with the dummies, then its report and its gates
    chosen = (Method("dummy-det", "none", "dummy-pose"), Method("oracle", "none", "lm"))
    info = run_benchmark(profile_from_dict(spec), out_dir=tmp_path / "run", workers=1, progress=False,
                         methods=chosen, renders_dir=tmp_path / "renders", report=build_report)
    report = (info.run_dir / "report.md").read_text()
    assert "dummy-det/none/dummy-pose" in report and "oracle/none/lm" in report
    per_window = gates.Gate("tiny", "*/*/*", "detection_rate", min=0.9, pose=(("per_wall", False),))
    oracles = gates.Gate("tiny", "*/*/*", "detection_rate", min=0.9, detector=(("needs_instances", True),))
    per_wall = gates.Gate("tiny", "*/*/*", "detection_rate", min=0.9, pose=(("per_wall", True),))
    assert gates.check(info.run_dir, [per_window, oracles]) == []  # both methods detect every window
    (v,) = gates.check(info.run_dir, [per_wall])  # no per-wall method ran: a violation, never a pass
    assert v.value is None and "per_wall" in v.bound


def _plugin_package(root: Path) -> Path:
    """A tiny installable package whose entry point registers an 'identity-shift' snapper."""
    root.mkdir()
    (root / "pyproject.toml").write_text(textwrap.dedent("""\
        [build-system]
        requires = ["setuptools>=61"]
        build-backend = "setuptools.build_meta"

        [project]
        name = "fenestra-identity-shift"
        version = "0.1"

        [project.entry-points."fenestra.plugins"]
        identity-shift = "fenestra_identity_shift"

        [tool.setuptools]
        py-modules = ["fenestra_identity_shift"]
        """))
    (root / "fenestra_identity_shift.py").write_text(textwrap.dedent('''\
        """A snapper from another package: every corner 1 px to the right."""
        from dataclasses import dataclass

        from fenestra.pipeline.snappers import SNAPPERS
        from fenestra.pipeline.snappers.base import Snapper, check_inputs


        @dataclass(frozen=True)
        class ShiftParams:
            dx_px: float = 1.0


        def snap_shift(gray, quad, params=ShiftParams()):
            """Every corner moved dx_px to the right."""
            _, q = check_inputs(gray, quad)
            return q + [params.dx_px, 0.0], {"moved": [True] * 4}


        SNAPPERS.register(Snapper("identity-shift", snap_shift, ShiftParams, test_median_px=10.0,
                                  description="plug-in: every corner 1 px to the right"))
        '''))
    return root


def test_a_plugin_package_is_benchmarked(tmp_path):
    """Installed into a fresh environment (offline), the plug-in's snapper gets the bench's rows."""
    import pandas as pd

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    purelib = subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             check=True, capture_output=True, text=True).stdout.strip()
    # this environment's packages (numpy, torch, setuptools, ...) are visible to the new one
    (Path(purelib) / "_host.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps",
                        "--no-build-isolation", "--no-index", "--quiet", str(_plugin_package(tmp_path / "plugin"))],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    profile = tmp_path / "tiny.toml"
    profile.write_text(textwrap.dedent("""\
        name = "tiny"
        [scenes]
        houses = ["fzk-haus"]
        [render]
        views_per_house = 1
        width = 160
        height = 120
        [methods]
        detectors = ["oracle"]
        snappers = ["all"]
        pose_solvers = ["lm"]
        """))
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "OMP_NUM_THREADS": "1",
           "PYOPENGL_PLATFORM": "egl", "MPLBACKEND": "Agg", "HOME": str(tmp_path)}
    r = subprocess.run([py, "-m", "fenestra", "bench", "--profile", str(profile), "--out", str(tmp_path / "run"),
                        "--workers", "1", "--no-report"], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    df = pd.read_parquet(tmp_path / "run" / "results.parquet")
    mine = df[df.snapper == "identity-shift"]
    assert len(mine) == (df.snapper == "none").sum() > 0 and set(mine.method) == {"oracle/identity-shift/lm"}
    # its corners are the mask-fit ones moved 1 px: the snapped error differs from 'none' by <= 1 px
    ok = df[df.evaluable & (df.status == "ok")].set_index(["view", "window_id", "snapper"]).corner_err_px_snap
    diff = (ok.xs("identity-shift", level="snapper") - ok.xs("none", level="snapper")).abs()
    assert len(diff) > 0 and (diff <= 1.0 + 1e-9).all() and (diff > 0).any()
