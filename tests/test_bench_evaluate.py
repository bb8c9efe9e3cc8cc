"""bench.evaluate on a view folder built by hand in this test (not a renders/ output).

A wall in the plane y = 0 (outward normal -y) with three window voids seen by a known camera:
the image is drawn with exact area coverage (renders.quad_image, independent of the code under
test), the instance map by pixel centres, view.json from the camera and the world corners. The
third window hangs off the image edge; a fourth is listed but hidden (absent from the map).
"""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from bench.evaluate import ViewTask, evaluate_view, window_conditions
from fenestra.methods import Method
from bench.profiles import EvalSpec
from fenestra.conventions import K_from_fov, look_at, project
from renders.quad_image import coverage, pixel_centre_mask

W, H = 640, 480


def _window(x0: float, z0: float, w: float, h: float) -> np.ndarray:
    """World corners TL, TR, BR, BL of a void on the wall y = 0 seen from -y."""
    return np.array([[x0, 0, z0 + h], [x0 + w, 0, z0 + h], [x0 + w, 0, z0], [x0, 0, z0]], float)


@pytest.fixture(scope="module")
def view_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("views") / "000000"
    d.mkdir()
    K = K_from_fov(W, H, 60.0)
    R, t = look_at(eye=[1.0, -7.0, 2.0], target=[2.5, 0.0, 1.6])
    wins = [_window(0.5, 1.0, 1.2, 1.4), _window(2.6, 1.0, 0.9, 1.4), _window(6.0, 1.0, 1.6, 1.4),
            _window(0.5, 3.0, 0.8, 0.8)]
    img = np.full((H, W), 190.0)
    inst = np.zeros((H, W), np.uint16)
    meta_wins = []
    for k, C in enumerate(wins, start=1):
        q = project(K, R, t, C)
        if k < 4:  # window 4 is hidden behind something: listed, never drawn
            img += (35.0 - 190.0) * coverage(q, (H, W))
            inst[pixel_centre_mask(q, (H, W))] = k
        n = np.array([0.0, -1.0, 0.0])
        cam = -R.T @ t
        v = cam - C.mean(0)
        meta_wins.append({"id": f"W{k}", "instance_id": k, "corners_world": C.tolist(),
                          "corners_px": q.tolist(), "corner_visible": [k < 4] * 4,
                          "visible_fraction": 1.0 if k < 4 else 0.0,
                          "incidence_deg": float(np.degrees(np.arccos(n @ v / np.linalg.norm(v)))),
                          "distance_m": float(np.linalg.norm(v))})
    rgb = np.repeat(np.clip(np.round(img), 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
    cv2.imwrite(str(d / "image.png"), rgb)
    cv2.imwrite(str(d / "instances.png"), inst)
    (d / "view.json").write_text(json.dumps({"K": K.tolist(), "width": W, "height": H,
                                             "R": R.tolist(), "t": t.tolist(), "distortion": None,
                                             "renderer": "hand", "seed": 0, "windows": meta_wins}))
    return d


def _run(view_dir, methods):
    return evaluate_view(ViewTask(str(view_dir), "hand", "hand", tuple(methods), EvalSpec()))


def test_every_gt_window_gets_a_row_per_method(view_dir):
    methods = [Method("oracle", "none", "lm"), Method("oracle", "none", "ippe")]
    out = _run(view_dir, methods)
    assert len(out.rows) == 4 * 2
    by = {(r["window_id"], r["pose"]): r for r in out.rows}
    assert by[("W3", "lm")]["eval_reason"] == "out_of_frame" and not by[("W3", "lm")]["evaluable"]
    assert by[("W4", "lm")]["status"] == "missed" and by[("W4", "lm")]["eval_reason"] == "hidden"
    assert np.isnan(by[("W4", "lm")]["corner_err_px_snap"])
    for w in ("W1", "W2"):
        r = by[(w, "lm")]
        assert r["evaluable"] and r["status"] == "ok", r
        # exact masks of a sharp void: the mask-fit quad is within a pixel of the projected corners
        assert r["corner_err_px_mask"] < 1.0
        assert r["corner_err_px_reproj"] < 1.5
        assert r["aspect_err_rel"] < 0.05
        assert r["rot_err_deg"] < 5.0 and r["normal_err_deg"] <= r["rot_err_deg"] + 1e-9
        assert r["match_iou"] == pytest.approx(1.0)
        assert r["iou_2d"] > 0.95
    # stage times were recorded
    assert out.stage_s["detect"] > 0 and out.stage_s["reconstruct"] > 0
    assert out.n_false_positives["oracle"] == 0
    assert len(out.coco_gt) == 3 and len(out.coco_dt["oracle"]) == 3


def test_window_conditions_reasons(view_dir):
    meta = json.loads((view_dir / "view.json").read_text())
    inst = cv2.imread(str(view_dir / "instances.png"), cv2.IMREAD_UNCHANGED).astype(np.int32)
    w1 = meta["windows"][0]
    px = int(np.count_nonzero(inst == w1["instance_id"]))
    c = window_conditions(w1, meta, px, EvalSpec())
    assert c["evaluable"] and c["corners_in_frame"]
    assert c["gt_aspect"] == pytest.approx(1.2 / 1.4)
    # independent check of the size columns: pixel count of the mask vs polygon area
    assert c["mask_px"] == pytest.approx(c["window_area_px"], rel=0.02)
    strict = EvalSpec(min_window_px=1000.0)
    assert window_conditions(w1, meta, px, strict)["eval_reason"] == "too_small"
    part = dict(w1, visible_fraction=0.5)
    assert window_conditions(part, meta, px, EvalSpec())["eval_reason"] == "occluded"


def test_rows_identical_with_dense_reference_matching(view_dir, monkeypatch):
    """The sparse IoU (crops of overlapping boxes) gives the rows of full-image dense matching."""
    from bench import matching
    from fenestra.data import SparseMask

    methods = [Method("oracle", "none", "lm"), Method("oracle-degraded", "linefit", "ippe")]
    sparse = _run(view_dir, methods).rows

    def dense_iou(det, gt):
        d = [m.dense() if isinstance(m, SparseMask) else np.asarray(m, bool) for m in det]
        g = [m.dense() if isinstance(m, SparseMask) else np.asarray(m, bool) for m in gt]
        out = np.zeros((len(d), len(g)))
        for i, a in enumerate(d):
            for j, b in enumerate(g):
                u = np.sum(a | b)
                out[i, j] = np.float32(np.sum(a & b)) / np.float32(max(u, 1)) if u else 0.0
        return out

    monkeypatch.setattr(matching, "iou_matrix", dense_iou)
    dense = _run(view_dir, methods).rows
    assert len(sparse) == len(dense) == 8
    for a, b in zip(sparse, dense):
        assert a.keys() == b.keys()
        for k in a:
            same = (a[k] == b[k]) or (isinstance(a[k], float) and np.isnan(a[k]) and np.isnan(b[k]))
            assert same, (k, a[k], b[k])


def test_per_wall_rows_same_with_and_without_reused_per_window_results(view_dir):
    """A per-wall method reuses the per-window (ippe) run of its snapper when the same view runs it:
    its rows equal those of a view that runs the per-wall method alone."""
    alone = _run(view_dir, [Method("oracle", "none", "wall")]).rows
    shared = [r for r in _run(view_dir, [Method("oracle", "none", "ippe"), Method("oracle", "none", "wall"),
                                         Method("oracle", "none", "building")]).rows if r["pose"] == "wall"]
    assert len(alone) == len(shared) == 4
    assert any(r["status"] == "ok" for r in alone)
    for a, b in zip(alone, shared):
        assert a.keys() == b.keys()
        for k in a:
            same = (a[k] == b[k]) or (isinstance(a[k], float) and np.isnan(a[k]) and np.isnan(b[k]))
            assert same, (k, a[k], b[k])


def test_reconstruct_base_only_for_per_wall_strategies():
    from pipeline.reconstruct import ReconstructConfig, reconstruct_from_quads

    with pytest.raises(ValueError, match="base: 0 per-window results given for pose 'lm'"):
        reconstruct_from_quads(np.zeros((20, 20), np.float32), None, [], [], ReconstructConfig(pose="lm"), base=[])
