"""The K-free single-photo path in the real bench (bench.photo_eval, issue 24 item 7): the
transforms are exact, export precision and focal spread against hand-built truth, the profile's
[kfree] table, and `bench --profile real` on a one-photo dataset reaching summary.json's "kfree"
block, the report and the generated docs."""
from __future__ import annotations

import io
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from PIL import Image

from fenestra.bench import photo_eval as pe
from fenestra.bench.real.profile import ProfileError, load_real_profile, real_profile_from_dict
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra.images import read_image


def _image(h: int = 60, w: int = 100, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)


def _decode(enc: pe.Encoded, tmp_path: Path, name: str = "x") -> np.ndarray:
    p = tmp_path / f"{name}{enc.suffix}"
    p.write_bytes(enc.data)
    return read_image(p)


# ---------------------------------------------------------------- transforms

def test_mirror_twice_is_identity_and_mirrors_columns():
    im = _image()
    m = pe.mirror_image(im)
    assert np.array_equal(m[:, 0], im[:, -1]) and np.array_equal(m[7, 30], im[7, 100 - 1 - 30])
    assert np.array_equal(pe.mirror_image(m), im)


def test_crop_removes_ten_percent_centred():
    im = _image(60, 100)
    c = pe.crop_image(im)
    assert c.shape == (54, 90, 3)  # 5 % of 100 = 5 columns and 5 % of 60 = 3 rows off each side
    assert np.array_equal(c, im[3:57, 5:95])
    with pytest.raises(ValueError, match="0.5"):
        pe.crop_image(im, 0.5)


def test_exif_rotated_file_reads_back_as_the_original(tmp_path):
    im = _image(60, 100)
    enc = pe.exif_rotated(im)
    with Image.open(io.BytesIO(enc.data)) as f:
        assert f.getexif().get(0x0112) == 6
        assert f.size == (60, 100)  # stored turned: W and H swapped
    assert np.array_equal(_decode(enc, tmp_path), im)  # the one reader applies the tag: exact (lossless)


def test_png_as_is_is_lossless_and_gray_is_luma(tmp_path):
    im = _image()
    assert np.array_equal(_decode(pe.png(im), tmp_path), im)
    g = pe.gray_image(im)
    luma = im.astype(float) @ np.array([0.299, 0.587, 0.114])
    assert g.shape == im.shape and np.all(g[..., 0] == g[..., 2])
    assert np.abs(g[..., 0] - luma).max() <= 1.0


def test_jpeg_re_encodes_with_loss_but_keeps_the_size(tmp_path):
    im = cv2.GaussianBlur(_image(64, 96), (9, 9), 3)
    back = _decode(pe.jpeg(im), tmp_path)
    assert back.shape == im.shape and not np.array_equal(back, im)
    assert np.abs(back.astype(int) - im).mean() < 4


def test_every_transform_is_registered_and_pure():
    im = _image()
    before = im.copy()
    for name, fn in pe.TRANSFORMS.items():
        a, b = fn(im), fn(im)
        assert a == b, name  # deterministic bytes
    assert np.array_equal(im, before)


# ---------------------------------------------------------------- figures against hand-built truth

def _view(boxes, K=None, name="p") -> LabelledView:
    return LabelledView(dataset="d", name=name, image=_image(40, 50),
                        windows=tuple(LabelledWindow(id=f"{name}:{i}", box=np.array(b, float)) for i, b in enumerate(boxes)),
                        K=K)


def _win(box, exported=True, wall=0) -> dict:
    x0, y0, x1, y1 = box
    return {"quad_snapped": [[x0, y0], [x1, y0], [x1, y1], [x0, y1]], "exported": exported, "plausible": exported,
            "wall": wall, "not_exported": None if exported else "flagged: w/h outside 0.2-4", "failure": None}


def test_export_precision_against_hand_built_boxes():
    view = _view([[0, 0, 10, 10], [20, 0, 30, 10]])
    doc = {"K_source": {"source": "prior", "focal_px": 100.0, "interval_px": [80.0, 120.0]}, "walls": [{}],
           "windows": [_win([0, 0, 10, 10]),          # IoU 1 with label 0
                       _win([25, 0, 35, 10]),         # IoU 50 / 150 = 1/3 with label 1: >= 0.3
                       _win([26, 0, 36, 10]),         # IoU 40 / 160 = 1/4: no match
                       _win([40, 20, 45, 30]),        # nothing there
                       _win([0, 0, 10, 10], False)]}  # matches but not exported
    assert pe.exported_matches(doc, [w.bbox() for w in view.windows], 0.3) == (4, 2)
    assert pe.exported_matches(doc, [w.bbox() for w in view.windows], 0.5) == (4, 1)
    row = pe.photo_row(view, pe.AS_IS, doc, None, 1.0, 0.3, True)
    assert (row["n_exported"], row["n_exported_match"], row["n_labelled"], row["n_walls"]) == (4, 2, 2, 1)
    assert row["n_walls_fitted"] == 1
    fig = pe.dataset_summary(pd.DataFrame([row]))
    assert fig["export_precision"] == 0.5 and fig["windows_per_label"] == 2.0 and fig["output_share"] == 1.0
    assert fig["focal_err_median"] is None  # no calibration


def test_model_walls_are_the_walls_of_exported_windows():
    """Three fitted walls; wall 2 holds only a flagged window, wall 3 a failed one: two in the model."""
    failed = {**_win([0, 0, 1, 1], wall=3), "failure": "quad: not_quadrilateral"}
    doc = {"walls": [{}, {}, {}, {}], "windows": [_win([0, 0, 1, 1], wall=0), _win([2, 0, 3, 1], wall=1),
                                                   _win([4, 0, 5, 1], wall=1), _win([6, 0, 7, 1], False, wall=2),
                                                   failed, {**_win([8, 0, 9, 1]), "wall": None}]}
    assert pe.model_walls(doc) == 2
    assert pe.model_walls({"walls": [{}], "windows": []}) == 0


def test_focal_spread_and_focal_error_hand_computed():
    K = np.array([[1000.0, 0, 25], [0, 1000.0, 20], [0, 0, 1]])
    view = _view([[0, 0, 10, 10]], K=K)

    def doc(f, source="vanishing points"):
        return {"K_source": {"source": source, "focal_px": f, "interval_px": [f, f]}, "walls": [], "windows": []}

    rows = [pe.photo_row(view, t, doc(f), None, 1.0, 0.3, True)
            for t, f in ((pe.AS_IS, 1020.0), ("gray", 1020.0 * 1.01), ("crop", 1020.0 * 0.95))]
    fig = pe.dataset_summary(pd.DataFrame(rows))
    assert fig["focal_spread_median"] == pytest.approx(0.05)
    assert fig["focal_spread_observed_median"] == pytest.approx(0.05) and fig["focal_spread_n_observed"] == 1
    assert fig["focal_spread_by_transform"] == pytest.approx({"crop": 0.05, "gray": 0.01})
    assert fig["focal_err_median"] == pytest.approx(0.02) and fig["focal_err_n_observed"] == 1
    prior = pd.DataFrame([pe.photo_row(view, pe.AS_IS, doc(1500.0, "prior"), None, 1.0, 0.3, True)])
    assert pe.dataset_summary(prior)["focal_err_median"] is None  # the prior observes nothing
    assert pe.dataset_summary(prior)["focal_err_median_all"] == pytest.approx(0.5)
    met = {t["key"]: t["met"] for t in pe.check_targets(fig)}
    assert met == {"output_share": True, "focal_spread_observed_median": False, "walls_median": True, "focal_err_median": True,
                   "export_recall": False, "n_exported_oversized": True, "walls_stable_share": True}  # 0 of 1 label, 0 walls each


def test_focal_spread_target_counts_only_photos_the_vanishing_points_observed():
    """A prior photo's crop moves f by the crop by construction: in the all-photo figure, not the target's."""
    def rows(name, source, f, f_crop):
        v = _view([[0, 0, 10, 10]], name=name)
        return [pe.photo_row(v, t, {"K_source": {"source": source, "focal_px": x, "interval_px": [x, x]},
                                    "walls": [], "windows": []}, None, 1.0, 0.3, True)
                for t, x in ((pe.AS_IS, f), ("crop", f_crop))]

    df = pd.DataFrame(rows("a", "prior", 1000.0, 900.0) + rows("b", "vanishing points", 800.0, 808.0)
                      + rows("c", "prior", 500.0, 450.0))
    fig = pe.dataset_summary(df)
    assert fig["focal_spread_median"] == pytest.approx(0.1)  # 0.1, 0.01, 0.1
    assert fig["focal_spread_observed_median"] == pytest.approx(0.01) and fig["focal_spread_n_observed"] == 1
    assert {t["key"]: t["met"] for t in pe.check_targets(fig)}["focal_spread_observed_median"] is True


def _sized(box, w_m, h_m, wall=0, partial=False, exported=True, index=0) -> dict:
    return {**_win(box, exported), "index": index, "width_m": w_m, "height_m": h_m, "wall": wall, "partial": partial}


def test_export_recall_counts_labels_matched_partial_windows_included():
    view = _view([[0, 0, 10, 10], [20, 0, 30, 10], [40, 0, 50, 10]])
    doc = {"windows": [_sized([0, 0, 10, 10], 1, 1),                        # label 0
                       _sized([1, 0, 11, 10], 1, 1),                        # label 0 again: counted once
                       _sized([25, 0, 30, 10], 0.5, 1, partial=True),       # partial: IoU 50/100 with label 1
                       _sized([40, 0, 50, 10], 1, 1, exported=False)]}      # label 2, not exported
    labels = [w.bbox() for w in view.windows]
    assert pe.labels_matched(doc, labels, 0.3) == 2 and pe.labels_matched(doc, labels, 0.6) == 1
    assert pe.labels_matched(doc, [], 0.3) == 0 and pe.labels_matched({"windows": []}, labels, 0.3) == 0
    row = pe.photo_row(view, pe.AS_IS, {**doc, "walls": []}, None, 1.0, 0.3, True)
    assert (row["n_exported"], row["n_exported_match"], row["n_labels_matched"], row["n_exported_partial"]) == (3, 3, 2, 1)
    fig = pe.dataset_summary(pd.DataFrame([row, {**row, "photo": "q", "n_labels_matched": 0, "n_labelled": 5}]))
    assert fig["export_recall"] == pytest.approx(2 / 8) and fig["n_labels_matched"] == 2
    assert fig["export_precision"] == 1.0


def test_oversized_and_taller_than_count_exported_windows_only():
    doc = {"windows": [_sized([0, 0, 1, 1], 4.0, 1.0),              # exactly 4 m: not over
                       _sized([0, 0, 1, 1], 4.01, 1.0),             # wide
                       _sized([0, 0, 1, 1], 1.0, 5.0),              # tall
                       _sized([0, 0, 1, 1], 1.0, 3.3),              # taller than a 3.2 m storey
                       _sized([0, 0, 1, 1], 9.0, 9.0, exported=False),
                       _sized([0, 0, 1, 1], None, 4.5),             # no width: its height counts
                       _sized([0, 0, 1, 1], None, None)]}           # no size (failed): not counted
    assert pe.MAX_WINDOW_M == 4.0  # the pipeline's own flag limit (facade_model)
    assert pe.oversized(doc) == 3 and pe.oversized(doc, 3.0) == 5
    assert pe.taller_than(doc, 3.2) == 3 and pe.taller_than(doc, 5.0) == 0


def _manifest(up, rows=()) -> dict:
    from fenestra.pipeline.export.geometry import camera_to_world

    return {"world_frame": {"camera_to_export": camera_to_world(None if up is None else np.asarray(up, float)).tolist()},
            "storeys": {"rows": [{"windows": list(r)} for r in rows]}}


def test_wall_tilts_against_the_exported_vertical_hand_computed():
    t = math.radians(3.0)
    doc = {"walls": [{"id": 0, "normal": [0.0, 0.0, -1.0]},                      # plumb facing the camera
                     {"id": 1, "normal": [0.0, math.sin(t), -math.cos(t)]},      # leaning 3 deg
                     {"id": 2, "normal": [1.0, 0.0, 0.0]}],                      # no exported window: not in the model
           "windows": [_sized([0, 0, 1, 1], 1, 1, wall=0), _sized([0, 0, 1, 1], 1, 1, wall=1),
                       _sized([0, 0, 1, 1], 1, 1, wall=2, exported=False)]}
    up = pe.export_up(_manifest([0.0, -1.0, 0.0]))
    assert np.allclose(up, [0, -1, 0])
    assert pe.wall_tilts_deg(doc, up) == pytest.approx([0.0, 3.0])
    assert np.allclose(pe.export_up(_manifest(None)), [0, -1, 0])  # the camera-level fallback: the camera's -y
    # a camera pitched 10 deg up: the model's vertical leans in the camera frame, and so does a plumb wall's normal
    p = math.radians(10.0)
    up_p = [0.0, -math.cos(p), math.sin(p)]
    assert np.allclose(pe.export_up(_manifest(up_p)), up_p)
    pitched = {**doc, "walls": [{"id": 0, "normal": [0.0, -math.sin(p), -math.cos(p)]}]}
    assert pe.wall_tilts_deg(pitched, up_p) == pytest.approx([0.0], abs=1e-9)
    assert pe.wall_tilts_deg(pitched, [0.0, -1.0, 0.0]) == pytest.approx([10.0])
    row = pe.photo_row(_view([[0, 0, 1, 1]]), pe.AS_IS, {**doc, "K_source": {}}, None, 1.0, 0.3, True,
                       manifest=_manifest([0.0, -1.0, 0.0]))
    row2 = {**row, "photo": "q", "wall_tilts_deg": [1.0]}
    fig = pe.dataset_summary(pd.DataFrame([row, row2, {**row, "photo": "r", "wall_tilts_deg": None}]))
    assert fig["wall_tilt_median_deg"] == pytest.approx(1.0) and fig["wall_tilt_n_walls"] == 3
    assert fig["wall_tilt_max_deg"] == pytest.approx(3.0)


def test_row_spreads_of_whole_exported_windows():
    doc = {"windows": [_sized([0, 0, 1, 1], 1, 1.0, index=0), _sized([0, 0, 1, 1], 1, 1.1, index=1),
                       _sized([0, 0, 1, 1], 1, 1.2, index=2),                  # row 0: (1.2 - 1.0) / 1.1
                       _sized([0, 0, 1, 1], 1, 0.4, index=3, partial=True),    # partial: its visible part, left out
                       _sized([0, 0, 1, 1], 1, 1.5, index=4),
                       _sized([0, 0, 1, 1], 1, 1.5, index=5),                  # row 1: 0
                       _sized([0, 0, 1, 1], 1, 2.0, index=6),                  # row 2: alone, no spread
                       _sized([0, 0, 1, 1], 1, 9.0, index=7, exported=False)]}
    mf = _manifest(None, rows=[(0, 1, 2, 3), (4, 5, 7), (6,)])
    assert pe.row_spreads(doc, mf) == pytest.approx([0.2 / 1.1, 0.0])
    assert pe.row_spreads(doc, {"storeys": {"rows": []}}) == []


def test_walls_stable_share_hand_computed():
    rows = []
    for photo, counts in (("a", {"as_is": 1, "gray": 1, "crop": 1}),      # stable
                          ("b", {"as_is": 2, "gray": 2, "crop": 1}),      # crop differs
                          ("c", {"as_is": 1, "gray": math.nan}),          # a failed run: not the same
                          ("d", {"as_is": 3, "known_storey": 2}),         # no image transform: not counted
                          ("e", {"as_is": 2, "mirror": 2})):              # stable
        rows += [{"dataset": "d", "photo": photo, "transform": t, "n_walls": n} for t, n in counts.items()]
    assert pe.walls_stable_share(pd.DataFrame(rows)) == (pytest.approx(2 / 4), 4)
    assert pe.walls_stable_share(pd.DataFrame([rows[0]])) == (None, 0)  # as is only


def test_known_storey_rows_give_the_storey_figures_not_a_focal_spread(tmp_path):
    view = _view([[0, 0, 10, 10]])
    ks = {"source": "vanishing points", "focal_px": 1000.0, "interval_px": [900.0, 1100.0]}
    doc = {"K_source": ks, "walls": [{"id": 0, "normal": [0.0, 0.0, -1.0]}],
           "windows": [_sized([0, 0, 10, 10], 1.0, 3.5, index=0), _sized([0, 0, 10, 10], 1.0, 1.5, index=1),
                       _sized([0, 0, 10, 10], 1.0, 1.6, index=2)]}
    mf = _manifest(None, rows=[(1, 2)])
    rows = [pe.photo_row(view, pe.AS_IS, doc, None, 1.0, 0.3, True, manifest=mf),
            pe.photo_row(view, pe.KNOWN_STOREY, {**doc, "K_source": {**ks, "focal_px": 1200.0}}, None, 1.0, 0.3, True,
                         manifest=mf, known_storey_m=3.2)]
    assert rows[0]["n_taller_than_storey"] != rows[0]["n_taller_than_storey"]  # NaN: no storey known as is
    assert rows[1]["n_taller_than_storey"] == 1 and rows[1]["n_exported"] == 3
    fig = pe.dataset_summary(pd.DataFrame(rows))
    assert fig["known_storey_taller"] == 1 and fig["known_storey_m"] == 3.2 and fig["known_storey_n_photos"] == 1
    assert fig["known_storey_row_spread_median"] == pytest.approx(0.1 / 1.55) and fig["known_storey_n_rows"] == 1
    assert fig["n_photos"] == 1 and fig["n_exported"] == 3  # the as-is figures from the as-is row only
    assert fig["focal_spread_by_transform"] == {} and fig["focal_spread_median"] is None
    assert fig["walls_stable_share"] is None
    met = {t["key"]: t["met"] for t in pe.check_targets(fig)}
    assert met["known_storey_taller"] is False and met["known_storey_row_spread_median"] is False
    assert met["n_exported_oversized"] is True and met["wall_tilt_median_deg"] is True
    spec = pe.KfreeSpec(datasets=("d", "e"), known_storey_datasets=("d",), transform_datasets=("e",),
                        transforms=("gray",), known_storey_m=3.0)
    tasks = pe.kfree_tasks(spec, [view, LabelledView(dataset="e", name="q", image=view.image, windows=())], tmp_path)
    assert [(t.view.dataset, t.transform) for t in tasks] == [("d", "as_is"), ("d", "known_storey"), ("e", "as_is"), ("e", "gray")]
    assert [t.known_storey_m for t in tasks][1] == 3.0 and all(math.isnan(tasks[i].known_storey_m) for i in (0, 2, 3))
    with pytest.raises(ValueError, match="known_storey_datasets"):
        pe.KfreeSpec(datasets=("d",), known_storey_datasets=("x",))
    with pytest.raises(ValueError, match="known_storey_m"):
        pe.KfreeSpec(datasets=("d",), known_storey_m=0.0)


def test_failed_run_counts_as_no_output():
    row = pe.photo_row(_view([[0, 0, 10, 10]]), pe.AS_IS, None, "PipelineError: x", 1.0, 0.3, False)
    fig = pe.dataset_summary(pd.DataFrame([row]))
    assert fig["output_share"] == 0.0 and fig["errors"] == {"p": "PipelineError: x"}


# ---------------------------------------------------------------- profile

def test_kfree_table_of_the_real_profile():
    p = load_real_profile("real")
    assert p.kfree is not None and "spb_facades" in p.kfree.transform_datasets
    assert set(p.kfree.transforms) == {"gray", "jpeg", "exif_rot", "mirror", "crop"}
    names = [d.name for d in p.available_datasets()[0]]
    assert "spb_val" not in names  # kfree_only: never in the method grid
    base = {"name": "u", "kind": "real", "data": "/x/y", "format": "yolo"}
    with pytest.raises(ProfileError, match="not datasets of the profile"):
        real_profile_from_dict({**base, "kfree": {"datasets": ["z"]}})
    with pytest.raises(ProfileError, match="transforms"):
        real_profile_from_dict({**base, "kfree": {"datasets": ["y"], "transforms": ["blur"]}})
    with pytest.raises(ProfileError, match="unknown key"):
        real_profile_from_dict({**base, "kfree": {"datasets": ["y"], "photos": 3}})


# ---------------------------------------------------------------- end to end

def test_bench_real_reaches_the_kfree_block(tmp_path):
    from fenestra.bench.runner import run_benchmark
    from lab.docs.figures import collect_kfree
    from lab.docs.text import kfree_section
    from fenestra.reports.real import real_sections

    ds = tmp_path / "boxes"
    (ds / "images").mkdir(parents=True)
    (ds / "labels").mkdir()
    cv2.imwrite(str(ds / "images" / "a.png"), _image(120, 160))
    (ds / "labels" / "a.txt").write_text("0 0.25 0.25 0.2 0.2\n")
    prof = real_profile_from_dict({
        "name": "t", "kind": "real", "methods": {"detectors": ["oracle"], "snappers": ["none"], "pose_solvers": ["lm"]},
        "datasets": [{"name": "boxes", "format": "yolo", "path": str(ds)}],
        "kfree": {"datasets": ["boxes"], "transform_datasets": ["boxes"], "transforms": ["mirror", "crop"],
                  "known_storey_datasets": ["boxes"], "known_storey_m": 3.0}})
    info = run_benchmark(prof, out_dir=tmp_path / "run", progress=False, report=False)
    summary = json.loads((info.run_dir / "summary.json").read_text())
    block = summary["kfree"]
    df = pd.read_parquet(info.run_dir / pe.KFREE_PARQUET)
    assert sorted(df["transform"]) == ["as_is", "crop", "known_storey", "mirror"] and "kfree" in info.stage_time_s
    exported = df.set_index("transform")
    for t in ("as_is", "known_storey"):  # exported: export.json was read (a list, maybe empty), not None
        assert exported.loc[t, "wall_tilts_deg"] is not None and exported.loc[t, "row_spreads"] is not None
    assert exported.loc["mirror", "wall_tilts_deg"] is None and exported.loc["known_storey", "known_storey_m"] == 3.0
    d = block["datasets"]["boxes"]
    assert d["n_photos"] == 1 and d["output_share"] == 1.0 and d["n_labelled"] == 1
    assert d["K_sources"] == {"prior": 1}  # noise: no vanishing point, no EXIF
    assert d["known_storey_n_photos"] == 1 and d["known_storey_m"] == 3.0 and d["walls_stable_n_photos"] == 1
    assert {"export_recall", "n_exported_oversized", "walls_stable_share"} <= {t["key"] for t in d["targets"]}
    assert d["focal_spread_by_transform"].keys() == {"mirror", "crop"}  # the known storey is no transform
    # the prior is a field of view of the frame: mirrored the same focal length, cropped 144 / 160 of it
    assert d["focal_spread_by_transform"]["mirror"] == 0.0
    assert d["focal_spread_by_transform"]["crop"] == pytest.approx(1 - 144 / 160, abs=1e-9)
    sections = real_sections(info.run_dir, summary["results"], summary)
    assert ("h2", "K-free path: `fenestra reconstruct PHOTO` without intrinsics") in sections
    table = next(sec for sec in sections if sec[0] == "table" and sec[1][:2] == ["dataset", "figure"])
    assert ["boxes", "photos with an output", 1.0, ">= 1", "yes"] in table[2]
    md = "\n".join(kfree_section(collect_kfree(block)))
    assert "crop 0.100, mirror 0.000" in md and "`boxes`" in md  # spread shown; no target: the prior observes nothing
    assert "focal_spread_observed_median" not in {t["key"] for t in d["targets"]}
    assert "labelled windows exported (partial windows included)" in md and "`--known-storey 3`" in md
    assert math.isclose(collect_kfree(block)["datasets"]["boxes"]["focal_spread_median"], 0.1, rel_tol=1e-3)


def test_labelled_masks_written_as_the_instance_map_reconstruct_reads(tmp_path):
    from fenestra.masks import SparseMask
    from fenestra.images import read_instances

    m = np.zeros((40, 50), bool)
    m[5:15, 10:20] = True
    view = LabelledView(dataset="d", name="p", image=_image(40, 50),
                        windows=(LabelledWindow(id="p:0", mask=SparseMask.from_dense(m)),))
    path = pe.write_masks(view, tmp_path / "m.png")
    assert np.array_equal(read_instances(path, (50, 40)), m.astype(np.int32))
    assert pe.write_masks(_view([[0, 0, 10, 10]]), tmp_path / "n.png") is None  # boxes only: no masks
    with pytest.raises(ValueError, match="mask_datasets"):
        pe.KfreeSpec(datasets=("a",), transform_datasets=("a",), mask_datasets=("a",))


def _facade(seed: int) -> np.ndarray:
    """A light wall with a grid of dark windows (something for the detector and the focal chain)."""
    im = np.full((120, 160, 3), 200, np.uint8)
    rng = np.random.default_rng(seed)
    for y in (15, 65):
        for x in (15, 60, 105):
            im[y:y + 35, x:x + 30] = rng.integers(20, 60)
    return im


def test_kfree_in_two_processes_gives_the_rows_of_one(tmp_path):
    from fenestra.masks import SparseMask

    m = np.zeros((120, 160), bool)
    m[15:50, 15:45] = True
    views = [LabelledView(dataset="t", name="a", image=_facade(0),
                          windows=(LabelledWindow(id="a:0", box=np.array([15.0, 15, 45, 50])),)),
             LabelledView(dataset="m", name="a", image=_facade(1),  # same name as t/a: own folders
                          windows=(LabelledWindow(id="a:0", mask=SparseMask.from_dense(m)),)),
             LabelledView(dataset="t", name="no/such", image=_facade(2),  # its file cannot be written: raises
                          windows=())]
    spec = pe.KfreeSpec(datasets=("t", "m"), transform_datasets=("t",), mask_datasets=("m",),
                        transforms=("mirror",))
    one, two = (pe.evaluate_kfree(spec, views, workers=w).drop(columns="seconds") for w in (1, 2))
    assert list(one[["dataset", "photo", "transform"]].itertuples(index=False, name=None)) == [
        ("t", "a", "as_is"), ("t", "a", "mirror"), ("m", "a", "as_is"), ("t", "no/such", "as_is"), ("t", "no/such", "mirror")]
    assert one.loc[3:, "error"].str.startswith("FileNotFoundError").all() and not one.loc[3:, "output"].any()
    assert one.loc[:2, "error"].isna().all() and one.loc[2, "detections"] == "labelled masks"
    for df in (one, two):  # the error names the run's temporary folder
        df["error"] = df["error"].str.replace(r"fenestra-kfree-[^/]+/", "TMP/", regex=True)
    pd.testing.assert_frame_equal(one, two)


def test_interval_coverage_against_a_calibration_by_hand():
    """Three observed photos of known f = 1000 px: intervals [950, 1050] and [990, 1000] hold it
    (the bound counts), [1010, 1100] does not: 2 of 3."""
    rows = pd.DataFrame({"focal_true_px": [1000.0, 1000.0, 1000.0, math.nan],
                         "focal_lo_px": [950.0, 990.0, 1010.0, 900.0], "focal_hi_px": [1050.0, 1000.0, 1100.0, 1100.0]})
    assert pe.interval_coverage(rows) == {"focal_interval_coverage": pytest.approx(2 / 3), "focal_interval_n": 3}
    assert pe.interval_coverage(rows.iloc[3:]) == {"focal_interval_coverage": None, "focal_interval_n": 0}
