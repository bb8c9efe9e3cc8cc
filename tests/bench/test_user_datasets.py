"""A user's own dataset, end to end: YOLO, COCO (boxes, polygons, RLE) and label maps built from
the bundled curtain-wall photos (tests/user_datasets.py) go through ``fenestra check-data`` and
``fenestra bench --profile real --data DIR --format F`` to a report; the counts are the builder's."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from user_datasets import curtain_panes, write_coco, write_labelmap, write_yolo

from fenestra.bench.real.adapters import ADAPTERS

ROOT = Path(__file__).resolve().parents[2]
WRITERS = {"yolo": write_yolo, "coco": write_coco, "labelmap": write_labelmap}


@pytest.fixture(scope="module")
def panes():
    return curtain_panes(2)


def cli(*args, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYOPENGL_PLATFORM": "egl", "MPLBACKEND": "Agg",
           "OMP_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, "-m", "fenestra", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def test_adapters_carry_the_builders_truth(panes, tmp_path):
    """Boxes at the pixel-centre convention, RLE (compressed and not) and label-map masks equal to
    the pane masks, doors/signboards left out, partial panes where they touch the border."""
    for fmt, write in WRITERS.items():
        write(tmp_path / fmt, panes)
        views = list(ADAPTERS[fmt](tmp_path / fmt))
        assert [v.name for v in views] == [n for n, _, _ in panes]
        for (_, _, ps), v in zip(panes, views):
            assert len(v.windows) == len(ps)
            if fmt == "labelmap":  # components come in row-major order: compare as sets
                assert sorted(int(w.mask.area) for w in v.windows) == sorted(int(p.mask.sum()) for p in ps)
                assert sum(w.partial for w in v.windows) == sum(p.partial for p in ps)
                continue
            for j, (p, w) in enumerate(zip(ps, v.windows)):
                x, y, bw, bh = p.bbox
                np.testing.assert_allclose(w.box, [x - 0.5, y - 0.5, x + bw - 0.5, y + bh - 0.5], atol=1e-3)
                if fmt == "coco" and j % 4 in (2, 3):
                    assert np.array_equal(w.mask.dense(), p.mask)
                if fmt == "coco" and j % 4 == 1:
                    assert w.quad is not None and w.mask is not None


def test_check_data_lists_photos_and_refusals(panes, tmp_path):
    n = write_yolo(tmp_path / "y", panes)
    (tmp_path / "y" / "labels" / "lost.txt").write_text("0 0.5 0.5 0.1 0.1\n")
    with open(tmp_path / "y" / "labels" / f"{panes[0][0]}.txt", "a") as f:
        f.write("0 1.5 1.5 0.2 0.2\n")  # entirely off the photo
    r = cli("check-data", tmp_path / "y", "--format", "yolo", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert f"2 photo(s), {n} window(s), 2 refused, 0 problem(s)" in r.stdout
    assert f"found: {panes[0][0]} 384x512: {len(panes[0][2])} windows (0 quad, 0 mask, {len(panes[0][2])} box" in r.stdout
    assert "lost.txt: no photo lost.* in" in r.stdout
    assert f"{panes[0][0]}.txt:{len(panes[0][2]) + 3}: box (cx 1.5, cy 1.5, w 0.2, h 0.2) lies entirely outside" in r.stdout
    r = cli("check-data", tmp_path / "y", "--format", "yolo", "--option", "classes=[0,3,5]", cwd=tmp_path)
    assert f"{n + 4} window(s)" in r.stdout, r.stdout


@pytest.mark.parametrize("fmt", sorted(WRITERS))
def test_bench_real_on_a_user_dataset_writes_a_report(fmt, panes, tmp_path):
    n = WRITERS[fmt](tmp_path / "mydata", panes)
    r = cli("bench", "--profile", "real", "--data", tmp_path / "mydata", "--format", fmt, "--out", "run", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    run = tmp_path / "run"
    assert (run / "report.html").is_file() and (run / "report.md").is_file()
    s = json.loads((run / "summary.json").read_text())
    assert s["metadata"]["n_windows"] == {"mydata": n} and s["metadata"]["profile"] == "real-mydata"
    m = json.loads((run / "manifest.json").read_text())
    assert m["n_rows"] == n * len(s["metadata"]["methods"])
    if fmt == "labelmap":  # exact masks: the oracle finds every evaluable (whole) pane
        whole = sum(not p.partial for _, _, ps in panes for p in ps)
        assert s["results"]["oracle/none/lm"]["n_evaluable"] == whole
        assert s["results"]["oracle/none/lm"]["detection_rate"] == 1.0
    r = cli("bench", "--profile", "smoke", "--data", tmp_path / "mydata", cwd=tmp_path)  # --data needs a real profile
    assert r.returncode == 2 and "need a real profile" in r.stderr
