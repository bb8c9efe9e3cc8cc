"""The pipeline on real photos (examples/curtainwall), checked against the known pane size.

The photos are of a 1:25 glass curtain wall whose glass panes are all 93.2 mm x 143.2 mm (aspect
0.6508) on a 103.2 mm x 153.2 mm module grid: ground truth independent of the pipeline. The photos
carry lens distortion; K.json has the calibration, the pane masks are in the undistorted frame.

Measured (2 photos, 7 whole panes, 768x1024 px; see examples/curtainwall/README.md):
median aspect error 0.54 % (snapper none) and 0.55 % (linefit); per-photo median pairwise normal
angle 1.2 / 2.6 deg (none), 1.2 / 3.2 deg (linefit); neighbouring panes' offsets within 3 % of the
module pitch. Bounds below leave a stated margin over those numbers.
"""
from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from fenestra.errors import PipelineError
from fenestra.pipeline.cli import run_reconstruct
from fenestra.pipeline.io import Camera, check_distortion, read_camera, read_K, undistort_photo

ROOT = Path(__file__).resolve().parents[2]
EX = ROOT / "examples" / "curtainwall"
PHOTOS = ("017", "086")
PANE_W_M, PANE_H_M = 0.0932, 0.1432  # glass pane, from the dataset's documentation
PANE_ASPECT = PANE_W_M / PANE_H_M  # 0.6508
PITCH_M = np.array([0.1032, 0.1532])  # pane + frame module: pane-to-pane offset along x, y
N_PANES = {"017": 3, "086": 4}

# Bounds (measured value -> bound):
ASPECT_MEDIAN_REL = 0.015  # 0.55 % -> 1.5 % (~3x): 1 px of mask error is ~0.5 % here
ASPECT_MAX_REL = 0.04  # worst pane 1.5 % -> 4 %
NORMAL_MEDIAN_DEG = 5.0  # 3.2 deg -> 5 deg: pane 3 of img086 is seen almost head-on (4 deg)
NORMAL_MAX_DEG = 8.0  # 4.9 deg -> 8 deg
PITCH_RESIDUAL = 0.06  # in-plane offsets off the module grid: 2.8 % of a pitch -> 6 %


def _photo(n: str) -> Path:
    return EX / f"img{n}.jpg"


def _masks(n: str) -> Path:
    return EX / f"panes{n}.png"


@pytest.fixture(scope="module")
def docs(tmp_path_factory) -> dict:
    """windows.json dicts through the Python API: {(photo, snapper): doc}, width fixed to 93.2 mm."""
    out = tmp_path_factory.mktemp("curtainwall")
    return {(n, s): run_reconstruct(_photo(n), out / f"{n}_{s}", K_json=EX / "K.json", masks=_masks(n),
                                    snapper=s, pose="lm", width=PANE_W_M, export=False).to_json()
            for n in PHOTOS for s in ("none", "linefit")}


def _aspect_errors(doc: dict) -> np.ndarray:
    return np.array([abs(w["aspect_ratio"] / PANE_ASPECT - 1.0) for w in doc["windows"]])


def _normal_angles_deg(doc: dict) -> np.ndarray:
    """Pairwise angles (deg) between the panes' normals (window z axis in the camera frame)."""
    ns = [np.asarray(w["R"])[:, 2] for w in doc["windows"]]
    return np.array([np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))) for a, b in itertools.combinations(ns, 2)])


def test_example_files_are_consistent():
    cam = read_camera(EX / "K.json")
    assert cam.has_distortion and cam.distortion.shape == (5,)
    for n in PHOTOS:
        img = cv2.imread(str(_photo(n)))
        inst = cv2.imread(str(_masks(n)), cv2.IMREAD_UNCHANGED)
        assert inst.dtype == np.uint16 and inst.shape == img.shape[:2]
        assert sorted(np.unique(inst).tolist()) == list(range(N_PANES[n] + 1))


@pytest.mark.parametrize("snapper", ["none", "linefit"])
def test_aspect_ratio_matches_known_pane_size(docs, snapper):
    errs = []
    for n in PHOTOS:
        doc = docs[(n, snapper)]
        assert doc["undistorted"] is True
        assert len(doc["windows"]) == N_PANES[n]
        assert all(w["failure"] is None for w in doc["windows"]), [w["failure"] for w in doc["windows"]]
        errs.extend(_aspect_errors(doc))
    errs = np.array(errs)
    assert np.median(errs) < ASPECT_MEDIAN_REL, errs
    assert errs.max() < ASPECT_MAX_REL, errs


@pytest.mark.parametrize("snapper", ["none", "linefit"])
def test_pane_height_from_known_width(docs, snapper):
    """One scale per wall (issue 24): each photo's panes are one wall whose median pane gets the known
    width; the others are measured (measured: widths within 2.6 %, heights within 3.5 % of the truth)."""
    for n in PHOTOS:
        doc = docs[(n, snapper)]
        assert len(doc["walls"]) == 1 and not doc["scale"]["assumed"]
        assert np.median([w["width_m"] for w in doc["windows"]]) == pytest.approx(PANE_W_M)
    h = np.array([w["height_m"] for n in PHOTOS for w in docs[(n, snapper)]["windows"]])
    wm = np.array([w["width_m"] for n in PHOTOS for w in docs[(n, snapper)]["windows"]])
    assert np.all(np.abs(wm / PANE_W_M - 1.0) < ASPECT_MAX_REL), wm
    assert abs(np.median(h) / PANE_H_M - 1.0) < ASPECT_MEDIAN_REL, h
    assert np.all(np.abs(h / PANE_H_M - 1.0) < 1.5 * ASPECT_MAX_REL), h


@pytest.mark.parametrize("snapper", ["none", "linefit"])
def test_panes_of_one_photo_share_a_plane(docs, snapper):
    for n in PHOTOS:
        ang = _normal_angles_deg(docs[(n, snapper)])
        assert np.median(ang) < NORMAL_MEDIAN_DEG, (n, ang)
        assert ang.max() < NORMAL_MAX_DEG, (n, ang)


@pytest.mark.parametrize("snapper", ["none", "linefit"])
def test_pane_positions_lie_on_the_module_grid(docs, snapper):
    """Metric pose check: with the width fixed, pane j seen from pane i's frame sits a whole number
    of modules (103.2 x 153.2 mm) away along the wall, and not at the same place."""
    for n in PHOTOS:
        ws = docs[(n, snapper)]["windows"]
        for i, j in itertools.permutations(range(len(ws)), 2):
            Ri, ti, tj = (np.asarray(ws[i]["R"]), np.asarray(ws[i]["t"]), np.asarray(ws[j]["t"]))
            g = (Ri.T @ (tj - ti))[:2] / PITCH_M
            assert np.any(np.round(g) != 0), (n, i, j, g)
            assert np.abs(g - np.round(g)).max() < PITCH_RESIDUAL, (n, i, j, g)


def _distort_instances(inst: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The undistorted-frame instance map resampled (nearest) into the distorted photo's frame."""
    H, W = inst.shape
    u, v = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    und = cv2.undistortPoints(np.stack([u.ravel(), v.ravel()], 1).reshape(-1, 1, 2), K, dist, P=K)
    und = und.reshape(H, W, 2)
    return cv2.remap(inst, und[..., 0], und[..., 1], cv2.INTER_NEAREST, borderValue=0)


def test_ignoring_distortion_is_measurably_worse(docs, tmp_path):
    """The same panes, labelled on the raw photo, reconstructed with a pinhole K (distortion
    ignored): the wall's panes disagree about its plane (measured 6-9 deg vs 1-3 deg) and the
    aspect ratios are worse (median 1.3-1.6 % vs ~0.55 %)."""
    cam = read_camera(EX / "K.json")
    (tmp_path / "K.json").write_text(json.dumps({"K": cam.K.tolist()}))
    for snapper in ("none", "linefit"):
        naive_errs, aware_errs = [], []
        for n in PHOTOS:
            inst = cv2.imread(str(_masks(n)), cv2.IMREAD_UNCHANGED)
            cv2.imwrite(str(tmp_path / f"raw{n}.png"), _distort_instances(inst, cam.K, cam.distortion))
            naive = run_reconstruct(_photo(n), tmp_path / "out", K_json=tmp_path / "K.json",
                                    masks=tmp_path / f"raw{n}.png", snapper=snapper, pose="lm", width=PANE_W_M,
                                    export=False).to_json()
            assert naive["undistorted"] is False and len(naive["windows"]) == N_PANES[n]
            aware = docs[(n, snapper)]
            assert np.median(_normal_angles_deg(naive)) > 2.0 * np.median(_normal_angles_deg(aware)), n
            naive_errs.extend(_aspect_errors(naive))
            aware_errs.extend(_aspect_errors(aware))
        assert np.median(naive_errs) > np.median(aware_errs), (snapper, naive_errs, aware_errs)


def test_cli_on_the_example(docs, tmp_path):
    """The README's command, as a user runs it: same numbers as the API, plus the exports."""
    out = tmp_path / "curtainwall"
    env = {**os.environ, "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl")}
    cmd = [sys.executable, "-m", "fenestra", "reconstruct", str(_photo("017")), "--K", str(EX / "K.json"),
           "--masks", str(_masks("017")), "--snapper", "linefit", "--pose", "lm", "--width", str(PANE_W_M), "--out", str(out)]
    r = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "undistorted" in r.stdout
    doc = json.loads((out / "windows.json").read_text())
    assert doc["undistorted"] is True and len(doc["distortion"]) == 5
    api = docs[("017", "linefit")]
    assert np.allclose([w["aspect_ratio"] for w in doc["windows"]], [w["aspect_ratio"] for w in api["windows"]])
    assert np.median(_aspect_errors(doc)) < ASPECT_MEDIAN_REL
    assert (out / "overlay.png").is_file()


# --- reading distortion from K.json (pipeline.io) ---

def test_read_camera_forms(tmp_path):
    K = [[900.0, 0.0, 383.5], [0.0, 900.0, 511.5], [0.0, 0.0, 1.0]]
    f = tmp_path / "K.json"
    f.write_text(json.dumps({"K": K, "distortion": [-0.15, 0.05, 0.0, 0.0, 0.0]}))
    cam = read_camera(f)
    assert np.allclose(cam.K, K) and np.allclose(cam.distortion, [-0.15, 0.05, 0, 0, 0])
    assert np.allclose(read_K(f), K)  # the old reader still works on files with distortion
    f.write_text(json.dumps({"fx": 900.0, "distortion": [-0.15, 0.05, 0.001, 0.0]}))
    cam = read_camera(f, (768, 1024))
    assert np.allclose(cam.K, K) and cam.distortion.shape == (4,)
    for none in (None, [0.0] * 5):
        f.write_text(json.dumps({"K": K, "distortion": none}))
        assert read_camera(f).distortion is None and not read_camera(f).has_distortion
    f.write_text(json.dumps({"K": K}))
    assert read_camera(f).distortion is None


@pytest.mark.parametrize("bad", [[-0.1, 0.05, 0.0], [0.1] * 6, [[0.1, 0.0, 0.0, 0.0, 0.0]], "k1",
                                 [0.1, float("nan"), 0.0, 0.0, 0.0], [0.1, float("inf"), 0.0, 0.0]])
def test_bad_distortion_is_named(tmp_path, bad):
    f = tmp_path / "K.json"
    f.write_text(json.dumps({"K": [[900.0, 0, 10], [0, 900.0, 10], [0, 0, 1]], "distortion": bad}))
    with pytest.raises(PipelineError, match="distortion"):
        read_camera(f)
    with pytest.raises(PipelineError):
        check_distortion(bad)


def test_undistort_photo_moves_points_like_undistortPoints_with_the_same_K():
    """undistort_photo keeps K: a blob at a raw-photo point moves to that point's pinhole image."""
    cam = read_camera(EX / "K.json")
    W, H = 768, 1024
    p = np.array([100.0, 120.0])  # near the corner, where the distortion is large
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    blob = np.exp(-((u - p[0]) ** 2 + (v - p[1]) ** 2) / (2 * 3.0**2)).astype(np.float32)
    und = undistort_photo(blob, cam)
    c = np.array([(und * u).sum(), (und * v).sum()]) / und.sum()
    q = cv2.undistortPoints(p.reshape(1, 1, 2), cam.K, cam.distortion, P=cam.K)[0, 0]
    assert np.linalg.norm(q - p) > 10.0, q
    assert np.linalg.norm(c - q) < 0.2, (c, q)
    assert undistort_photo(blob, Camera(K=cam.K)) is blob


def test_shared_plane_on_the_curtain_wall(tmp_path, docs):
    """Per-wall strategy (`--pose wall`, mask quads): every pane within 1.5 % of the true aspect, a
    smaller median error than per-window LM on the same panes, one normal for the whole wall, and
    the true aspect inside the 90 % interval for at least 6 of the 7 panes."""
    wall_errs, lm_errs, covered = [], [], []
    for n in PHOTOS:
        doc = run_reconstruct(_photo(n), tmp_path / n, K_json=EX / "K.json", masks=_masks(n), snapper="none",
                              pose="wall", width=PANE_W_M, export=False).to_json()
        assert {w["wall"] for w in doc["windows"]} == {0}
        assert max(_normal_angles_deg(doc)) < 1e-6
        wall_errs.extend(_aspect_errors(doc))
        lm_errs.extend(_aspect_errors(docs[(n, "none")]))
        covered += [w["uncertainty"]["aspect_lo"] <= PANE_ASPECT <= w["uncertainty"]["aspect_hi"] for w in doc["windows"]]
    assert max(wall_errs) < 0.015 and np.median(wall_errs) < np.median(lm_errs)
    assert sum(covered) >= 6
