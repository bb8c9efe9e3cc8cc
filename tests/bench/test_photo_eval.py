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

from fenestra.bench import kfree_summary as ks
from fenestra.bench import photo_eval as pe
from fenestra.bench import photo_transforms as pt
from fenestra.bench.evaluators import row_spreads, wall_tilts_deg
from fenestra.bench.real.profile import ProfileError, load_real_profile, real_profile_from_dict
from fenestra.bench.views import LabelledView, LabelledWindow
from fenestra.errors import DatasetError
from fenestra.images import read_image
from fenestra.methods import Method
from fenestra.pipeline.export import WrittenModel
from fenestra.pipeline.export.floors import floor_levels
from fenestra.pipeline.export.geometry import Gravity, StoreyLevels
from fenestra.pipeline.facade_model import FacadeModel, Known, WallModel
from fenestra.pipeline.intrinsics import FocalEstimate, ResolvedK
from fenestra.pipeline.session import ExportDecision, Reconstruction, Window
from fenestra.pipeline.types import Failure, Partial, WindowResult


def _image(h: int = 60, w: int = 100, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)


def _decode(enc: pt.Encoded, tmp_path: Path, name: str = "x") -> np.ndarray:
    p = tmp_path / f"{name}{enc.suffix}"
    p.write_bytes(enc.data)
    return read_image(p)


# ---------------------------------------------------------------- transforms

def test_mirror_twice_is_identity_and_mirrors_columns():
    im = _image()
    m = pt.mirror_image(im)
    assert np.array_equal(m[:, 0], im[:, -1]) and np.array_equal(m[7, 30], im[7, 100 - 1 - 30])
    assert np.array_equal(pt.mirror_image(m), im)


def test_crop_removes_ten_percent_centred():
    im = _image(60, 100)
    c = pt.crop_image(im)
    assert c.shape == (54, 90, 3)  # 5 % of 100 = 5 columns and 5 % of 60 = 3 rows off each side
    assert np.array_equal(c, im[3:57, 5:95])
    with pytest.raises(ValueError, match="0.5"):
        pt.crop_image(im, 0.5)


def test_exif_rotated_file_reads_back_as_the_original(tmp_path):
    im = _image(60, 100)
    enc = pt.exif_rotated(im)
    with Image.open(io.BytesIO(enc.data)) as f:
        assert f.getexif().get(0x0112) == 6
        assert f.size == (60, 100)  # stored turned: W and H swapped
    assert np.array_equal(_decode(enc, tmp_path), im)  # the one reader applies the tag: exact (lossless)


def test_png_as_is_is_lossless_and_gray_is_luma(tmp_path):
    im = _image()
    assert np.array_equal(_decode(pt.png(im), tmp_path), im)
    g = pt.gray_image(im)
    luma = im.astype(float) @ np.array([0.299, 0.587, 0.114])
    assert g.shape == im.shape and np.all(g[..., 0] == g[..., 2])
    assert np.abs(g[..., 0] - luma).max() <= 1.0


def test_jpeg_re_encodes_with_loss_but_keeps_the_size(tmp_path):
    im = cv2.GaussianBlur(_image(64, 96), (9, 9), 3)
    back = _decode(pt.jpeg(im), tmp_path)
    assert back.shape == im.shape and not np.array_equal(back, im)
    assert np.abs(back.astype(int) - im).mean() < 4


def test_every_transform_is_registered_and_pure():
    im = _image()
    before = im.copy()
    for name, fn in pt.TRANSFORMS.items():
        a, b = fn(im), fn(im)
        assert a == b, name  # deterministic bytes
    assert np.array_equal(im, before)


def test_decoded_in_memory_is_what_the_cli_reads_from_the_file(tmp_path):
    """Every transform's photo as the session takes it (pixels, EXIF tags) equals what
    `fenestra reconstruct` reads from a file of the same bytes (fenestra.images.read_image and
    pipeline.intrinsics.read_exif_tags of the file)."""
    from fenestra.pipeline.intrinsics import read_exif_tags

    im = cv2.GaussianBlur(_image(64, 96), (5, 5), 2)
    for name, fn in pt.TRANSFORMS.items():
        enc = fn(im)
        path = tmp_path / f"{name}{enc.suffix}"
        path.write_bytes(enc.data)
        photo = pt.transformed(im, name)
        assert np.array_equal(photo.image, read_image(path)), name
        assert photo.exif == read_exif_tags(path), name
    assert pt.transformed(im, "exif_rot").exif == {0x0112: 6} and pt.transformed(im, "as_is").exif == {}
    with pytest.raises(DatasetError, match="not an image"):
        pt.decode(pt.Encoded(b"not an image", ".png"))


# ---------------------------------------------------------------- figures against hand-built truth

def _view(boxes, K=None, name="p") -> LabelledView:
    return LabelledView(dataset="d", name=name, image=_image(40, 50),
                        windows=tuple(LabelledWindow(id=f"{name}:{i}", box=np.array(b, float)) for i, b in enumerate(boxes)),
                        K=K)


def _res(index: int, box, w_m=1.0, h_m=1.0, partial=False, failure=None) -> WindowResult:
    """A window's result: its snapped quad the box's corners, its size w_m x h_m m (w_m None: no
    aspect ratio; h_m None: no height either), a plumb pose facing the camera."""
    x0, y0, x1, y1 = box
    q = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)
    cut = Partial(("left",), Failure("quad", "touches_border", "the left edge")) if partial else None
    return WindowResult(index=index, score=0.9, quad_mask=q, quad_snapped=q,
                        aspect_ratio=None if w_m is None or h_m is None else w_m / h_m, aspect_case=None,
                        focal_estimate_px=None, R=np.eye(3), t=np.array([0.0, 0.0, 10.0]), height_m=h_m,
                        quad_reprojected=q, failure=failure, partial=cut)


def _win(index: int, box, exported=True, wall=0, **kw) -> Window:
    r = _res(index, box, **kw)
    return Window(index, r, r, r if r.partial is not None else None, None, None,
                  ExportDecision(exported, None if exported else "implausible: w/h outside 0.2-4"), wall)


def _rec(windows, walls=(), flags=None, source="prior", f=100.0, interval=(80.0, 120.0)) -> Reconstruction:
    """A Reconstruction of ``windows`` (Window) on walls {id: normal (3,)}, the focal chain's answer
    ``source`` f px in ``interval``; flags {index: [reasons]} of the façade model."""
    K = np.array([[f, 0, 25], [0, f, 20], [0, 0, 1]])
    wall_models = [WallModel(i, tuple(w.index for w in windows if w.wall == i), np.asarray(n, float), 10.0, "assumed",
                             True, (i,)) for i, n in walls]
    return Reconstruction(Method("default", "none", "lm"), (), tuple(windows),
                          ResolvedK(K, FocalEstimate(source, f, interval, ""), (), {}, ()),
                          FacadeModel(wall_models, dict(flags or {})), Known(), {}, None)


def _model(up=None, rows=()) -> WrittenModel:
    """The written model's vertical ``up`` (None: camera level) and storey rows (window indices)."""
    row_of = {i: r for r, row in enumerate(rows) for i in row}
    return WrittenModel((), (), Gravity(None if up is None else np.asarray(up, float), "given"),
                        StoreyLevels(row_of, tuple(float(r) for r in range(len(rows))), 0.9, 0.5), 0.0,
                        floor_levels([]))


def _run(view, rec, transform=pe.AS_IS, model="auto", known_storey_m=math.nan, error=None) -> pe.KfreeRun:
    """The run of ``transform`` on ``view`` that gave ``rec`` (None: raised ``error``); export runs
    get a camera-level model with no rows unless ``model`` is given."""
    task = pe.KfreeTask(view, transform, 0.3, "", False, known_storey_m)
    if model == "auto":
        model = _model() if task.exports and rec is not None else None
    return pe.KfreeRun(task, rec, model, error, 1.0)


PLUMB = (0.0, 0.0, -1.0)


def test_export_precision_against_hand_built_boxes():
    view = _view([[0, 0, 10, 10], [20, 0, 30, 10]])
    rec = _rec([_win(0, [0, 0, 10, 10]),           # IoU 1 with label 0
                _win(1, [25, 0, 35, 10]),          # IoU 50 / 150 = 1/3 with label 1: >= 0.3
                _win(2, [26, 0, 36, 10]),          # IoU 40 / 160 = 1/4: no match
                _win(3, [40, 20, 45, 30]),         # nothing there
                _win(4, [0, 0, 10, 10], False)],   # matches but not exported
               walls=[(0, PLUMB)])
    assert pe.exported_matches(rec, [w.bbox() for w in view.windows], 0.3) == (4, 2)
    assert pe.exported_matches(rec, [w.bbox() for w in view.windows], 0.5) == (4, 1)
    row = pe.photo_row(_run(view, rec))
    assert (row["n_exported"], row["n_exported_match"], row["n_labelled"], row["n_walls"]) == (4, 2, 2, 1)
    assert row["n_walls_fitted"] == 1 and row["n_detected"] == 5 and row["n_plausible"] == 5
    fig = ks.dataset_summary(pd.DataFrame([row]))
    assert fig["export_precision"] == 0.5 and fig["windows_per_label"] == 2.0 and fig["output_share"] == 1.0
    assert fig["focal_err_median"] is None  # no calibration
    mirrored = pe.photo_row(_run(view, rec, "mirror"))  # no export under a transform: no export figures
    assert math.isnan(mirrored["n_exported"]) and mirrored["wall_tilts_deg"] is None and mirrored["n_walls"] == 1


def test_model_walls_are_the_walls_of_exported_windows():
    """Three fitted walls; wall 2 holds only a flagged window, wall 3 a failed one: two in the model."""
    failed = _win(4, [0, 0, 1, 1], wall=3, failure=Failure("quad", "not_quadrilateral", ""))
    rec = _rec([_win(0, [0, 0, 1, 1], wall=0), _win(1, [2, 0, 3, 1], wall=1), _win(2, [4, 0, 5, 1], wall=1),
                _win(3, [6, 0, 7, 1], False, wall=2), failed, _win(5, [8, 0, 9, 1], wall=None)],
               walls=[(i, PLUMB) for i in range(4)], flags={3: ["w/h outside 0.2-4"]})
    assert rec.model_wall_ids() == {0, 1}
    assert _rec([]).model_wall_ids() == set()
    row = pe.photo_row(_run(_view([]), rec))
    assert (row["n_walls"], row["n_walls_fitted"], row["n_plausible"]) == (2, 4, 4)  # flagged and failed: not plausible


def test_focal_spread_and_focal_error_hand_computed():
    K = np.array([[1000.0, 0, 25], [0, 1000.0, 20], [0, 0, 1]])
    view = _view([[0, 0, 10, 10]], K=K)

    def rec(f, source="vanishing points"):
        return _rec([], source=source, f=f, interval=(f, f))

    rows = [pe.photo_row(_run(view, rec(f), t))
            for t, f in ((pe.AS_IS, 1020.0), ("gray", 1020.0 * 1.01), ("crop", 1020.0 * 0.95))]
    assert rows[0]["focal_err_rel"] == pytest.approx(0.02) and rows[0]["focal_true_px"] == 1000.0
    fig = ks.dataset_summary(pd.DataFrame(rows))
    assert fig["focal_spread_median"] == pytest.approx(0.05)
    assert fig["focal_spread_observed_median"] == pytest.approx(0.05) and fig["focal_spread_n_observed"] == 1
    assert fig["focal_spread_by_transform"] == pytest.approx({"crop": 0.05, "gray": 0.01})
    assert fig["focal_err_median"] == pytest.approx(0.02) and fig["focal_err_n_observed"] == 1
    prior = pd.DataFrame([pe.photo_row(_run(view, rec(1500.0, "prior")))])
    assert ks.dataset_summary(prior)["focal_err_median"] is None  # the prior observes nothing
    assert ks.dataset_summary(prior)["focal_err_median_all"] == pytest.approx(0.5)
    met = {t["key"]: t["met"] for t in ks.check_targets(fig)}
    assert met == {"output_share": True, "focal_spread_observed_median": False, "walls_median": True, "focal_err_median": True,
                   "export_recall": False, "n_exported_oversized": True, "walls_stable_share": True}  # 0 of 1 label, 0 walls each


def test_focal_spread_target_counts_only_photos_the_vanishing_points_observed():
    """A prior photo's crop moves f by the crop by construction: in the all-photo figure, not the target's."""
    def rows(name, source, f, f_crop):
        v = _view([[0, 0, 10, 10]], name=name)
        return [pe.photo_row(_run(v, _rec([], source=source, f=x, interval=(x, x)), t))
                for t, x in ((pe.AS_IS, f), ("crop", f_crop))]

    df = pd.DataFrame(rows("a", "prior", 1000.0, 900.0) + rows("b", "vanishing points", 800.0, 808.0)
                      + rows("c", "prior", 500.0, 450.0))
    fig = ks.dataset_summary(df)
    assert fig["focal_spread_median"] == pytest.approx(0.1)  # 0.1, 0.01, 0.1
    assert fig["focal_spread_observed_median"] == pytest.approx(0.01) and fig["focal_spread_n_observed"] == 1
    assert {t["key"]: t["met"] for t in ks.check_targets(fig)}["focal_spread_observed_median"] is True


def test_export_recall_counts_labels_matched_partial_windows_included():
    view = _view([[0, 0, 10, 10], [20, 0, 30, 10], [40, 0, 50, 10]])
    rec = _rec([_win(0, [0, 0, 10, 10]),                               # label 0
                _win(1, [1, 0, 11, 10]),                               # label 0 again: counted once
                _win(2, [25, 0, 30, 10], w_m=0.5, partial=True),       # partial: IoU 50/100 with label 1
                _win(3, [40, 0, 50, 10], exported=False)])             # label 2, not exported
    labels = [w.bbox() for w in view.windows]
    assert pe.labels_matched(rec, labels, 0.3) == 2 and pe.labels_matched(rec, labels, 0.6) == 1
    assert pe.labels_matched(rec, [], 0.3) == 0 and pe.labels_matched(_rec([]), labels, 0.3) == 0
    row = pe.photo_row(_run(view, rec))
    assert (row["n_exported"], row["n_exported_match"], row["n_labels_matched"], row["n_exported_partial"]) == (3, 3, 2, 1)
    fig = ks.dataset_summary(pd.DataFrame([row, {**row, "photo": "q", "n_labels_matched": 0, "n_labelled": 5}]))
    assert fig["export_recall"] == pytest.approx(2 / 8) and fig["n_labels_matched"] == 2
    assert fig["export_precision"] == 1.0


def test_oversized_and_taller_than_count_exported_windows_only():
    box = [0, 0, 1, 1]
    rec = _rec([_win(0, box, w_m=4.0, h_m=1.0),              # exactly 4 m: not over
                _win(1, box, w_m=4.01, h_m=1.0),             # wide
                _win(2, box, w_m=1.0, h_m=5.0),              # tall
                _win(3, box, w_m=1.0, h_m=3.3),              # taller than a 3.2 m storey
                _win(4, box, False, w_m=9.0, h_m=9.0),
                _win(5, box, w_m=None, h_m=4.5),             # no width: its height counts
                _win(6, box, w_m=None, h_m=None)])           # no size (failed): not counted
    assert pe.MAX_WINDOW_M == 4.0  # the pipeline's own flag limit (facade_model)
    assert pe.oversized(rec) == 3 and pe.oversized(rec, 3.0) == 5
    assert pe.taller_than(rec, 3.2) == 3 and pe.taller_than(rec, 5.0) == 0


def test_wall_tilts_against_the_written_vertical_hand_computed():
    t = math.radians(3.0)
    box = [0, 0, 1, 1]
    rec = _rec([_win(0, box, wall=0), _win(1, box, wall=1), _win(2, box, exported=False, wall=2)],
               walls=[(0, PLUMB),                                  # plumb facing the camera
                      (1, (0.0, math.sin(t), -math.cos(t))),       # leaning 3 deg
                      (2, (1.0, 0.0, 0.0))])                       # no exported window: not in the model
    up = _model([0.0, -1.0, 0.0]).up
    assert np.allclose(up, [0, -1, 0])
    assert list(wall_tilts_deg(rec, up).values()) == pytest.approx([0.0, 3.0]) and list(wall_tilts_deg(rec, up)) == [0, 1]
    assert np.allclose(_model(None).up, [0, -1, 0])  # the camera-level fallback: the camera's -y
    # a camera pitched 10 deg up: the model's vertical leans in the camera frame, and so does a plumb wall's normal
    p = math.radians(10.0)
    up_p = [0.0, -math.cos(p), math.sin(p)]
    assert np.allclose(_model(up_p).up, up_p)
    pitched = _rec([_win(0, box, wall=0)], walls=[(0, (0.0, -math.sin(p), -math.cos(p)))])
    assert list(wall_tilts_deg(pitched, up_p).values()) == pytest.approx([0.0], abs=1e-9)
    assert list(wall_tilts_deg(pitched, [0.0, -1.0, 0.0]).values()) == pytest.approx([10.0])
    row = pe.photo_row(_run(_view([[0, 0, 1, 1]]), rec, model=_model([0.0, -1.0, 0.0])))
    assert row["wall_tilts_deg"] == pytest.approx([0.0, 3.0])
    row2 = {**row, "photo": "q", "wall_tilts_deg": [1.0]}
    fig = ks.dataset_summary(pd.DataFrame([row, row2, {**row, "photo": "r", "wall_tilts_deg": None}]))
    assert fig["wall_tilt_median_deg"] == pytest.approx(1.0) and fig["wall_tilt_n_walls"] == 3
    assert fig["wall_tilt_max_deg"] == pytest.approx(3.0)


def test_row_spreads_of_whole_exported_windows():
    box = [0, 0, 1, 1]
    rec = _rec([_win(0, box, h_m=1.0), _win(1, box, h_m=1.1),
                _win(2, box, h_m=1.2),                                # row 0: (1.2 - 1.0) / 1.1
                _win(3, box, h_m=0.4, partial=True),                  # partial: its visible part, left out
                _win(4, box, h_m=1.5),
                _win(5, box, h_m=1.5),                                # row 1: 0
                _win(6, box, h_m=2.0),                                # row 2: alone, no spread
                _win(7, box, h_m=9.0, exported=False)])
    rows = _model(None, rows=[(0, 1, 2, 3), (4, 5, 7), (6,)]).rows()
    assert rows == [[0, 1, 2, 3], [4, 5, 7], [6]]
    assert row_spreads(rec, rows) == pytest.approx([0.2 / 1.1, 0.0])
    assert row_spreads(rec, []) == []


def test_walls_stable_share_hand_computed():
    rows = []
    for photo, counts in (("a", {"as_is": 1, "gray": 1, "crop": 1}),      # stable
                          ("b", {"as_is": 2, "gray": 2, "crop": 1}),      # crop differs
                          ("c", {"as_is": 1, "gray": math.nan}),          # a failed run: not the same
                          ("d", {"as_is": 3, "known_storey": 2}),         # no image transform: not counted
                          ("e", {"as_is": 2, "mirror": 2})):              # stable
        rows += [{"dataset": "d", "photo": photo, "transform": t, "n_walls": n} for t, n in counts.items()]
    assert ks.walls_stable_share(pd.DataFrame(rows)) == (pytest.approx(2 / 4), 4)
    assert ks.walls_stable_share(pd.DataFrame([rows[0]])) == (None, 0)  # as is only


def test_known_storey_rows_give_the_storey_figures_not_a_focal_spread():
    view = _view([[0, 0, 10, 10]])
    wins = [_win(0, [0, 0, 10, 10], h_m=3.5), _win(1, [0, 0, 10, 10], h_m=1.5), _win(2, [0, 0, 10, 10], h_m=1.6)]
    mf = _model(None, rows=[(1, 2)])
    rows = [pe.photo_row(_run(view, _rec(wins, walls=[(0, PLUMB)], source="vanishing points", f=1000.0,
                                         interval=(900.0, 1100.0)), model=mf)),
            pe.photo_row(_run(view, _rec(wins, walls=[(0, PLUMB)], source="vanishing points", f=1200.0,
                                         interval=(900.0, 1100.0)), pe.KNOWN_STOREY, model=mf, known_storey_m=3.2))]
    assert rows[0]["n_taller_than_storey"] != rows[0]["n_taller_than_storey"]  # NaN: no storey known as is
    assert rows[1]["n_taller_than_storey"] == 1 and rows[1]["n_exported"] == 3
    fig = ks.dataset_summary(pd.DataFrame(rows))
    assert fig["known_storey_taller"] == 1 and fig["known_storey_m"] == 3.2 and fig["known_storey_n_photos"] == 1
    assert fig["known_storey_row_spread_median"] == pytest.approx(0.1 / 1.55) and fig["known_storey_n_rows"] == 1
    assert fig["n_photos"] == 1 and fig["n_exported"] == 3  # the as-is figures from the as-is row only
    assert fig["focal_spread_by_transform"] == {} and fig["focal_spread_median"] is None
    assert fig["walls_stable_share"] is None
    met = {t["key"]: t["met"] for t in ks.check_targets(fig)}
    assert met["known_storey_taller"] is False and met["known_storey_row_spread_median"] is False
    assert met["n_exported_oversized"] is True and met["wall_tilt_median_deg"] is True
    spec = pe.KfreeSpec(datasets=("d", "e"), known_storey_datasets=("d",), transform_datasets=("e",),
                        transforms=("gray",), known_storey_m=3.0)
    tasks = pe.kfree_tasks(spec, [view, LabelledView(dataset="e", name="q", image=view.image, windows=())])
    assert [(t.view.dataset, t.transform) for t in tasks] == [("d", "as_is"), ("d", "known_storey"), ("e", "as_is"), ("e", "gray")]
    assert [t.known_storey_m for t in tasks][1] == 3.0 and all(math.isnan(tasks[i].known_storey_m) for i in (0, 2, 3))
    with pytest.raises(ValueError, match="known_storey_datasets"):
        pe.KfreeSpec(datasets=("d",), known_storey_datasets=("x",))
    with pytest.raises(ValueError, match="known_storey_m"):
        pe.KfreeSpec(datasets=("d",), known_storey_m=0.0)
    with pytest.raises(ValueError, match="known storey height"):
        pe.KfreeTask(view, pe.KNOWN_STOREY, 0.3, "", False)
    with pytest.raises(ValueError, match="untransformed frame"):
        pe.KfreeTask(view, "mirror", 0.3, "", True)


def test_failed_run_counts_as_no_output():
    row = pe.photo_row(_run(_view([[0, 0, 10, 10]]), None, error="PipelineError: x"))
    assert not row["output"] and row["K_source"] is None and math.isnan(row["focal_px"]) and math.isnan(row["n_walls"])
    fig = ks.dataset_summary(pd.DataFrame([row]))
    assert fig["output_share"] == 0.0 and fig["errors"] == {"p": "PipelineError: x"}


# ---------------------------------------------------------------- profile

def test_kfree_table_of_the_real_profile():
    p = load_real_profile("real")
    kfree = p.source.kfree
    assert kfree is not None and "spb_facades" in kfree.transform_datasets
    assert set(kfree.transforms) == {"gray", "jpeg", "exif_rot", "mirror", "crop"}
    names = [d.name for d in p.source.available()[0]]
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


def _facade(seed: int) -> np.ndarray:
    """A light wall with a grid of dark windows (something for the detector and the focal chain)."""
    im = np.full((120, 160, 3), 200, np.uint8)
    rng = np.random.default_rng(seed)
    for y in (15, 65):
        for x in (15, 60, 105):
            im[y:y + 35, x:x + 30] = rng.integers(20, 60)
    return im


def test_labelled_masks_are_the_instance_map_the_session_reads():
    """A mask dataset's run detects with the labelled masks (the oracle on the view's instance
    map, as `fenestra reconstruct --masks`): its one detection is the labelled mask, pixel for pixel."""
    from fenestra.masks import SparseMask

    m = np.zeros((120, 160), bool)
    m[15:50, 15:45] = True
    view = LabelledView(dataset="d", name="p", image=_facade(0), windows=(LabelledWindow(id="p:0", mask=SparseMask.from_dense(m)),))
    task = pe.KfreeTask(view, pe.AS_IS, 0.3, "", True)
    assert np.array_equal(task.instances(), m.astype(np.int32)) and task.detections == "labelled masks"
    run = pe.run_task(task)
    assert run.error is None and run.rec.method.detector == "oracle" and len(run.rec.detections) == 1
    d = run.rec.detections[0]
    full = np.zeros_like(m)
    full[d.origin[1]:d.origin[1] + d.mask.shape[0], d.origin[0]:d.origin[0] + d.mask.shape[1]] = d.mask
    assert np.array_equal(full, m)
    boxes = pe.KfreeTask(_view([[0, 0, 10, 10]]), pe.AS_IS, 0.3, "", True)  # boxes only: no masks, the detector
    assert boxes.instances() is None and boxes.detections == "default"
    with pytest.raises(ValueError, match="mask_datasets"):
        pe.KfreeSpec(datasets=("a",), transform_datasets=("a",), mask_datasets=("a",))


def test_kfree_in_two_processes_gives_the_rows_of_one(tmp_path):
    from fenestra.masks import SparseMask

    m = np.zeros((120, 160), bool)
    m[15:50, 15:45] = True
    views = [LabelledView(dataset="t", name="a", image=_facade(0),
                          windows=(LabelledWindow(id="a:0", box=np.array([15.0, 15, 45, 50])),)),
             LabelledView(dataset="m", name="a", image=_facade(1),  # same name as t/a: own folders
                          windows=(LabelledWindow(id="a:0", mask=SparseMask.from_dense(m)),)),
             LabelledView(dataset="t", name="tiny", image=_facade(2)[:4, :4],  # too small for the pipeline: raises
                          windows=())]
    spec = pe.KfreeSpec(datasets=("t", "m"), transform_datasets=("t",), mask_datasets=("m",),
                        transforms=("mirror",))
    one, two = (pe.evaluate_kfree(spec, views, workers=w).drop(columns="seconds") for w in (1, 2))
    assert list(one[["dataset", "photo", "transform"]].itertuples(index=False, name=None)) == [
        ("t", "a", "as_is"), ("t", "a", "mirror"), ("m", "a", "as_is"), ("t", "tiny", "as_is"), ("t", "tiny", "mirror")]
    assert one.loc[3:, "error"].str.startswith("ImageError: image too small").all() and not one.loc[3:, "output"].any()
    assert one.loc[:2, "error"].isna().all() and one.loc[2, "detections"] == "labelled masks"
    pd.testing.assert_frame_equal(one, two)


def test_interval_coverage_against_a_calibration_by_hand():
    """Three observed photos of known f = 1000 px: intervals [950, 1050] and [990, 1000] hold it
    (the bound counts), [1010, 1100] does not: 2 of 3."""
    rows = pd.DataFrame({"focal_true_px": [1000.0, 1000.0, 1000.0, math.nan],
                         "focal_lo_px": [950.0, 990.0, 1010.0, 900.0], "focal_hi_px": [1050.0, 1000.0, 1100.0, 1100.0]})
    assert ks.interval_coverage(rows) == {"focal_interval_coverage": pytest.approx(2 / 3), "focal_interval_n": 3}
    assert ks.interval_coverage(rows.iloc[3:]) == {"focal_interval_coverage": None, "focal_interval_n": 0}


def test_each_kfree_evaluator_gives_its_own_columns_and_together_the_row():
    """Every evaluator of the K-free block returns exactly the columns it declares, for an export
    run, a transform run and a run that raised; the row is the run's identity, their columns in
    order and what detected the windows."""
    view = _view([[0, 0, 10, 10]])
    rec = _rec([_win(0, [0, 0, 10, 10])], walls=[(0, PLUMB)])
    runs = (_run(view, rec), _run(view, rec, "gray"), _run(view, None, error="ImageError: x"),
            _run(view, rec, pe.KNOWN_STOREY, known_storey_m=3.0))
    for run in runs:
        cols = []
        for e in pe.kfree_evaluators():
            got = e.process(view, run)
            assert tuple(got) == e.columns, type(e).__name__
            cols += list(got)
        row = pe.photo_row(run)
        assert list(row) == ["dataset", "photo", "transform", "output", "error", "seconds", *cols, "detections"]
