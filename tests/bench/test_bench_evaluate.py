"""bench.evaluate on a view folder built by hand in this test (not a renders/ output), read by the
rendered-view adapter (bench.render_adapter.read_rendered_view) into the one LabelledView.

A wall in the plane y = 0 (outward normal -y) with three window voids seen by a known camera:
the image is drawn with exact area coverage (renders.quad_image, independent of the code under
test), the instance map by pixel centres, view.json from the camera and the world corners. The
third window hangs off the image edge; a fourth is listed but hidden (absent from the map).
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest

from fenestra.bench.evaluate import (BIM_COLUMNS, MODEL_COLUMNS, PHOTO_COLUMNS, RENDER_COLUMNS, EvalOptions, ViewTask,
                                     evaluate_task, evaluate_view, render_conditions)
from fenestra.methods import Method
from fenestra.bench.profiles import EvalSpec
from fenestra.bench.render_adapter import RenderedViewRef, read_rendered_view
from fenestra.conventions import K_from_fov, look_at, project
from quad_image import coverage, pixel_centre_mask

W, H = 640, 480


def _window(x0: float, z0: float, w: float, h: float) -> np.ndarray:
    """World corners TL, TR, BR, BL of a void on the wall y = 0 seen from -y."""
    return np.array([[x0, 0, z0 + h], [x0 + w, 0, z0 + h], [x0 + w, 0, z0], [x0, 0, z0]], float)


def _write_view(d: Path, wins: list[np.ndarray], hidden: tuple[int, ...] = (), ignore: tuple[int, ...] = (),
                unlisted: tuple[int, ...] = ()) -> Path:
    """A view folder of voids on the wall y = 0 (world corners ``wins``; instance id k + 1 each):
    the image drawn with exact area coverage, the instance map by pixel centres. ``hidden``: listed
    windows never drawn; ``ignore``: voids drawn and in the instance map but listed as ignore
    regions (glazed doors: view.json's ``ignore``, ignore.png), not windows; ``unlisted``: voids
    drawn and in the instance map but neither window nor ignore region (a dark panel)."""
    d.mkdir()
    K = K_from_fov(W, H, 60.0)
    R, t = look_at(eye=[1.0, -7.0, 2.0], target=[2.5, 0.0, 1.6])
    img = np.full((H, W), 190.0)
    inst = np.zeros((H, W), np.uint16)
    ign = np.zeros((H, W), np.uint16)
    meta_wins, meta_ignore = [], []
    for k, C in enumerate(wins, start=1):
        q = project(K, R, t, C)
        if k not in hidden:
            img += (35.0 - 190.0) * coverage(q, (H, W))
            inst[pixel_centre_mask(q, (H, W))] = k
        if k in ignore:
            ign[pixel_centre_mask(q, (H, W))] = k
            meta_ignore.append({"id": f"D{k}", "instance_id": k, "kind": "glazed_door"})
        if k in ignore or k in unlisted:
            continue
        n = np.array([0.0, -1.0, 0.0])
        cam = -R.T @ t
        v = cam - C.mean(0)
        meta_wins.append({"id": f"W{k}", "instance_id": k, "corners_world": C.tolist(),
                          "corners_px": q.tolist(), "corner_visible": [k not in hidden] * 4,
                          "visible_fraction": 0.0 if k in hidden else 1.0,
                          "incidence_deg": float(np.degrees(np.arccos(n @ v / np.linalg.norm(v)))),
                          "distance_m": float(np.linalg.norm(v))})
    rgb = np.repeat(np.clip(np.round(img), 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
    cv2.imwrite(str(d / "image.png"), rgb)
    cv2.imwrite(str(d / "instances.png"), inst)
    meta = {"K": K.tolist(), "width": W, "height": H, "R": R.tolist(), "t": t.tolist(), "distortion": None,
            "renderer": "hand", "seed": 0, "windows": meta_wins}
    if meta_ignore:
        cv2.imwrite(str(d / "ignore.png"), ign)
        meta["ignore"] = meta_ignore
    (d / "view.json").write_text(json.dumps(meta))
    return d


@pytest.fixture(scope="module")
def view_dir(tmp_path_factory):
    wins = [_window(0.5, 1.0, 1.2, 1.4), _window(2.6, 1.0, 0.9, 1.4), _window(6.0, 1.0, 1.6, 1.4),
            _window(0.5, 3.0, 0.8, 0.8)]
    return _write_view(tmp_path_factory.mktemp("views") / "000000", wins, hidden=(4,))  # window 4: behind something


def _run(view_dir, methods):
    return evaluate_view(read_rendered_view(view_dir, "hand", "hand"), tuple(methods), EvalOptions())


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
    view = read_rendered_view(view_dir, "hand", "hand")
    inst = cv2.imread(str(view_dir / "instances.png"), cv2.IMREAD_UNCHANGED).astype(np.int32)
    w1 = view.windows[0]
    c = render_conditions(view, w1, EvalSpec())
    assert c["evaluable"] and c["corners_in_frame"]
    assert c["gt_aspect"] == pytest.approx(1.2 / 1.4)
    assert c["gt_width_m"] == pytest.approx(1.2) and c["gt_height_m"] == pytest.approx(1.4)
    assert c["mask_px"] == int(np.count_nonzero(inst == 1))
    # independent check of the size columns: pixel count of the mask vs polygon area
    assert c["mask_px"] == pytest.approx(c["window_area_px"], rel=0.02)
    strict = EvalSpec(min_window_px=1000.0)
    assert render_conditions(view, w1, strict)["eval_reason"] == "too_small"
    part = dataclasses.replace(w1, visible_fraction=0.5)
    assert render_conditions(view, part, EvalSpec())["eval_reason"] == "occluded"


def test_rendered_view_adapter_reads_the_contract(view_dir):
    """Exact truth of a render: view.json's corners, world corners and pose, masks from
    instances.png (the hidden window's empty), K; no ignore region listed."""
    meta = json.loads((view_dir / "view.json").read_text())
    v = read_rendered_view(view_dir, "hand", "hand")
    assert (v.dataset, v.name, v.key, v.renderer, v.size) == ("hand", "000000", "hand/000000", "hand", (H, W))
    np.testing.assert_array_equal(v.K, meta["K"])
    np.testing.assert_array_equal(v.pose[0], meta["R"])
    assert [w.id for w in v.windows] == ["W1", "W2", "W3", "W4"] and v.ignore == ()
    for w, m in zip(v.windows, meta["windows"]):
        np.testing.assert_array_equal(w.quad, m["corners_px"])
        np.testing.assert_array_equal(w.corners_world, m["corners_world"])
        assert w.instance_id == m["instance_id"] and w.box is None and not w.partial
    assert [w.mask.area for w in v.windows][3] == 0 and all(w.mask.area > 0 for w in v.windows[:3])
    assert v.instance_map() is v.instances


def _same(a, b) -> bool:
    """Equal, NaN == NaN (None for NaN in JSON), floats to 1e-9 relative."""
    if isinstance(a, float) and np.isnan(a):
        return b is None or (isinstance(b, float) and np.isnan(b))
    if isinstance(a, float) and isinstance(b, float):
        return a == pytest.approx(b, rel=1e-9, abs=1e-12)
    return a == b


def test_rows_equal_those_of_the_former_render_evaluator(view_dir):
    """The one evaluation path gives a render the rows the render-only evaluator of commit 991c33e
    gave (tests/golden/hand_view_rows.json, written by that code): every column and value, for
    per-window, per-wall and degraded-oracle methods, with two changes the session made on purpose
    (the bench runs what `fenestra reconstruct` runs): a per-window method's ``wall_id`` is now
    its façade plane (the CLI's façade model: one wall here), and a K-withheld method goes through
    the focal chain (vanishing points here) instead of the per-wall fit's free focal length, so its
    pose-side values change while its mask and snapped corners do not."""
    golden = json.loads((Path(__file__).resolve().parents[1] / "golden" / "hand_view_rows.json").read_text())
    methods = tuple(Method.from_label(m) for m in golden["methods"])
    rows = _run(view_dir, methods).rows
    assert len(rows) == len(golden["rows"]) == 20
    for r, g in zip(rows, golden["rows"]):
        assert list(r) == list(RENDER_COLUMNS) and set(r) == set(g) | set(BIM_COLUMNS) | set(MODEL_COLUMNS), set(r) ^ set(g)
        bad = {k: (r[k], g[k]) for k in g if not _same(r[k], g[k])}
        if r["status"] == "missed":
            assert not bad and all(_same(r[k], float("nan")) for k in BIM_COLUMNS), (r["method"], r["window_id"], bad)
            continue
        if r["pose"].endswith("+noK"):
            assert r["K_source"] in ("vanishing points", "prior")  # here: the vanishing points are too vague
            if r["K_source"] == "prior":  # a 65 deg field of view along the long side, as DESIGN.md states
                assert r["K_focal_px"] == pytest.approx(max(W, H) / 2 / math.tan(math.radians(65 / 2)))
            assert not {k for k in bad if k.startswith(("corner_err_px_mask", "corner_err_px_snap", "iou_2d_mask"))}
            if r["K_source"] == "vanishing points":  # the chain's focal length, then a fit with it fixed: where
                # the free-focal joint fit landed, to float noise (the same vanishing geometry)
                # the error bars now come from a fit with K fixed (narrower: the focal length's own
                # uncertainty is not in them), so the interval columns may change
                intervals = {"aspect_ci90_rel", "rot_ci90_deg", "aspect_in90", "rot_in90", "trans_in90"}
                focal = {"focal_est_px", "focal_err_rel"}  # the photo's K: now on every window, one the fit left out too
                far = {k: v for k, v in bad.items() if k not in intervals and not (k in focal and v[1] is None) and not (
                    v[1] is not None and float(v[0]) == pytest.approx(v[1], rel=1e-6, abs=1e-9))}
                assert not far, far
            else:
                assert not bad or {"focal_est_px", "focal_err_rel"} <= set(bad)
            continue
        assert r["K_source"] == "K" and r["K_focal_px"] == pytest.approx(g_focal(view_dir))
        if r["status"] == "ok" and g["wall_id"] is None:  # a per-window method: now on the façade model's wall
            assert bad.pop("wall_id") == (0.0, None)
        assert not bad, (r["method"], r["window_id"], bad)


def g_focal(view_dir) -> float:
    """The view's true focal length (view.json's K), read independently of the code under test."""
    return float(json.loads((Path(view_dir) / "view.json").read_text())["K"][0][0])


def test_render_and_photo_tables_share_columns_and_dtypes(view_dir, tmp_path):
    """A render's and a photo's rows (the same oracle method) make tables whose columns are the
    two kinds' pinned ones (as results tables of commit 991c33e had them) and whose common columns
    have the same dtypes."""
    from fenestra.bench.real.adapters import read_coco
    from test_bench_real import _rectangle_view

    m = (Method("oracle", "none", "lm"),)
    render = pd.DataFrame(_run(view_dir, m).rows)
    folder, *_ = _rectangle_view(tmp_path)
    (photo_view,) = list(read_coco(folder))
    photo = pd.DataFrame(evaluate_view(photo_view, m, EvalOptions(detector_long_side=640)).rows)
    before_render = ["house", "renderer", "view", "window_id", "instance_id", "incidence_deg", "distance_m",
                     "visible_fraction", "n_corners_visible", "corners_in_frame", "window_px", "window_area_px",
                     "mask_px", "gt_width_m", "gt_height_m", "gt_aspect", "evaluable", "eval_reason"]
    before_photo = ["house", "dataset", "renderer", "view", "window_id", "instance_id", "incidence_deg",
                    "distance_m", "visible_fraction", "window_px", "gt_aspect", "has_quad", "has_box", "has_mask",
                    "has_aspect", "has_size", "has_pose", "known_K", "evaluable", "eval_reason"]
    errors = ["corner_err_px_mask", "corner_err_px_mask_max", "corner_err_px_snap", "corner_err_px_snap_max",
              "corner_err_px_reproj", "corner_err_px_reproj_max", "snap_gain_px", "aspect_est", "aspect_err_rel",
              "rot_err_deg", "normal_err_deg", "trans_err_m", "iou_2d", "iou_2d_mask", "iou_2d_reproj",
              "match_iou", "det_score", "corner_err_px_head"]
    method = ["detector", "snapper", "pose", "method"]
    bim = ["K_source", "K_focal_px", "scale_source", "exported", "not_exported", "width_err_m", "height_err_m",
           "pos_err_m", "scale_source_storey", "width_err_m_storey", "height_err_m_storey", "pos_err_m_storey"]
    assert list(render.columns) == list(RENDER_COLUMNS) == before_render + method + errors + [
        "focal_est_px", "focal_err_rel", "aspect_in90", "rot_in90", "trans_in90", "aspect_ci90_rel", "rot_ci90_deg",
        "wall_id", *bim, "model_up_err_deg", "model_wall_tilt_deg", "model_storey", "true_storey", "model_n_storeys",
        "true_n_storeys", "status", "reason", "aspect_case"]
    assert list(photo.columns) == list(PHOTO_COLUMNS) == before_photo + method + errors + [
        "reproj_consistency_px", "rel_size_err", *bim, "aspect_case", "status", "reason"]
    common = [c for c in render.columns if c in photo.columns]
    assert len(common) == 12 + 4 + 18 + 12 + 3
    assert {c: (render[c].dtype, photo[c].dtype) for c in common if render[c].dtype != photo[c].dtype} == {}
    # a photo has no pose truth: pose errors absent (NaN), not 0; the render has them
    assert photo["rot_err_deg"].isna().all() and render.loc[render.status == "ok", "rot_err_deg"].notna().all()
    assert (photo["renderer"] == "photo").all() and (photo["instance_id"] == -1).all()


def test_task_reads_the_view_in_the_worker(view_dir):
    """evaluate_task (what the executors run) gives evaluate_view's rows and times the load."""
    m = (Method("oracle", "none", "lm"),)
    out = evaluate_task(ViewTask(RenderedViewRef(str(view_dir), "hand", "hand"), m, EvalOptions()))
    ref = _run(view_dir, m)
    assert out.key == "hand/000000" and out.size == (H, W) and out.window_ids == ("W1", "W2", "W3", "W4")
    assert out.stage_s["load"] > 0
    assert all(a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a) for a, b in zip(out.rows, ref.rows))


def test_rows_identical_with_dense_reference_matching(view_dir, monkeypatch):
    """The sparse IoU (crops of overlapping boxes) gives the rows of full-image dense matching."""
    from fenestra.bench import matching
    from fenestra.masks import SparseMask

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
    from fenestra.pipeline.reconstruct import ReconstructConfig, reconstruct_from_quads

    with pytest.raises(ValueError, match="base: 0 per-window results given for pose 'lm'"):
        reconstruct_from_quads(np.zeros((20, 20), np.float32), None, [], [], ReconstructConfig(pose="lm"), base=[])


def test_quad_iou_memo_gives_quad_iou_once_per_pair():
    from fenestra.bench import metrics
    from fenestra.bench.evaluators import QuadIoUMemo

    memo, gt = QuadIoUMemo(), np.array([[0, 0], [10, 0], [10, 10], [0, 10.0]])
    for q in (gt + 1.0, gt + 2.5, gt + 1.0, gt * 0.5):
        assert memo(q, gt) == metrics.quad_iou(q, gt)
    assert len(memo._seen) == 3


def _shifted_corner_detector(**_):
    """The oracle's masks with a corner head that reads each mask-fit quad 1.5 px to the right."""
    import dataclasses

    from fenestra.pipeline.detectors.oracle import check_instances, oracle_detections
    from fenestra.pipeline.quad import mask_to_quad

    def run(image, instances=None):
        dets = oracle_detections(check_instances(instances, image.shape))
        out = []
        for d in dets:
            q = mask_to_quad(d.mask)  # crop coordinates: d.origin (x, y) is the crop's corner
            shift = np.asarray(d.origin, float) + [1.5, 0.0]
            out.append(dataclasses.replace(d, corners=None if q.quad is None else q.quad + shift))
        return out
    return run


def test_per_wall_reuse_keeps_quad_sources_apart(view_dir):
    """A per-wall method with corner-head quads must not reuse the per-window results of the mask
    fit's quads (the reuse key holds the quad parameters): its rows equal those of a run alone."""
    from fenestra.pipeline.detectors import DETECTORS, DetectorEntry

    DETECTORS.register(DetectorEntry("shifted-corners", _shifted_corner_detector, "test: oracle + shifted corners",
                                     needs_instances=True))
    try:
        corners = Method("shifted-corners", "none", "wall", quad_source="corners")
        alone = _run(view_dir, [corners]).rows
        shared = [r for r in _run(view_dir, [Method("shifted-corners", "none", "wall"), corners]).rows
                  if r["method"] == corners.label]
        mask_rows = [r for r in _run(view_dir, [Method("shifted-corners", "none", "wall")]).rows]
    finally:
        DETECTORS.unregister("shifted-corners")
    assert len(alone) == len(shared) == 4 and any(r["status"] == "ok" for r in alone)
    ok = [i for i, r in enumerate(alone) if r["status"] == "ok"]
    assert any(abs(alone[i]["corner_err_px_mask"] - mask_rows[i]["corner_err_px_mask"]) > 0.5 for i in ok)
    for a, b in zip(alone, shared):
        for k in a:
            same = (a[k] == b[k]) or (isinstance(a[k], float) and np.isnan(a[k]) and np.isnan(b[k]))
            assert same, (k, a[k], b[k])


@pytest.fixture(scope="module")
def door_view_dir(tmp_path_factory):
    """Two windows, a glazed door (an ignore region: a negative) and a dark panel that is neither
    window nor door; the oracle detects all four voids (instance ids 1-4), so what each detection
    is, is known by construction."""
    wins = [_window(0.5, 1.0, 1.2, 1.4), _window(2.6, 1.0, 0.9, 1.4), _window(4.2, 0.0, 1.0, 2.2),
            _window(2.6, 3.0, 0.8, 0.8)]
    return _write_view(tmp_path_factory.mktemp("doors") / "000000", wins, ignore=(3,), unlisted=(4,))


WHAT = {1: "n_matched", 2: "n_matched", 3: "n_on_ignore", 4: "n_on_nothing"}  # door_view_dir's voids by instance id


def test_export_counts_know_the_door_and_the_panel(door_view_dir):
    """Per method, the exported detections: matched to a window, on the door (a false export) or on
    nothing; what each detection is comes from the view's construction (its instance id), the
    export decision from the session's run of the method (what `fenestra reconstruct` exports)."""
    from fenestra.bench.evaluate import view_session
    from fenestra.bench.results import add_export_precision, export_precision

    view = read_rendered_view(door_view_dir, "hand", "hand")
    assert [w.id for w in view.windows] == ["W1", "W2"] and [r.id for r in view.ignore] == ["D3"]
    methods = (Method("oracle", "none", "lm"), Method("oracle", "linefit", "ippe"))
    out = evaluate_view(view, methods, EvalOptions())
    session = view_session(view, EvalOptions(), ("oracle",))
    for m in methods:
        rec = session.run(m)
        assert [d.instance_id for d in rec.detections] == [1, 2, 3, 4]
        want = {"n_exported": 0, "n_matched": 0, "n_on_ignore": 0, "n_on_nothing": 0, "n_on_door": 0}
        for d, exported in rec.exported.items():
            if exported:
                want["n_exported"] += 1
                want[WHAT[rec.detections[d].instance_id]] += 1
                want["n_on_door"] += rec.detections[d].instance_id == 3  # the glazed door: written as an IfcWindow
        assert out.export_counts[m.name] == want
    # every void is a plausible window here: the door and the panel are exported, and counted as false
    assert out.export_counts["oracle/none/lm"] == {"n_exported": 4, "n_matched": 2, "n_on_ignore": 1, "n_on_nothing": 1,
                                                   "n_on_door": 1}
    assert [r.kind for r in view.ignore] == ["glazed_door"]
    assert out.n_false_positives["oracle"] == 2
    prec = export_precision([out, out])
    assert prec["oracle/none/lm"] == {"n_exported": 8, "n_matched": 4, "n_on_ignore": 2, "n_on_nothing": 2,
                                      "n_on_door": 2, "n_views": 2, "precision": 0.5}
    summary = add_export_precision({"oracle/none/lm": {"n_gt": 2}}, [out])
    assert summary["oracle/none/lm"]["export"]["precision"] == 0.5 and "oracle/linefit/ippe" not in summary


def test_a_detection_on_a_door_box_is_on_the_ignore_region(door_view_dir):
    """Ignore regions labelled by box only (a photo's): a detection is on one when at least
    TOL.match_iou of its box lies inside; the door's own box, then that box moved sideways by 60 %
    of its width (40 % of the detection inside) and by 40 % (60 % inside)."""
    from fenestra.bench.evaluate import on_ignore
    from fenestra.bench.views import LabelledWindow
    from fenestra.masks import SparseMask

    view = read_rendered_view(door_view_dir, "hand", "hand")
    inst = cv2.imread(str(door_view_dir / "instances.png"), cv2.IMREAD_UNCHANGED)
    masks = [SparseMask.from_dense(inst == k) for k in (1, 2, 3, 4)]
    dets = [dataclasses.make_dataclass("D", ["box"])(m.box()) for m in masks]
    assert on_ignore(view, masks, dets) == {2: "glazed_door"}  # by mask: the door is detection 2
    b = masks[2].box()
    for shift, want in ((0.0, {2: None}), (0.6, {}), (0.4, {2: None})):  # a box label says no kind
        box = b + np.array([1, 0, 1, 0]) * shift * (b[2] - b[0])
        boxed = dataclasses.replace(view, ignore=(LabelledWindow("D3", box=box),))
        assert on_ignore(boxed, masks, dets) == want, shift


def test_each_evaluator_returns_its_own_columns_and_together_they_fill_the_table(tmp_path):
    """bench.evaluators: on a hand-made render (three windows, one off the image's edge) every
    evaluator returns, per matched labelled window, only the columns it declares; together their
    columns are every error and BIM column of the render table (the loop adds status, reason,
    aspect case); the evaluate_view rows hold exactly the merged values."""
    from fenestra.bench.evaluate import RENDER_TAIL, _match_ious, view_session
    from fenestra.bench import matching
    from fenestra.bench.evaluators import MethodResult, default_evaluators
    from fenestra.masks import SparseMask
    from fenestra.tolerances import TOL

    wins = [_window(0.5, 1.0, 1.2, 1.4), _window(2.6, 1.0, 0.9, 1.4), _window(6.0, 1.0, 1.6, 1.4)]
    view = read_rendered_view(_write_view(tmp_path / "000000", wins), "hand", "hand")
    method = Method("oracle", "linefit", "wall")
    rec = view_session(view, EvalOptions(), ("oracle",)).run(method)
    dets = list(rec.detections)
    det_masks = [SparseMask.from_crop(d.mask, d.origin, view.size) for d in dets]
    det_for_gt = matching.match(_match_ious(view, det_masks, dets), TOL.match_iou).det_for_gt()
    assert sorted(det_for_gt) == [0, 1, 2]
    evaluators = default_evaluators()
    merged = {g: {} for g in det_for_gt}
    for e in evaluators:
        e.reset(view)
        got = e.process(view, MethodResult(rec, None, det_for_gt))
        assert set(got) <= set(det_for_gt), type(e).__name__
        for g, cols in got.items():
            assert set(cols) <= set(e.columns), (type(e).__name__, set(cols) - set(e.columns))
            merged[g].update(cols)
    declared = {c for e in evaluators for c in e.columns}
    assert set(RENDER_TAIL) - {"status", "reason", "aspect_case"} <= declared
    rows = {r["window_id"]: r for r in evaluate_view(view, (method,), EvalOptions()).rows}
    for g, cols in merged.items():
        row = rows[view.windows[g].id]
        for c, v in cols.items():
            if c in RENDER_TAIL and not c.endswith("_storey"):  # the rows also know the true storey
                assert row[c] == v or (v != v and row[c] != row[c]), (g, c, row[c], v)


def test_bench_rows_measure_a_cut_window_as_whole_and_count_its_export():
    """bench.evaluate on a view whose third window hangs off the image's right edge
    (tests/bench/test_bench_evaluate.py's): its row is not evaluable and keeps the quad stage's
    touches_border failure and NaN sizes (the visible part is not the window), while it is exported
    completed to its row's width (``exported`` 1) and matched in the export counts."""
    import math

    from fenestra.bench.evaluate import EvalOptions, evaluate_view, view_session
    from fenestra.bench.render_adapter import read_rendered_view
    from fenestra.methods import Method

    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        wins = [_window(0.5, 1.0, 1.2, 1.4), _window(2.6, 1.0, 1.2, 1.4), _window(6.4, 1.0, 1.2, 1.4)]
        view = read_rendered_view(_write_view(Path(tmp) / "000000", wins), "hand", "hand")
        method = Method("oracle", "none", "wall")
        out = evaluate_view(view, (method,), EvalOptions())
        rec = view_session(view, EvalOptions(), ("oracle",)).run(method)
    rows = {r["window_id"]: r for r in out.rows}
    cut = rows["W3"]
    assert not cut["evaluable"] and cut["eval_reason"] == "out_of_frame"
    assert cut["status"] == "failed" and "touches_border" in cut["reason"]
    assert math.isnan(cut["corner_err_px_snap"]) and math.isnan(cut["width_err_m"])
    assert cut["exported"] == 1.0 and cut["scale_source"] == "assumed"
    d = next(i for i, det in enumerate(rec.detections) if det.instance_id == 3)
    assert rec.windows[d].partial.cut == ("right",) and rec.windows[d].measured.failure.stage == "quad"
    # the window's record keeps every stage: the fit and the façade model's whole-window failure, its
    # visible part placed on the wall, what the model holds (that part) and what the bench measures
    cut_win = rec.windows[d]
    assert cut_win.fit.failure.code == cut_win.measured.failure.code == "touches_border"
    assert cut_win.placed is not None and cut_win.placed.failure is None and cut_win.placed.partial.cut == ("right",)
    assert cut_win.result is cut_win.placed and cut_win.shipped is cut_win.measured
    assert cut_win.wall == rec.model.wall_of(d).id and cut_win.export.exported
    for k, win in enumerate(rec.windows):
        if k == d:
            continue
        assert win.placed is None and win.fit.group is not None and win.measured.group == win.fit.group
        assert win.fit.height_m == 1.0 != win.measured.height_m  # the fit's scale parameter; the wall's scale
        assert win.result is (win.regularized or win.measured) and win.shipped is win.result
        assert win.wall == rec.model.wall_of(k).id
    assert all(rows[w]["evaluable"] and rows[w]["status"] == "ok" for w in ("W1", "W2"))
    assert out.export_counts[method.name] == {"n_exported": 3, "n_matched": 3, "n_on_ignore": 0, "n_on_nothing": 0,
                                                 "n_on_door": 0}


def _leaned(C: np.ndarray, deg: float) -> np.ndarray:
    """World corners C (N, 3) turned by ``deg`` about the world x axis: the wall y = 0 leaning."""
    a = math.radians(deg)
    return C @ np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]]).T


@pytest.mark.parametrize("lean_deg", [0.0, 4.0])
def test_the_written_model_against_the_true_vertical_and_the_houses_storeys(tmp_path, lean_deg):
    """bench.evaluators.ModelEvaluator on a hand-made render read as a view of the FZK-Haus (its
    IFC's storeys: the ground floor at 0 m, the next at 2.7 m): two rows of three windows, sills at
    0.5 m and 2.9 m, are the model's two storey rows, each window in its own storey; on a plumb
    wall the written model's vertical and the wall's tilt are within half a degree of the truth
    (the world's z); the same windows on a wall leaning 4 deg: the wall's tilt is 4 deg, and so is
    the model's vertical, the walls' own up axis (the written model has no other)."""
    from fenestra.scenes.storeys import facade_levels, storey_index

    wins = [_leaned(_window(x, z, 0.9, h), lean_deg) for z, h in ((0.5, 1.0), (2.9, 0.7)) for x in (0.5, 2.0, 3.5)]
    view = read_rendered_view(_write_view(tmp_path / "000000", wins), "fzk-haus", "hand")
    methods = (Method("oracle", "linefit", "lm"), Method("oracle", "none", "wall"))
    rows = evaluate_view(view, methods, EvalOptions()).rows
    assert len(rows) == 12 and all(r["status"] == "ok" and r["exported"] == 1.0 for r in rows)
    for r in rows:
        k = int(r["window_id"][1:])
        assert r["true_storey"] == (0 if k <= 3 else 1) == r["model_storey"], r["window_id"]
        assert r["model_n_storeys"] == r["true_n_storeys"] == 2
        assert r["model_wall_tilt_deg"] == pytest.approx(lean_deg, abs=0.5), r["method"]
        assert r["model_up_err_deg"] == pytest.approx(lean_deg, abs=0.5), r["method"]
    assert facade_levels([2.7, 0.0, -1.2, 2.7]) == [0.0, 2.7]  # a basement is no façade storey
    assert [storey_index(z, [0.0, 2.7]) for z in (-0.1, 0.0, 2.69, 2.7, 9.0)] == [None, 0, 0, 1, 1]
    assert storey_index(1.0, []) is None
    photo = dataclasses.replace(view, pose=None)
    from fenestra.bench.evaluators import ModelEvaluator, true_storeys
    assert true_storeys(photo) == {} and true_storeys(view) == {0: 0, 1: 0, 2: 0, 3: 1, 4: 1, 5: 1}
    assert ModelEvaluator().process(photo, None) == {}  # a photo has no true vertical
