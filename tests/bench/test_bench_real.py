"""The real-photo bench: adapters (fenestra/bench/real) on small hand-made files, metrics against
hand-computed numbers, one row per labelled window per method through the one evaluation path
(bench.evaluate, bench.runner), the profile and the CLI."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from fenestra.bench import metrics as rm
from fenestra.bench.detection_ap import coco_ap_of
from fenestra.bench.evaluate import EvalOptions, ViewOutcome, evaluate_view, gt_coco
from fenestra.bench.evaluators import window_errors
from fenestra.methods import Method
from fenestra.bench.real.adapters import ADAPTERS, CURTAIN_K, read_coco
from fenestra.bench.real.profile import ProfileError, load_real_profile, real_profile_from_dict
from fenestra.bench.real.simreal import ranking
from fenestra.bench.runner import run_benchmark
from fenestra.bench.views import LabelledWindow
from fenestra.coco import coco_result
from fenestra.pipeline.types import WindowResult

ROOT = Path(__file__).resolve().parents[2]


def _write_rgb(path: Path, rgb: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.ascontiguousarray(rgb[..., ::-1]))


def _photo(h: int = 100, w: int = 100, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(60, 200, (h, w, 3), dtype=np.uint8)


# ---------------------------------------------------------------- adapters

@pytest.fixture
def yolo_dir(tmp_path) -> Path:
    ds = tmp_path / "yolo"  # its own folder: a run's --out beside it, never inside an input
    _write_rgb(ds / "images" / "a.png", _photo())
    (ds / "labels").mkdir()
    # window (class 0) at x 15..35, y 15..35 px; window 60..80 x 50..70; a door (class 5) ignored
    (ds / "labels" / "a.txt").write_text("0 0.25 0.25 0.2 0.2\n0 0.7 0.6 0.2 0.2\n5 0.5 0.9 0.1 0.1\n")
    return ds


def test_yolo_boxes_in_pixel_centre_convention(yolo_dir):
    (v,) = list(ADAPTERS["yolo"](yolo_dir))
    assert v.K is None and not v.has_masks and len(v.windows) == 2
    np.testing.assert_allclose(v.windows[0].box, [14.5, 14.5, 34.5, 34.5])
    np.testing.assert_allclose(v.windows[1].box, [59.5, 49.5, 79.5, 69.5])
    assert all(w.quad is None and w.mask is None and w.aspect is None for w in v.windows)
    # back to COCO's pixel-edge x, y, w, h
    assert gt_coco(v)[0]["bbox"] == [15.0, 15.0, 20.0, 20.0]
    assert len(list(ADAPTERS["yolo"](yolo_dir, classes=[0, 5]))[0].windows) == 3


def test_yolo_bad_line_names_file_and_line(yolo_dir):
    (yolo_dir / "labels" / "a.txt").write_text("0 0.25 0.25 0.2 0.2\n0 0.5 oops\n")
    with pytest.raises(ValueError, match=r"a\.txt:2: bad YOLO line"):
        list(ADAPTERS["yolo"](yolo_dir))


def test_box_ap_hand_computed(yolo_dir):
    """GT boxes A, B; detections: A exactly (0.9), a false positive (0.8), B at IoU 0.625 (0.7).
    IoU thresholds 0.5-0.6: precision 1 up to recall 0.5, then 2/3 up to 1: AP = (51 + 50 * 2/3) / 101;
    thresholds 0.65-0.95: only A: AP = 51 / 101. Mean over the 10 thresholds."""
    (v,) = list(ADAPTERS["yolo"](yolo_dir))
    key = v.key
    dt = [coco_result(key, 0.9, [14.5, 14.5, 34.5, 34.5]), coco_result(key, 0.8, [79.5, -0.5, 89.5, 9.5]),
          coco_result(key, 0.7, [59.5, 49.5, 79.5, 62.0])]
    assert [d["bbox"] for d in dt] == [[15.0, 15.0, 20.0, 20.0], [80.0, 0.0, 10.0, 10.0], [60.0, 50.0, 20.0, 12.5]]
    out = ViewOutcome(rows=[], stage_s={}, coco_gt=gt_coco(v), coco_dt={"d": dt}, dataset=v.dataset, view=v.name,
                      size=(100, 100))
    s = coco_ap_of([out], "d")
    ap_low, ap_high = (51 + 50 * 2 / 3) / 101, 51 / 101
    assert s["bbox_AP50"] == pytest.approx(ap_low, abs=1e-9)
    assert s["bbox_AP"] == pytest.approx((3 * ap_low + 7 * ap_high) / 10, abs=1e-9)
    assert s["bbox_R50"] == pytest.approx(1.0)
    assert np.isnan(s["segm_AP"])  # boxes only: mask AP is absent, not zero
    assert s["n_gt"] == 2 and s["n_detections"] == 3


def test_coco_crowd_region_is_ignored_in_box_ap(tmp_path):
    """COCO windows A (x 10..30, y 10..30), B (50..70, 10..30) and an iscrowd region R (10..90,
    60..90): R becomes an ignore region, not a window. Detections: inside R (0.9), on nothing
    (0.8), exactly A (0.7). R's detection counts neither way: precision 1/2 at recall 1/2, AP =
    0.5 * 51 / 101 at every IoU; were R absent, that detection would be a false positive: (1/3) * 51 / 101."""
    _write_rgb(tmp_path / "p.png", _photo())
    doc = {"images": [{"id": 1, "file_name": "p.png", "width": 100, "height": 100}],
           "categories": [{"id": 1, "name": "window"}],
           "annotations": [{"id": 1, "image_id": 1, "category_id": 1, "bbox": [10, 10, 20, 20]},
                           {"id": 2, "image_id": 1, "category_id": 1, "bbox": [50, 10, 20, 20]},
                           {"id": 3, "image_id": 1, "category_id": 1, "bbox": [10, 60, 80, 30], "iscrowd": 1}]}
    (tmp_path / "annotations.json").write_text(json.dumps(doc))
    (v,) = list(read_coco(tmp_path))
    assert [w.id for w in v.windows] == ["1", "2"] and [w.id for w in v.ignore] == ["3"]
    key = v.key
    dt = [coco_result(key, 0.9, [19.5, 64.5, 39.5, 84.5]), coco_result(key, 0.8, [79.5, 39.5, 95.5, 49.5]),
          coco_result(key, 0.7, [9.5, 9.5, 29.5, 29.5])]
    out = ViewOutcome(rows=[], stage_s={}, coco_gt=gt_coco(v), coco_dt={"d": dt}, dataset=v.dataset, view=v.name,
                      size=(100, 100))
    s = coco_ap_of([out], "d")
    assert s["bbox_AP"] == pytest.approx(0.5 * 51 / 101, abs=1e-12) and s["bbox_R50"] == pytest.approx(0.5)
    assert s["n_gt"] == 2 and np.isnan(s["segm_AP"])
    no_ignore = ViewOutcome(rows=[], stage_s={}, coco_gt=gt_coco(v)[:2], coco_dt={"d": dt}, dataset=v.dataset,
                            view=v.name, size=(100, 100))
    assert coco_ap_of([no_ignore], "d")["bbox_AP"] == pytest.approx(
        51 / 101 / 3, abs=1e-12)


def test_box_iou_matrix_hand_computed():
    iou = rm.box_iou_matrix([np.array([0, 0, 10, 10.0]), np.array([5, 0, 15, 10.0])],
                            [np.array([0, 0, 10, 10.0]), np.array([20, 20, 30, 30.0])])
    np.testing.assert_allclose(iou, [[1.0, 0.0], [50 / 150, 0.0]])


def test_labelmap_colour_and_id(tmp_path):
    lab = np.zeros((20, 30, 3), np.uint8)
    lab[2:6, 3:9] = (255, 0, 0)  # 4 x 6 = 24 px
    lab[10:20, 20:25] = (255, 0, 0)  # touches the bottom border: partial
    lab[2:6, 20:25] = (0, 0, 255)  # another class
    _write_rgb(tmp_path / "labels" / "f.png", lab)
    _write_rgb(tmp_path / "images" / "f.jpg", _photo(20, 30))
    (v,) = list(ADAPTERS["labelmap"](tmp_path, window=[255, 0, 0]))
    assert [w.mask.area for w in v.windows] == [24, 50]
    assert [w.partial for w in v.windows] == [False, True]
    np.testing.assert_allclose(v.windows[0].bbox(), [2.5, 1.5, 8.5, 5.5])
    ids = np.zeros((20, 30), np.uint8)
    ids[2:6, 3:9] = 7
    cv2.imwrite(str(tmp_path / "labels" / "f.png"), ids)
    (v,) = list(ADAPTERS["labelmap"](tmp_path, window=7))
    assert len(v.windows) == 1 and v.windows[0].mask.area == 24
    with pytest.raises(ValueError, match="colour"):
        list(ADAPTERS["labelmap"](tmp_path, window=[255, 0, 0]))


def _rectangle_view(tmp_path: Path) -> tuple[Path, np.ndarray, float, np.ndarray]:
    """A COCO folder: one 320x240 photo of a 0.8 x 1.2 m rectangle seen at an angle (K known),
    annotated with its 4-vertex polygon (pixel edges) and its aspect 2/3. Returns the folder, the
    quad (fenestra convention), the aspect and K."""
    K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
    a = np.radians(30)
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    X = np.array([[-0.4, -0.6, 0], [0.4, -0.6, 0], [0.4, 0.6, 0], [-0.4, 0.6, 0]])  # TL TR BR BL (y down)
    x = (X @ R.T + [0, 0, 3.0]) @ K.T
    quad = x[:, :2] / x[:, 2:]
    img = np.full((240, 320, 3), 90, np.uint8)
    mask = np.zeros((240, 320), np.uint8)
    cv2.fillPoly(mask, [np.round(quad * 256).astype(np.int32)], 1, shift=8)
    img[mask > 0] = (200, 210, 220)
    _write_rgb(tmp_path / "images" / "r.png", img)
    poly = (quad + 0.5).reshape(-1).tolist()
    doc = {"images": [{"id": 1, "file_name": "r.png", "width": 320, "height": 240, "K": K.tolist()}],
           "categories": [{"id": 1, "name": "window"}, {"id": 2, "name": "door"}],
           "annotations": [{"id": 5, "image_id": 1, "category_id": 1, "iscrowd": 0, "segmentation": [poly],
                            "bbox": [float(quad[:, 0].min() + 0.5), float(quad[:, 1].min() + 0.5),
                                     float(np.ptp(quad[:, 0])), float(np.ptp(quad[:, 1]))], "aspect": 0.8 / 1.2},
                           {"id": 6, "image_id": 1, "category_id": 2, "iscrowd": 0, "bbox": [1, 1, 5, 5]}]}
    (tmp_path / "annotations.json").write_text(json.dumps(doc))
    return tmp_path, quad, 0.8 / 1.2, K


def test_coco_polygon_gives_quad_mask_box_aspect_K(tmp_path):
    folder, quad, aspect, K = _rectangle_view(tmp_path)
    (v,) = list(read_coco(folder))
    (w,) = v.windows  # the door is another category
    np.testing.assert_allclose(w.quad, quad, atol=1e-9)
    assert w.mask is not None and w.aspect == pytest.approx(aspect)
    np.testing.assert_allclose(v.K, K)
    with pytest.raises(ValueError, match="no category matches 'tree'"):
        list(read_coco(folder, category="tree"))


def test_window_errors_hand_computed():
    """A result whose quads sit 3, 4 px off the labelled quad and whose aspect is 0.7 against a
    true 2/3: corner error 5 px, aspect error 0.05; reprojection consistency 5 px between them."""
    q = np.array([[10.0, 10], [50, 10], [50, 70], [10, 70]])
    w = LabelledWindow(id="w", quad=q, aspect=2 / 3)
    res = WindowResult(index=0, score=1.0, quad_mask=q + [3, 4], quad_snapped=q + [3, 4], aspect_ratio=0.7,
                       aspect_case="general", focal_estimate_px=None, R=np.eye(3), t=np.array([0, 0, 2.0]),
                       height_m=1.0, quad_reprojected=q + [6, 8], failure=None)
    K = np.array([[300.0, 0, 30], [0, 300.0, 40], [0, 0, 1]])
    e = window_errors(res, w, None, K)
    assert e["corner_err_px_snap"] == pytest.approx(5.0) and e["corner_err_px_reproj"] == pytest.approx(10.0)
    assert e["aspect_err_rel"] == pytest.approx(0.05)
    assert e["reproj_consistency_px"] == pytest.approx(5.0)
    assert np.isnan(e["rot_err_deg"]) and np.isnan(e["trans_err_m"])  # no true pose: absent
    assert np.isnan(window_errors(res, w, None, None)["reproj_consistency_px"])  # 0 by construction
    e = window_errors(res, LabelledWindow(id="w", box=np.array([0, 0, 5, 5.0])), None, K)
    assert np.isnan(e["corner_err_px_snap"]) and np.isnan(e["aspect_err_rel"])  # no quad, no aspect


def test_relative_size_hand_computed():
    # equal panes, plane distances 2 and 4 (units of the pose's height): estimated relative sizes
    # (1/2, 1/4) / median 3/8 = 4/3, 2/3 against truth 1, 1
    np.testing.assert_allclose(rm.relative_size_errors(np.array([2.0, 4.0]), np.array([0.1, 0.1])), [1 / 3, 1 / 3])
    np.testing.assert_allclose(rm.relative_size_errors(np.array([2.0, 4.0]), np.array([0.2, 0.1])), [0, 0], atol=1e-12)
    assert np.isnan(rm.relative_size_errors(np.array([2.0]), np.array([0.1]))).all()
    assert rm.plane_distance(np.eye(3), np.array([1.0, 2.0, -3.0])) == 3.0


def test_rectangle_end_to_end_with_oracle_masks(tmp_path):
    folder, quad, aspect, K = _rectangle_view(tmp_path)
    (v,) = list(read_coco(folder))
    methods = (Method("oracle", "none", "lm"),)
    out = evaluate_view(v, methods, EvalOptions(detector_long_side=640))
    (row,) = out.rows
    assert row["status"] == "ok", row["reason"]
    assert row["corner_err_px_mask"] < 0.5  # the mask was drawn from the labelled quad
    assert row["aspect_err_rel"] < 0.01
    assert np.isnan(row["rel_size_err"])  # one window, not a coplanar set of known sizes


def test_curtainwall_adapter_small_hand_made(tmp_path):
    """A 1/16-size photo: K scaled with the pixel-centre rule, one whole pane, one cut pane."""
    _write_rgb(tmp_path / "images" / "img001.png", _photo(128, 96))
    rgba = np.zeros((128, 96, 4), np.uint8)
    rgba[20:50, 10:30] = (255, 0, 0, 255)  # BGRA glass, 600 px, whole
    rgba[60:128, 50:70] = (255, 0, 0, 255)  # cut by the bottom border
    rgba[5:8, 80:83] = (255, 0, 0, 255)  # 9 px: below the pane size threshold
    (tmp_path / "masks").mkdir()
    cv2.imwrite(str(tmp_path / "masks" / "mask001.png"), rgba)
    (v,) = list(ADAPTERS["curtainwall"](tmp_path))
    s = 96 / 1536
    np.testing.assert_allclose(v.K[0], [CURTAIN_K[0][0] * s, 0, (CURTAIN_K[0][2] + 0.5) * s - 0.5])
    assert v.coplanar and v.distortion_removed is not None
    assert [w.mask.area for w in v.windows] == [600, 68 * 20]
    assert v.windows[0].aspect == pytest.approx(93.2 / 143.2) and not v.windows[0].partial
    assert v.windows[1].partial and v.windows[1].aspect is None


# ---------------------------------------------------------------- rows, profile, CLI

def test_every_labelled_window_one_row_per_method(tmp_path, yolo_dir):
    """Bundled curtain-wall photos + a box-only set: rows = windows x methods, each pair once;
    oracles cannot run on boxes and say so; non-ok rows carry a reason."""
    prof = real_profile_from_dict({
        "name": "t", "kind": "real", "methods": {"detectors": ["oracle"], "snappers": ["none", "harris"],
                                                 "pose_solvers": ["lm"]},
        "datasets": [{"name": "cw", "format": "curtainwall", "path": str(ROOT / "data/real/curtainwall")},
                     {"name": "boxes", "format": "yolo", "path": str(yolo_dir)},
                     {"name": "absent", "format": "coco", "path": str(tmp_path / "nope"), "optional": True}]})
    info = run_benchmark(prof, out_dir=tmp_path / "run", progress=False, report=False)
    import pandas as pd

    df = pd.read_parquet(info.run_dir / "results.parquet")
    meta = json.loads((info.run_dir / "summary.json").read_text())["metadata"]
    n_windows = meta["n_windows"]
    assert n_windows == {"cw": 45, "boxes": 2}  # 45 glass components >= 20 000 px in the 5 photos
    assert len(df) == sum(n_windows.values()) * 2
    assert not df.duplicated(["dataset", "view", "window_id", "method"]).any()
    assert (df.loc[df["status"] != "ok", "reason"].str.len() > 0).all()
    box_rows = df[df["dataset"] == "boxes"]
    assert (box_rows["reason"].str.startswith("not run: oracle needs ground-truth masks")).all()
    assert "absent" in meta["skipped_datasets"]
    s = json.loads((info.run_dir / "summary.json").read_text())["results"]
    assert s["oracle/none/lm"]["aspect_err_rel"]["n_valid"] == 14
    assert s["oracle/none/lm"]["corner_err_px_snap"]["n"] == 0  # no labelled quads: absent, not 0
    assert s["oracle/none/lm"]["corner_err_px_snap"]["recall"]["2"] is None
    # export precision: counted on the 5 photos the oracle ran on (not the box-only set); the
    # oracle's masks are the labelled windows', so every window it exports is one
    e = s["oracle/none/lm"]["export"]
    assert e["n_views"] == 5 and e["n_exported"] > 0 and e["n_matched"] == e["n_exported"] and e["precision"] == 1.0
    assert e["n_on_ignore"] == e["n_on_nothing"] == 0


def test_real_profile_loads_and_resolves_paths():
    p = load_real_profile("real")
    datasets = p.source.datasets
    assert datasets[0].folder() == ROOT / "data" / "real" / "curtainwall"
    assert datasets[1].folder() == (ROOT.parent / "shared" / "real" / "spb_facades")
    assert datasets[1].optional
    q = real_profile_from_dict({"name": "u", "kind": "real", "data": "/x/y", "format": "yolo"})
    assert q.source.datasets[0].format == "yolo" and q.source.datasets[0].name == "y"
    with pytest.raises(ProfileError, match="format 'voc' unknown"):
        real_profile_from_dict({"name": "u", "kind": "real", "data": "/x", "format": "voc"})
    q = real_profile_from_dict({"name": "u", "kind": "real", "data": "/x/y",
                                "detector_options": {"default": {"weights": "w.pt"}}})
    assert q.source.detector_options == (("default", (("weights", "w.pt"),)),) and q.source.datasets[0].format == "coco"
    with pytest.raises(ProfileError, match="no datasets"):
        real_profile_from_dict({"name": "u", "kind": "real"})


def test_simreal_ranking_hand_computed():
    import pandas as pd

    sim = pd.Series({"d/a/lm": 1.0, "d/b/lm": 2.0, "d/c/lm": 3.0})
    real = pd.Series({"d/a/lm": 0.1, "d/b/lm": 0.3, "d/c/lm": 0.2})
    r = ranking(sim, real)
    assert r["spearman"] == pytest.approx(0.5) and r["kendall"] == pytest.approx(1 / 3)
    assert r["best_sim"] == r["best_real"] == "d/a/lm" and r["regret"] == 0.0
    r = ranking(sim, pd.Series({"d/a/lm": 0.3, "d/b/lm": 0.2, "d/c/lm": 0.1}))
    assert r["spearman"] == pytest.approx(-1.0) and r["best_real"] == "d/c/lm"
    assert r["best_sim_real_rank"] == 3 and r["regret"] == pytest.approx(0.2) and r["regret_rel"] == pytest.approx(2.0)


def test_simreal_section_in_the_report(tmp_path):
    """A synthetic run identical to the real one: renders choose what photos choose ("yes"), and
    the report carries the real metrics and the sim-to-real sections."""
    import shutil

    from fenestra.bench.real.simreal import write_simreal
    from fenestra.reports.build import build_report

    folder, *_ = _rectangle_view(tmp_path / "data")
    prof = real_profile_from_dict({"name": "t", "kind": "real", "data": str(folder),
                                   "methods": {"detectors": ["oracle"], "snappers": ["none", "harris"],
                                               "pose_solvers": ["lm"]}})
    info = run_benchmark(prof, out_dir=tmp_path / "real", progress=False, report=False)
    summary = json.loads((info.run_dir / "summary.json").read_text())  # a user's COCO folder: exact aspect
    assert summary["results"]["oracle/none/lm"]["aspect_err_rel"]["median"] < 0.01
    shutil.copytree(info.run_dir, tmp_path / "sim")
    doc = json.loads(write_simreal(tmp_path / "sim", info.run_dir).read_text())
    (r,) = [x for x in doc["rankings"] if x["metric"] == "aspect_err_rel"]
    assert r["best_sim"] == r["best_real"] and r["regret"] == 0.0 and r["n_windows_real"] == 1
    assert doc["answer"][0].startswith("oracle masks, aspect_err_rel") and ": yes: renders choose" in doc["answer"][0]
    assert doc["gap"]["oracle"]["aspect_err_rel"] == pytest.approx(1.0)
    md = build_report(info.run_dir)[1].read_text()
    assert "## Real photos: what the labels allow" in md and "## Sim-to-real: do render rankings hold on photos?" in md
    assert "| oracle | 1.00 | 1.00 | 1.00 | 1.00 | 1.00 | 1.00 | 1 |" in md  # exact masks: AP = recall = 1


def test_coco_rle_masks_uncompressed_and_compressed(tmp_path):
    """Column-major RLE on a 5 x 6 image: 7 off, 3 on, 2 off, 3 on -> rows 2-4 of columns 1-2."""
    from pycocotools import mask as mask_utils

    _write_rgb(tmp_path / "p.png", _photo(5, 6))
    rle = {"size": [5, 6], "counts": [7, 3, 2, 3, 15]}
    m = np.zeros((5, 6), np.uint8)
    m[2:5, 1:3] = 1
    packed = mask_utils.encode(np.asfortranarray(m))
    doc = {"images": [{"id": 1, "file_name": "p.png", "width": 6, "height": 5}],
           "categories": [{"id": 3, "name": "window"}],
           "annotations": [{"id": 1, "image_id": 1, "category_id": 3, "segmentation": rle},
                           {"id": 2, "image_id": 1, "category_id": 3,
                            "segmentation": {"size": [5, 6], "counts": packed["counts"].decode("ascii")}}]}
    (tmp_path / "annotations.json").write_text(json.dumps(doc))
    (v,) = list(read_coco(tmp_path))
    for w in v.windows:
        np.testing.assert_array_equal(w.mask.dense(), m.astype(bool))
        np.testing.assert_allclose(w.bbox(), [0.5, 1.5, 2.5, 4.5])
        assert w.quad is None and w.box is None and w.aspect is None


def test_photo_rows_equal_those_of_the_former_real_evaluator(tmp_path, yolo_dir):
    """The one evaluation path gives photos the rows fenestra/bench/real's own evaluator of commit 991c33e
    gave (tests/golden/photo_view_rows.json, written by that code): a labelled quad with aspect and
    K, box-only labels (oracles not run), and a coplanar curtain-wall photo (relative sizes, partial
    panes); every column in the photo table's order, every value, and the COCO material's sizes.
    The session added the BIM columns (bench.evaluate.BIM_COLUMNS); the former ones are unchanged
    but a per-window method's ``wall_id`` would be (a photo table has none)."""
    from fenestra.bench.evaluate import BIM_COLUMNS, PHOTO_COLUMNS

    golden = json.loads((ROOT / "tests" / "golden" / "photo_view_rows.json").read_text())
    methods = tuple(Method.from_label(m) for m in golden["methods"])
    folder, *_ = _rectangle_view(tmp_path / "rect")
    views = [next(iter(read_coco(folder))), next(iter(ADAPTERS["yolo"](yolo_dir))),
             next(iter(ADAPTERS["curtainwall"](ROOT / "data" / "real" / "curtainwall")))]
    for v in views:
        g = golden["views"][v.dataset]
        out = evaluate_view(v, methods, EvalOptions(detector_long_side=640))
        assert len(out.rows) == len(g["rows"]) > 0, v.dataset
        assert out.n_false_positives == g["n_false_positives"] and len(out.coco_gt) == g["n_coco_gt"]
        assert {k: len(x) for k, x in out.coco_dt.items()} == g["n_coco_dt"]
        for r, e in zip(out.rows, g["rows"]):
            assert list(r) == list(PHOTO_COLUMNS) and set(r) == set(e) | set(BIM_COLUMNS)
            bad = {k: (r[k], e[k]) for k in e
                   if not (r[k] == e[k] or (e[k] is None and isinstance(r[k], float) and np.isnan(r[k]))
                           or (isinstance(r[k], float) and isinstance(e[k], float)
                               and r[k] == pytest.approx(e[k], rel=1e-9, abs=1e-12)))}
            assert not bad, (v.dataset, r["method"], r["window_id"], bad)
    assert sum(e["rel_size_err"] is not None for e in golden["views"]["curtainwall"]["rows"]) > 0


def test_photos_differing_by_case_or_extension_are_an_error_at_load(yolo_dir):
    """a.png with a.jpg (or A.PNG) would be two views named 'a' scored against one label file:
    refused when the dataset is read, naming both photos; one of them alone reads."""
    from fenestra.errors import DatasetError

    for other in ("a.jpg", "A.PNG"):
        _write_rgb(yolo_dir / "images" / other, _photo(seed=1))
        with pytest.raises(DatasetError, match=rf"photos '{other}' and 'a.png' differ only by case or extension"):
            list(ADAPTERS["yolo"](yolo_dir))
        (yolo_dir / "images" / other).unlink()
    assert [v.name for v in ADAPTERS["yolo"](yolo_dir)] == ["a"]


def test_coco_annotation_of_an_unknown_category_is_an_error_at_load(tmp_path):
    """A window annotated with a category the file does not list is an error naming it, not a
    window silently left out (which would make it background); with categories listed and known
    ids, windows of other categories are still left out by choice (category option)."""
    from fenestra.errors import DatasetError

    _write_rgb(tmp_path / "p.png", _photo())
    doc = {"images": [{"id": 1, "file_name": "p.png", "width": 100, "height": 100}],
           "categories": [{"id": 1, "name": "window"}, {"id": 2, "name": "door"}],
           "annotations": [{"id": 1, "image_id": 1, "category_id": 1, "bbox": [10, 10, 20, 20]},
                           {"id": 2, "image_id": 1, "category_id": 2, "bbox": [50, 10, 20, 20]},
                           {"id": 3, "image_id": 1, "category_id": 3, "bbox": [10, 60, 20, 20]}]}
    (tmp_path / "annotations.json").write_text(json.dumps(doc))
    with pytest.raises(DatasetError, match=r"annotations\[2\] \(id 3\): category_id 3 matches no category"):
        list(read_coco(tmp_path))
    doc["annotations"].pop()
    (tmp_path / "annotations.json").write_text(json.dumps(doc))
    (v,) = list(read_coco(tmp_path))
    assert [w.id for w in v.windows] == ["1"]


def test_real_val_profile_never_reads_the_test_photos():
    """real-val, the profile changes are chosen on, reads the validation part of the train folder
    (every 5th photo, kfree only) and the bundled curtain wall, never the 10 test photos."""
    p = load_real_profile("real-val")
    assert {d.name for d in p.source.datasets} == {"curtainwall", "spb_val"}
    val = next(d for d in p.source.datasets if d.name == "spb_val")
    assert val.folder() == ROOT.parent / "shared" / "real" / "spb_facades" / "train"
    assert p.source.kfree.datasets == p.source.kfree.transform_datasets == ("spb_val",) and p.source.kfree.max_photos == 30


def test_every_bundled_profile_is_one_profile_type_keyed_as_its_toml():
    """bench.profiles.load_profile reads both kinds into one Profile: a rendering one's source is
    Renders (scenes, render, evaluation), a real one's Datasets; its to_dict (what the config hash
    hashes) has exactly the TOML file's top-level keys, less kind, so the hash names what the file says."""
    import tomllib

    from fenestra.bench.profiles import PROFILE_DIR, Profile, Renders, available_profiles, load_profile
    from fenestra.bench.real.profile import Datasets

    for name in available_profiles():
        p = load_profile(name)
        toml = tomllib.loads((PROFILE_DIR / f"{name}.toml").read_text())
        real = toml.get("kind") == "real"
        assert type(p) is Profile and isinstance(p.source, Datasets if real else Renders) and p.photos is real, name
        keys = set(toml) - {"kind", "data", "format", "options"} | ({"datasets"} if real else set())
        assert keys <= set(p.to_dict()), (name, keys - set(p.to_dict()))
        assert set(p.to_dict()) - keys <= {"description", "seed", "methods", "scenes", "render", "evaluation",
                                           "detector_long_side", "min_window_px", "detector_options", "kfree"}, name
    assert load_profile("real") == load_real_profile("real")
