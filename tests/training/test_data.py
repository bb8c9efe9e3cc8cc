"""The data contracts of the ground floor: view files (fenestra.rendered_view), masks, RLE and boxes
(fenestra.masks), the COCO ground-truth builder and scoring (fenestra.coco), against pycocotools
and hand-computed values."""
from __future__ import annotations

import json

import numpy as np
import pytest
from pycocotools import mask as mask_utils

from fenestra.coco import SCORE_NAMES, coco_ground_truth, coco_result, coco_scores, complete_coco, gt_annotation
from fenestra.errors import DatasetError
from fenestra.masks import SparseMask, box_from_coco, box_to_coco, instance_masks, mask_box, rle_area, rle_from_crop, rle_from_mask, rle_to_mask, segmentation_to_rle
from fenestra.rendered_view import check_view, read_view, view_annotations, write_view


def _ref_rle(mask: np.ndarray) -> dict:
    """pycocotools' own encoding of a full mask, with str counts."""
    r = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
    return {"size": [int(v) for v in r["size"]], "counts": r["counts"].decode("ascii")}


def _rect(shape, r0, r1, c0, c1) -> np.ndarray:
    """Bool mask of rows r0..r1 and columns c0..c1 (inclusive)."""
    m = np.zeros(shape, bool)
    m[r0:r1 + 1, c0:c1 + 1] = True
    return m


# ---------------------------------------------------------------- RLE

def test_rle_equals_pycocotools_on_random_masks_and_crops():
    """Random blobby masks with holes, empty and full ones, masks touching the first and last
    index: the one encoder gives pycocotools' string, from the full mask and from any crop of it
    that holds all its pixels (at its origin); decoding gives the mask back."""
    rng = np.random.default_rng(7)
    H, W = 37, 53
    masks = [np.zeros((H, W), bool), np.ones((H, W), bool)]
    for _ in range(30):
        m = np.zeros((H, W), bool)
        for _ in range(rng.integers(1, 4)):
            r0, c0 = rng.integers(0, H), rng.integers(0, W)
            m[r0:r0 + rng.integers(1, 20), c0:c0 + rng.integers(1, 30)] = True
        m &= rng.random((H, W)) > 0.15  # holes: many short runs
        masks.append(m)
    edge = np.zeros((H, W), bool)
    edge[0, 0] = True  # the first index: the RLE starts with a run of 0 background pixels
    edge[:, W - 1] = True  # the last column, down to the last index: no trailing background run
    masks.append(edge)
    for m in masks:
        ref = _ref_rle(m)
        assert rle_from_mask(m) == ref
        assert SparseMask.from_dense(m).rle() == ref
        np.testing.assert_array_equal(rle_to_mask(ref), m)
        assert rle_area(ref) == int(m.sum())
        if m.any():
            ys, xs = np.nonzero(m)
            y0, x0 = int(rng.integers(0, ys.min() + 1)), int(rng.integers(0, xs.min() + 1))
            y1, x1 = int(rng.integers(ys.max() + 1, H + 1)), int(rng.integers(xs.max() + 1, W + 1))
            assert rle_from_crop(m[y0:y1, x0:x1], (x0, y0), (H, W)) == ref
            assert SparseMask.from_crop(m[y0:y1, x0:x1], (x0, y0), (H, W)).rle() == ref


def test_rle_of_a_crop_outside_the_image_is_refused():
    with pytest.raises(ValueError, match=r"origin \(50, 0\) does not fit an image of shape \(37, 53\)"):
        rle_from_crop(np.ones((3, 5), bool), (50, 0), (37, 53))
    # an empty crop anywhere is an empty mask
    assert rle_from_crop(np.zeros((3, 5), bool), (50, 0), (37, 53)) == _ref_rle(np.zeros((37, 53), bool))


def test_segmentation_to_rle_polygons_and_uncompressed():
    """Column-major uncompressed RLE on a 5 x 6 image: 7 off, 3 on, 2 off, 3 on -> rows 2-4 of
    columns 1-2; the pixel-edge polygon around the same pixels gives the same mask."""
    m = _rect((5, 6), 2, 4, 1, 2)
    ref = _ref_rle(m)
    assert segmentation_to_rle({"size": [5, 6], "counts": [7, 3, 2, 3, 15]}, 5, 6) == ref
    assert segmentation_to_rle(ref, 5, 6) == ref
    assert segmentation_to_rle({**ref, "counts": ref["counts"].encode()}, 5, 6) == ref
    poly = segmentation_to_rle([[1, 2, 3, 2, 3, 5, 1, 5]], 5, 6)
    np.testing.assert_array_equal(rle_to_mask(poly), m)
    with pytest.raises(ValueError, match="unreadable COCO segmentation"):
        segmentation_to_rle(42, 5, 6)


def test_instance_masks_and_sparse_box():
    inst = np.zeros((20, 30), np.int32)
    inst[2:6, 3:10] = 4
    inst[10:12, 29] = 1
    m4, m1, m9 = instance_masks(inst, [4, 1, 9])
    assert (m4.r0, m4.c0, m4.crop.shape, m4.area) == (2, 3, (4, 7), 28)
    np.testing.assert_array_equal(m4.box(), [2.5, 1.5, 9.5, 5.5])  # pixel-edge outline of columns 3-9, rows 2-5
    np.testing.assert_array_equal(mask_box(inst == 4), m4.box())
    np.testing.assert_array_equal(mask_box(m4.crop, (3, 2)), m4.box())
    np.testing.assert_array_equal(m1.box(), [28.5, 9.5, 29.5, 11.5])
    assert m9.area == 0 and not m9.dense().any()
    with pytest.raises(ValueError, match="ids must be >= 1"):
        instance_masks(inst, [0])
    with pytest.raises(ValueError, match="empty mask"):
        mask_box(np.zeros((3, 3), bool))


def test_box_convention_round_trip():
    """Pixel centres at integers: columns 10..29 span x 9.5..29.5; COCO puts that at x = 10, w = 20."""
    assert box_to_coco([9.5, 4.5, 29.5, 14.5]) == [10.0, 5.0, 20.0, 10.0]
    np.testing.assert_array_equal(box_from_coco([10.0, 5.0, 20.0, 10.0]), [9.5, 4.5, 29.5, 14.5])
    m = _rect((40, 40), 5, 14, 10, 29)
    assert box_to_coco(mask_box(m)) == mask_utils.toBbox(mask_utils.encode(
        np.asfortranarray(m.astype(np.uint8)))).tolist()


# ---------------------------------------------------------------- views

def _meta(H, W, ids, ignore=()):
    return {"K": [[100.0, 0, (W - 1) / 2], [0, 100.0, (H - 1) / 2], [0, 0, 1]], "width": W, "height": H,
            "R": np.eye(3).tolist(), "t": [0.0, 0.0, 5.0], "distortion": None, "renderer": "test", "seed": 0,
            "windows": [{"id": f"w{k}", "instance_id": k, "visible_fraction": 1.0} for k in ids],
            **({"ignore": [{"id": f"g{k}", "instance_id": k, "kind": "curtain_wall"} for k in ignore]}
               if ignore else {})}


def test_view_write_read_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    H, W = 24, 32
    image = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    inst = np.zeros((H, W), np.int32)
    inst[2:8, 3:9], inst[10:20, 20:30] = 1, 300  # ids beyond 8 bits
    ignore = np.zeros((H, W), np.int32)
    ignore[12:22, 2:12] = 2
    d = tmp_path / "views" / "000000"
    write_view(d, image, inst, _meta(H, W, [1, 300], ignore=[2]), ignore=ignore)
    assert check_view(d) is None
    v = read_view(d)
    np.testing.assert_array_equal(v.image, image)
    assert v.image.dtype == np.uint8 and v.instances.dtype == np.int32 and v.ignore.dtype == np.int32
    np.testing.assert_array_equal(v.instances, inst)
    np.testing.assert_array_equal(v.ignore, ignore)
    assert v.K.shape == (3, 3) and [w["instance_id"] for w in v.windows] == [1, 300]
    assert v.ignore_regions == [{"id": "g2", "instance_id": 2, "kind": "curtain_wall"}]
    files = json.loads((d / "view.json").read_text())["files"]
    assert set(files) == {"image.png", "instances.png", "ignore.png"}
    assert files["image.png"] == (d / "image.png").stat().st_size
    assert not list(d.glob(".*tmp*"))  # no temporary file left
    # a view without ignore regions has no ignore.png and reads ignore=None
    write_view(tmp_path / "b", image, inst, _meta(H, W, [1, 300]))
    assert not (tmp_path / "b" / "ignore.png").exists() and read_view(tmp_path / "b").ignore is None


def test_view_damage_and_bad_input_are_named(tmp_path):
    H, W = 8, 10
    image, inst = np.zeros((H, W, 3), np.uint8), np.zeros((H, W), np.int32)
    d = tmp_path / "v"
    write_view(d, image, inst, _meta(H, W, []))
    (d / "instances.png").write_bytes(b"not a png")
    assert "instances.png is 9 bytes" in check_view(d)
    with pytest.raises(DatasetError, match="cannot read instance map"):
        read_view(d)
    (d / "view.json").unlink()
    assert check_view(d) == "no view.json"
    with pytest.raises(DatasetError, match="no view.json"):
        read_view(d)
    (d / "view.json").write_text(json.dumps({"width": W, "height": H}))
    with pytest.raises(DatasetError, match=r"lacks key\(s\) \['K', 'R', 't', 'windows'\]"):
        read_view(d)
    with pytest.raises(ValueError, match=r"ids must be in \[0, 65535\]"):
        write_view(d, image, np.full((H, W), 70000), _meta(H, W, []))
    with pytest.raises(ValueError, match="uint8 RGB"):
        write_view(d, image.astype(np.float32), inst, _meta(H, W, []))
    with pytest.raises(ValueError, match=r"ignore map ids \[3\] are not listed"):
        write_view(d, image, inst, _meta(H, W, []), ignore=np.full((H, W), 3))


# ---------------------------------------------------------------- COCO ground truth

def test_coco_ground_truth_equals_a_hand_built_dict():
    H, W = 10, 12
    a = SparseMask.from_dense(_rect((H, W), 1, 3, 2, 5))  # rows 1-3, columns 2-5
    crowd = _rect((H, W), 6, 9, 0, 11)
    gt = coco_ground_truth(
        [("views/a.png", H, W), ("views/b.png", H, W)],
        [gt_annotation("views/b.png", a.rle(), window_id="W1"),
         gt_annotation("views/b.png", None, [-0.5, -0.5, 3.5, 1.5]),  # box-only label
         gt_annotation("views/a.png", _ref_rle(crowd), ignore=True)],
        first_image_id=0)
    assert gt == {
        "images": [{"id": 0, "file_name": "views/a.png", "height": 10, "width": 12},
                   {"id": 1, "file_name": "views/b.png", "height": 10, "width": 12}],
        "annotations": [
            {"id": 1, "image_id": 1, "category_id": 1, "iscrowd": 0, "bbox": [2.0, 1.0, 4.0, 3.0], "area": 12.0,
             "segmentation": _ref_rle(a.dense()), "window_id": "W1"},
            {"id": 2, "image_id": 1, "category_id": 1, "iscrowd": 0, "bbox": [0.0, 0.0, 4.0, 2.0], "area": 8.0},
            {"id": 3, "image_id": 0, "category_id": 1, "iscrowd": 1, "bbox": [0.0, 6.0, 12.0, 4.0], "area": 48.0,
             "segmentation": _ref_rle(crowd)}],
        "categories": [{"id": 1, "name": "window"}]}
    with pytest.raises(ValueError, match="unknown image 'x'"):
        coco_ground_truth([("a", 1, 1)], [gt_annotation("x", None, [0, 0, 1, 1])])
    with pytest.raises(ValueError, match="neither mask nor box"):
        gt_annotation("a")


def test_view_annotations_windows_then_ignore_regions(tmp_path):
    H, W = 20, 30
    inst, ignore = np.zeros((H, W), np.int32), np.zeros((H, W), np.int32)
    inst[2:6, 3:10] = 1  # window 2 is not in view: no annotation
    ignore[10:18, 0:30] = 5
    write_view(tmp_path, np.zeros((H, W, 3), np.uint8), inst, _meta(H, W, [1, 2], ignore=[5]), ignore)
    anns = view_annotations(read_view(tmp_path), "k")
    assert [(a["iscrowd"], a["bbox"], a["area"]) for a in anns] == [(0, [3.0, 2.0, 7.0, 4.0], 28.0),
                                                                     (1, [0.0, 10.0, 30.0, 8.0], 240.0)]
    assert anns[0]["window_id"] == "w1" and anns[1]["ignore_id"] == "g5" and anns[1]["kind"] == "curtain_wall"


# ---------------------------------------------------------------- scoring

def _ignore_case(ignore: bool, box_only_ignore: bool = False):
    """2 windows (A, B) + 1 ignore region R on a 100 x 100 image; detections: d1 (0.9) inside R,
    d2 (0.8) on nothing, d3 (0.7) exactly on A. B is missed."""
    S = (100, 100)
    A, B, R = _rect(S, 10, 29, 10, 29), _rect(S, 10, 29, 50, 69), _rect(S, 60, 89, 10, 89)
    anns = [gt_annotation("im", _ref_rle(A)), gt_annotation("im", _ref_rle(B))]
    if ignore:
        anns.append(gt_annotation("im", None if box_only_ignore else _ref_rle(R), mask_box(R),
                                       ignore=True))
    gt = coco_ground_truth([("im", *S)], anns)
    dets = [(0.9, _rect(S, 65, 84, 20, 39)), (0.8, _rect(S, 40, 49, 80, 95)), (0.7, A)]
    return gt, [coco_result("im", s, mask_box(m), _ref_rle(m)) for s, m in dets]


@pytest.mark.parametrize("iou_type", ["bbox", "segm"])
def test_ignore_region_hand_computed_ap(iou_type):
    """With R an ignore region, d1 counts neither way: ranked d2 (FP), d3 (TP): precision 1/2 at
    recall 1/2, so COCO's 101-point AP = 0.5 * 51 / 101 at every IoU threshold (d3 is exact).
    Without R, d1 is a false positive too: precision 1/3 at recall 1/2: AP = (1/3) * 51 / 101.
    Recall is 1/2 either way (B is missed); AR1 looks at d1 only: 0. All windows are small
    (< 32^2 px): no medium or large ones, NaN."""
    for box_only in (False, True):
        gt, res = _ignore_case(True, box_only)
        s = coco_scores(gt, res, (iou_type,))
        assert set(s) == {f"{iou_type}_{k}" for k in SCORE_NAMES}
        for k in ("AP", "AP50", "AP75", "AP_small"):
            assert s[f"{iou_type}_{k}"] == pytest.approx(0.5 * 51 / 101, abs=1e-12), (k, box_only)
        assert s[f"{iou_type}_AR100"] == pytest.approx(0.5) and s[f"{iou_type}_R50"] == pytest.approx(0.5)
        assert s[f"{iou_type}_AR1"] == 0.0
        assert np.isnan(s[f"{iou_type}_AP_medium"]) and np.isnan(s[f"{iou_type}_AR_large"])
    gt, res = _ignore_case(False)
    s = coco_scores(gt, res, (iou_type,))
    assert s[f"{iou_type}_AP"] == pytest.approx(51 / 101 / 3, abs=1e-12)


def test_scores_without_windows_detections_or_masks():
    gt, res = _ignore_case(True)
    assert all(v == 0.0 for v in coco_scores(gt, []).values())
    only_ignore = {**gt, "annotations": [a for a in gt["annotations"] if a["iscrowd"]]}
    assert all(np.isnan(v) for v in coco_scores(only_ignore, res).values())
    boxes = {**gt, "annotations": [{k: v for k, v in a.items() if k != "segmentation" or a["iscrowd"]}
                                   for a in gt["annotations"]]}
    s = coco_scores(boxes, res)  # box-only windows: mask AP absent, box AP as before
    assert np.isnan(s["segm_AP"]) and s["bbox_AP"] == pytest.approx(0.5 * 51 / 101, abs=1e-12)
    with pytest.raises(ValueError, match="unknown image 'nope'"):
        coco_scores(gt, [coco_result("nope", 1.0, [0, 0, 1, 1])])
    with pytest.raises(ValueError, match="iou_types"):
        coco_scores(gt, res, ("keypoints",))


def test_complete_coco_fills_a_foreign_file():
    """Uncompressed RLE, no area, bbox, id or iscrowd: completed from the mask."""
    m = _rect((5, 6), 2, 4, 1, 2)
    coco = {"images": [{"id": 7, "height": 5, "width": 6}],
            "annotations": [{"image_id": 7, "category_id": 1, "segmentation": {"size": [5, 6], "counts": [7, 3, 2, 3, 15]}}]}
    (a,) = complete_coco(coco)["annotations"]
    assert a == {"id": 1, "iscrowd": 0, "image_id": 7, "category_id": 1, "segmentation": _ref_rle(m),
                 "area": 6.0, "bbox": [1.0, 2.0, 2.0, 3.0]}
