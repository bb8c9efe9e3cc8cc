"""End to end on a synthetic photo: instance map -> windows.json; input files; CLI (import isolation: test_imports.py)."""
import json

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from fenestra.conventions import make_K, rotation_error_deg
from fenestra.errors import DatasetError, PipelineError
from fenestra.images import read_image, read_instances
from fenestra.pipeline.io import read_K
from fenestra.pipeline.detectors.oracle import detections_from_instance_map
from fenestra.pipeline.reconstruct import ReconstructConfig, reconstruct, windows_to_json
from quad_image import coverage, pixel_centre_mask, view_window

K = make_K(800.0, 800.0, 319.5, 239.5)
SHAPE = (480, 640)


def scene():
    """Two 1.0 x 1.4 m windows on a wall; returns (RGB image (gray), instance map, ground-truth views)."""
    img, inst, views = np.full(SHAPE, 200.0), np.zeros(SHAPE, np.uint16), []
    for i, off in enumerate([(-150.0, 0.0), (150.0, 20.0)]):
        sw = view_window(K, 1.0, 1.4, 25.0, 5.0, 2.0, 6.0, off)
        img += (40.0 - 200.0) * coverage(sw.corners_px, SHAPE)
        inst[pixel_centre_mask(sw.corners_px, SHAPE)] = i + 1
        views.append(sw)
    rgb = np.repeat(np.clip(np.round(img), 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
    return rgb, inst, views


def test_reconstruct_linefit_exact_scene():
    rgb, inst, views = scene()
    res = reconstruct(rgb, K, detections_from_instance_map(inst), ReconstructConfig(snapper="linefit", pose="lm", height_m=1.4))
    assert len(res) == 2
    for r, sw in zip(res, views):
        assert r.failure is None
        assert np.linalg.norm(r.quad_snapped - sw.corners_px, axis=1).max() < 0.05
        assert abs(r.aspect_ratio / (1.0 / 1.4) - 1) < 1e-3
        assert rotation_error_deg(r.R, sw.R) < 0.3
        assert np.linalg.norm(r.t - sw.t) < 0.01 * np.linalg.norm(sw.t)
        assert set(r.timings_ms) == {"quad", "snap", "aspect", "pose"}
    doc = json.loads(json.dumps(windows_to_json(res, K=K, image_size=(640, 480))))
    w = doc["windows"][0]
    for key in ("quad_mask", "quad_snapped", "aspect_ratio", "aspect_case", "R", "t", "quad_reprojected",
                "failure", "timings_ms"):
        assert key in w
    assert np.asarray(w["quad_snapped"]).shape == (4, 2) and w["failure"] is None


def test_unknown_focal_reconstruct():
    rgb, inst, views = scene()
    res = reconstruct(rgb, None, detections_from_instance_map(inst), ReconstructConfig(snapper="linefit", pose="lm"))
    for r in res:
        assert r.failure is None and abs(r.focal_estimate_px / 800.0 - 1) < 0.05


def test_two_blobs_one_id_is_a_failure_not_a_crash():
    rgb, inst, _ = scene()
    inst[inst == 2] = 1  # both windows carry id 1
    inst[300:340, 300:340] = 3  # a square window, fine
    res = reconstruct(rgb, K, detections_from_instance_map(inst))
    assert res[0].failure.stage == "quad" and res[0].failure.reason.startswith("multiple_blobs") and res[0].R is None
    assert str(res[0].failure).startswith("quad: multiple_blobs")  # the form windows.json and the tables hold
    assert res[1].failure is None


def test_empty_mask_and_wrong_shape_mask():
    from fenestra.pipeline.types import Detection
    rgb, _, _ = scene()
    # a (10, 10) mask is a sparse crop (at origin (0, 0) by default): outside the image only when
    # it does not fit there
    dets = [Detection(np.zeros(SHAPE, bool), np.zeros(4), 0.9),
            Detection(np.zeros((10, 10), bool), np.zeros(4), 0.9, origin=(SHAPE[1] - 5, 0)),
            Detection(np.zeros((SHAPE[0] + 1, SHAPE[1]), bool), np.zeros(4), 0.9)]
    res = reconstruct(rgb, K, dets)
    assert str(res[0].failure).startswith("quad: empty_mask")
    assert "mask shape" in res[1].failure.reason and "mask shape" in res[2].failure.reason
    with pytest.raises(ValueError, match="unknown snapper"):
        ReconstructConfig(snapper="magic")
    with pytest.raises(ValueError, match="K must be 3x3"):
        reconstruct(rgb, np.eye(4), dets)


def test_io_errors(tmp_path):
    bad = tmp_path / "photo.png"
    bad.write_bytes(b"not a png")
    with pytest.raises(DatasetError, match="cannot read photo .*photo.png"):
        read_image(bad, "photo")
    with pytest.raises(DatasetError, match="photo not found"):
        read_image(tmp_path / "missing.jpg", "photo")
    kf = tmp_path / "K.json"
    kf.write_text(json.dumps({"K": [[800, 0, 320], [0, 800, 240]]}))
    with pytest.raises(PipelineError, match=r"K must be 3x3, got shape \(2, 3\)"):
        read_K(kf)
    kf.write_text(json.dumps({"fx": 700}))
    assert np.allclose(read_K(kf, (640, 480)), make_K(700, 700, 319.5, 239.5))
    kf.write_text(json.dumps({"fx": -5, "cx": 1, "cy": 1}))
    with pytest.raises(PipelineError, match="fx=-5"):
        read_K(kf)
    m = tmp_path / "inst.png"
    cv2.imwrite(str(m), np.zeros((20, 30), np.uint16))
    with pytest.raises(DatasetError, match="30x20 but the photo is 640x480"):
        read_instances(m, (640, 480))
    assert read_instances(m, (30, 20)).dtype == np.int32


def test_cli_reconstruct(tmp_path):
    from fenestra.app.cli import app
    rgb, inst, _ = scene()
    cv2.imwrite(str(tmp_path / "photo.png"), rgb)
    cv2.imwrite(str(tmp_path / "inst.png"), inst)
    (tmp_path / "K.json").write_text(json.dumps({"K": K.tolist()}))
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["reconstruct", str(tmp_path / "photo.png"), "--K", str(tmp_path / "K.json"),
                                 "--masks", str(tmp_path / "inst.png"), "--snapper", "linefit",
                                 "--pose", "ippe", "--height", "1.4", "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "windows.json").read_text())
    assert len(doc["windows"]) == 2 and all(w["failure"] is None for w in doc["windows"])
    assert "median ms/window" in r.output
    assert (out / "model.ifc").is_file() and (out / "overlay.png").is_file()


def test_sparse_detections_fit_exactly_like_full_masks():
    """detections_from_instance_map's crops give the quad, lines and failure of mask_to_quad on
    the full (H, W) mask of each id: windows inside, touching the border, split in two blobs."""
    from fenestra.pipeline.quad import mask_to_quad
    from fenestra.pipeline.reconstruct import fit_quads

    _, inst, _ = scene()
    inst[0:30, 600:640] = 5  # touches the top and right edges
    inst[400:420, 20:40] = 6
    inst[400:420, 60:80] = 6  # two blobs, one id
    inst[100:160, 0:25] = 9  # touches the left edge only
    dets = detections_from_instance_map(inst)
    assert [d.instance_id for d in dets] == [1, 2, 5, 6, 9]
    assert all(d.mask.shape != SHAPE for d in dets)
    for d, f in zip(dets, fit_quads(dets, image_shape=SHAPE)):
        full = mask_to_quad(inst == d.instance_id)
        assert f.result.failure == full.failure
        if full.quad is not None:
            np.testing.assert_allclose(f.result.quad, full.quad, atol=1e-9)
            np.testing.assert_allclose(f.result.lines, full.lines, atol=1e-9)
    assert dets[2].box.tolist() == [599.5, -0.5, 639.5, 29.5]  # pixel-edge outline of columns 600-639, rows 0-29


def test_pose_strategies_are_one_registry_that_sees_late_entries():
    """Built-in solvers and wall strategies in one registry; a strategy registered after import
    reaches ReconstructConfig, estimate_pose by name and the reconstruction itself."""
    from fenestra.conventions import DEFAULTS
    from fenestra.pipeline.pose import SOLVERS, PoseSolver, solve_ippe
    from fenestra.pipeline.poses import POSES, PoseStrategy
    from fenestra.pipeline.reconstruct import pose_strategies
    from fenestra.pipeline.walls import WALL_STRATEGIES

    ps = pose_strategies()
    assert ps is POSES and list(ps) == [*(s.name for s in SOLVERS), *WALL_STRATEGIES]
    for name, s in ps.items():
        assert s.name == name and s.description.strip() and s.per_wall == (name in WALL_STRATEGIES)
        assert ReconstructConfig(pose=name).pose == name
    calls = []

    def counted(obj, img, K):
        calls.append(1)
        return solve_ippe(obj, img, K)

    POSES.register(PoseStrategy.per_window(PoseSolver("late-ippe", counted, "test: IPPE, counted")))
    try:
        from fenestra.pipeline.pose import estimate_pose
        from fenestra.tolerances import TOL

        sw = view_window(K, 1.2, 1.5, 30.0, 10.0, 5.0, 6.0)
        p = estimate_pose(sw.corners_px, K, 1.2 / 1.5, 1.5, solver="late-ippe")
        assert calls and rotation_error_deg(p.R, sw.R) < TOL.exact_rotation_deg
    finally:
        POSES.unregister("late-ippe")
    cfg = ReconstructConfig()
    assert (cfg.snapper, cfg.pose) == (DEFAULTS.snapper, DEFAULTS.pose)


def test_one_image_check_and_rgb_at_every_boundary(tmp_path):
    """One check_image (fenestra.checks) guards detect, reconstruct and the export, with one error that
    is both a PipelineError and a ValueError; colour images are read as RGB (gray = 0.299 R + 0.587 G
    + 0.114 B: pure red is 76, as BGR it would be 29)."""
    from fenestra.pipeline.detectors import detect
    from fenestra.pipeline.export import write_outputs
    from fenestra.pipeline.reconstruct import to_gray
    from fenestra.checks import ImageError

    red = np.zeros((20, 30, 3), np.uint8)
    red[..., 0] = 255
    assert np.all(to_gray(red) == 76)
    cv2.imwrite(str(tmp_path / "red.png"), red[:, :, ::-1])  # cv2 writes BGR
    np.testing.assert_array_equal(read_image(tmp_path / "red.png"), red)
    rgba = np.zeros((20, 30, 4), np.uint8)
    for call in (lambda: detect("oracle", rgba, instances=np.zeros((20, 30), np.int32)),
                 lambda: reconstruct(rgba, K, []), lambda: write_outputs(tmp_path / "o", rgba, K, [])):
        with pytest.raises(ImageError, match=r"image must be \(H, W, 3\) RGB, got shape \(20, 30, 4\)") as e:
            call()
        assert isinstance(e.value, PipelineError) and isinstance(e.value, ValueError)
    with pytest.raises(ImageError, match="uint8, got dtype float32"):
        reconstruct(red.astype(np.float32), K, [])


def test_shared_memo_gives_each_configs_own_results():
    """One pipeline.memo.StepMemo for every snapper x pose config on a photo (as the bench keeps
    one per view), with K and without: each config's results are bit for bit those of a run
    without it (timings aside), and the per-window solvers of one snapper shared its snapping."""
    from dataclasses import fields  # noqa: PLC0415

    from fenestra.pipeline.memo import StepMemo  # noqa: PLC0415
    from fenestra.pipeline.reconstruct import fit_quads, reconstruct_from_quads, to_gray  # noqa: PLC0415
    from fenestra.pipeline.segments import SegmentCache  # noqa: PLC0415

    rgb, inst, _ = scene()
    dets = detections_from_instance_map(inst)
    gray = to_gray(rgb)
    quads = fit_quads(dets, ReconstructConfig().quad, gray.shape)

    def same(a, b):
        return all((x.tobytes() == y.tobytes() and x.shape == y.shape) if isinstance(x, np.ndarray) else x == y
                   for r, s in zip(a, b) for f in fields(r) if f.name != "timings_ms"
                   for x, y in [(getattr(r, f.name), getattr(s, f.name))])

    for K_in in (K, None):
        memo, cache = StepMemo(), SegmentCache(gray)
        for snapper in ("none", "linefit"):
            for pose in ("lm", "ippe", "wall", "building+lines"):
                cfg = ReconstructConfig(snapper=snapper, pose=pose, height_m=1.4)
                shared = reconstruct_from_quads(gray, K_in, dets, quads, cfg, segment_cache=cache, memo=memo)
                alone = reconstruct_from_quads(gray, K_in, dets, quads, cfg)
                assert len(shared) == len(alone) == 2 and same(shared, alone), (snapper, pose, K_in is None)
        assert memo.hits >= 2 * 2 * 3  # at least: per snapper, ippe and the walls' base reuse lm's snapping
