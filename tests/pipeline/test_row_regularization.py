"""Row regularization (issue 35, pipeline.row_lines): the windows of one storey row of one wall
get the row's consensus sill and head lines; outliers, flagged and partial windows keep their own
and never move the consensus; windows.json keeps the measured values."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fenestra.conventions import project
from fenestra.pipeline.facade_model import FacadeModel, WallModel
from fenestra.pipeline.photo import row_fields
from fenestra.pipeline.row_lines import ROW_AGREE_FRACTION, regularize_rows, row_consensus
from fenestra.pipeline.types import Failure, Partial, WindowResult

# a frontal wall 10 m away: window x along the camera's x, window up along the camera's -y, outward to the camera
R_WALL = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
K = np.array([[1000.0, 0.0, 640.0], [0.0, 1000.0, 480.0], [0.0, 0.0, 1.0]])
WIDTH_M = 1.0


def _window(i: int, x: float, sill: float, h: float, partial: bool = False) -> WindowResult:
    """A posed window on the wall: bottom-left corner at x (m along the wall), sill (m up, from the
    camera's height), height h, width WIDTH_M."""
    t = np.array([x, -sill, 10.0])
    rect = np.array([[0.0, h, 0.0], [WIDTH_M, h, 0.0], [WIDTH_M, 0.0, 0.0], [0.0, 0.0, 0.0]])
    q = project(K, R_WALL, t, rect)
    part = Partial(("left",), Failure("quad", "touches_border", "mask reaches the image left edge")) if partial else None
    return WindowResult(i, 0.9, q, q, WIDTH_M / h, "general", None, R_WALL.copy(), t, h, q, None, group=0,
                        partial=part)


def _model(members, partial=(), flags=None) -> FacadeModel:
    return FacadeModel([WallModel(0, tuple(members), R_WALL[:, 2], 10.0, "assumed", True, (0,), tuple(partial))],
                       flags or {})


def _sill(r: WindowResult) -> float:
    return float(R_WALL[:, 1] @ np.asarray(r.t))


ROW = [(0.90, 1.50), (0.92, 1.52), (0.89, 1.48), (0.91, 1.55)]  # (sill, height) m: one window type


def _row(extra=()) -> list[WindowResult]:
    return [_window(i, 2.0 * i, s, h) for i, (s, h) in enumerate(ROW)] + list(extra)


def test_row_consensus_is_the_median_of_the_agreeing_windows():
    s = np.array([0.90, 0.92, 0.89, 0.91, 0.90])
    h = s + np.array([1.50, 1.52, 1.48, 1.55, 2.40])  # the last: a door-like window, its head 0.9 m higher
    S, H, tol, agree = row_consensus(s, h)
    assert agree.tolist() == [True, True, True, True, False]
    assert S == pytest.approx(np.median(s[:4])) and H == pytest.approx(np.median(h[:4]))
    assert tol == pytest.approx(ROW_AGREE_FRACTION * (np.median(h) - np.median(s)))
    with pytest.raises(ValueError, match="sills and heads"):
        row_consensus(s, h[:3])


def test_a_row_of_four_windows_gets_one_sill_and_one_head():
    results = _row()
    out, fits = regularize_rows(results, _model(range(4)), K)
    sills = np.array([s for s, _ in ROW])
    heads = sills + np.array([h for _, h in ROW])
    for k, r in enumerate(out):
        assert fits[k].regularized and fits[k].voters == (0, 1, 2, 3)
        assert _sill(r) == pytest.approx(np.median(sills), abs=1e-12)
        assert _sill(r) + r.height_m == pytest.approx(np.median(heads), abs=1e-12)
        assert r.aspect_ratio * r.height_m == pytest.approx(WIDTH_M)  # the width stays measured
        np.testing.assert_allclose(r.R, results[k].R)  # and the rotation, and the plane (depth)
        assert r.t[0] == pytest.approx(results[k].t[0]) and r.t[2] == pytest.approx(results[k].t[2])
        rect = np.array([[0.0, r.height_m, 0.0], [WIDTH_M, r.height_m, 0.0], [WIDTH_M, 0.0, 0.0], [0.0, 0.0, 0.0]])
        np.testing.assert_allclose(r.quad_reprojected, project(K, r.R, r.t, rect), atol=1e-9)
        assert results[k].height_m == ROW[k][1]  # the input is left as it was
    heights = [r.height_m for r in out]
    assert max(heights) - min(heights) < 1e-12


def test_a_door_like_window_keeps_its_own_and_does_not_move_the_consensus():
    door = _window(4, 8.0, 0.90, 2.40)
    out, fits = regularize_rows(_row([door]), _model(range(5)), K)
    assert out[4] is door and not fits[4].regularized and 4 in fits[4].voters and 4 not in fits[4].agreeing
    ref, _ = regularize_rows(_row(), _model(range(4)), K)
    for a, b in zip(out[:4], ref):
        assert a.height_m == pytest.approx(b.height_m) and _sill(a) == pytest.approx(_sill(b))


def test_a_partial_window_keeps_its_own_and_does_not_vote():
    part = _window(4, 8.0, 1.20, 0.80, partial=True)  # its visible part only
    out, fits = regularize_rows(_row([part]), _model(range(4), partial=(4,)), K)
    assert out[4] is part and 4 not in fits
    ref, _ = regularize_rows(_row(), _model(range(4)), K)
    assert [r.height_m for r in out[:4]] == pytest.approx([r.height_m for r in ref])


def test_flagged_windows_and_lone_windows_are_left_alone():
    results = _row()
    out, fits = regularize_rows(results, _model(range(4), flags={3: ["size: ..."]}), K)
    assert out[3] is results[3] and 3 not in fits and all(fits[k].regularized for k in range(3))
    out, fits = regularize_rows(results[:1], _model([0]), K)  # a row of one: nothing to agree with
    assert out[0] is results[0] and not fits


def test_rows_of_one_wall_are_regularized_each_on_its_own():
    upper = [_window(4 + i, 2.0 * i, s + 3.2, h) for i, (s, h) in enumerate([(0.9, 1.30), (0.95, 1.34), (0.88, 1.32)])]
    out, fits = regularize_rows(_row(upper), _model(range(7)), K)
    assert {fits[k].row for k in range(4)} == {0} and {fits[k].row for k in range(4, 7)} == {1}
    assert len({round(out[k].height_m, 9) for k in range(4)}) == 1
    assert len({round(out[k].height_m, 9) for k in range(4, 7)}) == 1
    assert out[4].height_m == pytest.approx(np.median([4.1 + 1.30, 4.15 + 1.34, 4.08 + 1.32]) - 4.1)


def test_windows_json_keeps_the_measured_values():
    results = _row()
    out, fits = regularize_rows(results, _model(range(4)), K)
    f = row_fields(out[1], results[1], fits[1])
    assert f["regularized"] and f["height_measured_m"] == pytest.approx(1.52)
    assert f["measured"]["height_m"] == pytest.approx(1.52) and f["measured"]["width_m"] == pytest.approx(WIDTH_M)
    assert f["measured"]["t"] == pytest.approx(results[1].t.tolist())
    assert f["row"]["voters"] == [0, 1, 2, 3] and f["row"]["height_m"] == pytest.approx(out[1].height_m)
    g = row_fields(results[1], None, None)  # not regularized: its own fields are the measured ones
    assert not g["regularized"] and g["measured"] is None and g["row"] is None and g["height_measured_m"] == 1.52


def test_reconstruct_exports_each_row_of_agreeing_windows_at_one_height(tmp_path):
    """End to end on the bundled curtain-wall photo (4 panes, 2 rows of 2, all 143.2 mm tall):
    in each row of export.json, the exported whole windows that agreed with their row's lines
    (``regularized``) have heights within TOL.row_height_spread_rel of each other, the measured
    heights stay in windows.json, and model.ifc's windows have the exported (regularized) heights."""
    import ifcopenshell  # noqa: PLC0415

    from fenestra.pipeline.cli import run_reconstruct  # noqa: PLC0415
    from fenestra.tolerances import TOL  # noqa: PLC0415

    ex = Path(__file__).resolve().parents[2] / "examples" / "curtainwall"
    out = tmp_path / "out"
    doc = run_reconstruct(ex / "img086.jpg", out, K_json=ex / "K.json", masks=ex / "panes086.png", snapper="linefit",
                          width=0.0932).to_json()
    saved = json.loads((out / "windows.json").read_text())
    manifest = json.loads((out / "export.json").read_text())
    assert saved["windows"] == doc["windows"]
    win = {w["index"]: w for w in saved["windows"]}
    checked = 0
    for row in manifest["storeys"]["rows"]:
        whole = [win[i] for i in row["windows"] if win[i]["exported"] and not win[i]["partial"]]
        agreed = [w for w in whole if w["regularized"]]
        if len(agreed) >= 2:
            h = np.array([w["height_m"] for w in agreed])
            assert (h.max() - h.min()) / np.median(h) <= TOL.row_height_spread_rel
            checked += 1
    assert checked >= 1  # the photo has rows to check, not none
    for w in saved["windows"]:
        if w["regularized"]:
            assert w["measured"]["height_m"] == w["height_measured_m"] and w["row"]["regularized"]
            assert w["width_m"] == pytest.approx(w["measured"]["width_m"])  # widths stay measured
    exported = sorted(e["height_m"] for e in manifest["exported"])
    assert exported == pytest.approx(sorted(win[e["index"]]["height_m"] for e in manifest["exported"]))
    ifc = ifcopenshell.open(str(out / "model.ifc"))
    assert sorted(float(x.OverallHeight) for x in ifc.by_type("IfcWindow")) == pytest.approx(exported, rel=1e-6)
