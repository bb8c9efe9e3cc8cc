"""Windows cut by the photo's border are exported as partial windows (issue 35), not dropped.

A flat wall (its own frame: x along, y up, z out of the wall) with two rows of six 1.2 x 1.5 m
windows, seen by a known camera turned 20 deg about the vertical (no pitch, no roll): the left
column hangs off the photo's left edge. The photo is drawn with exact area coverage and the masks
by pixel centres (tests/quad_image.py), so every truth below comes from the scene geometry here,
not from the code under test: the visible width of a cut window is where the ray of the image's
left edge (u = -0.5) meets the wall, up to the window's right side (with no pitch and no roll an
image column is a vertical line on the wall).
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from quad_image import coverage, pixel_centre_mask

W, H, F = 960, 640, 800.0
K = np.array([[F, 0.0, (W - 1) / 2], [0.0, F, (H - 1) / 2], [0.0, 0.0, 1.0]])
WIN_W, WIN_H = 1.2, 1.5
COLUMNS = (-4.9, -2.4, 0.0, 2.4, 4.8, 7.2)  # left edges, m along the wall; the first is cut by the photo
ROWS = (1.0, 4.0)  # bottom edges, m up the wall
CUT_IDS = (1, 7)  # instance ids of the cut windows (the first column of each row)


def camera(yaw_deg: float = 20.0, dist_m: float = 12.0, look_at=(5.5, 3.0)) -> tuple[np.ndarray, np.ndarray]:
    """Wall-to-camera R (3, 3), t (3,) m of a camera ``dist_m`` in front of the wall point
    ``look_at`` (x, y m), turned ``yaw_deg`` about the vertical."""
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ np.diag([1.0, -1.0, -1.0])  # wall y up -> image up
    return R, np.array([0.0, 0.0, dist_m]) - R @ np.array([*look_at, 0.0])


def window_corners(x0: float, y0: float) -> np.ndarray:
    """(4, 3) wall-frame corners TL TR BR BL of the window with bottom-left corner (x0, y0) m."""
    return np.array([[x0, y0 + WIN_H, 0], [x0 + WIN_W, y0 + WIN_H, 0], [x0 + WIN_W, y0, 0], [x0, y0, 0]], float)


def project(R: np.ndarray, t: np.ndarray, P: np.ndarray) -> np.ndarray:
    x = (P @ R.T + t) @ K.T
    return x[:, :2] / x[:, 2:3]


def wall_point(R: np.ndarray, t: np.ndarray, u: float, v: float) -> np.ndarray:
    """(3,) wall-frame point (m) where the ray of pixel (u, v) meets the wall z = 0."""
    d = np.linalg.solve(K, np.array([u, v, 1.0]))
    s = (R[:, 2] @ t) / (R[:, 2] @ d)
    return R.T @ (s * d - t)


def write_photo(d: Path, windows: list[np.ndarray], R, t, drawn=None, masked=None) -> tuple[Path, Path, Path]:
    """photo.png, masks.png (instance id k + 1 per window) and K.json in ``d``; ``drawn`` /
    ``masked``: the ids drawn in the photo / in the instance map (default: all)."""
    d.mkdir(parents=True)
    img, inst = np.full((H, W), 200.0), np.zeros((H, W), np.uint16)
    for k, P in enumerate(windows, start=1):
        q = project(R, t, P)
        if drawn is None or k in drawn:
            img += (40.0 - 200.0) * coverage(q, (H, W))
        if masked is None or k in masked:
            inst[pixel_centre_mask(q, (H, W))] = k
    g = np.clip(np.round(img), 0, 255).astype(np.uint8)
    cv2.imwrite(str(d / "photo.png"), np.repeat(g[:, :, None], 3, axis=2))
    cv2.imwrite(str(d / "masks.png"), inst)
    (d / "K.json").write_text(json.dumps({"K": K.tolist(), "width": W, "height": H}))
    return d / "photo.png", d / "masks.png", d / "K.json"


def run(d: Path, windows, R, t, drawn=None, masked=None, export: bool = False) -> dict:
    """reconstruct_photo of the photo written into ``d`` (K given, the masks given, a known window
    height: the truth's), its output in d / "out"; the windows.json data."""
    from fenestra.pipeline.facade_model import Known
    from fenestra.pipeline.photo import PhotoOptions, reconstruct_photo

    photo, masks, K_json = write_photo(d, windows, R, t, drawn, masked)
    return reconstruct_photo(photo, d / "out", K_json=K_json, masks=masks,
                             options=PhotoOptions(known=Known(window_height_m=WIN_H), export=export)).to_json()


def by_id(doc: dict) -> dict[int, dict]:
    return {w["instance_id"]: w for w in doc["windows"]}


@pytest.fixture(scope="module")
def scene():
    R, t = camera()
    windows = [window_corners(x, y) for y in ROWS for x in COLUMNS]
    for k, P in enumerate(windows, start=1):  # the scene is what the tests say it is
        q = project(R, t, P)
        cut = bool(np.any(q[:, 0] < -0.5))
        assert cut == (k in CUT_IDS) and np.all(q[:, 0] < W - 0.5) and np.all((q[:, 1] > 0) & (q[:, 1] < H - 1)), k
        assert cut is False or q[1, 0] > 10  # a cut window shows a good part of itself
    return R, t, windows


@pytest.fixture(scope="module")
def runs(scene, tmp_path_factory):
    """The photo with its cut windows (exported), the same photo with the cut windows' masks left
    out, and the photo with the cut windows not drawn at all (nor masked)."""
    R, t, windows = scene
    root = tmp_path_factory.mktemp("partial")
    whole = [k for k in range(1, len(windows) + 1) if k not in CUT_IDS]
    return {"cut": run(root / "cut", windows, R, t, export=True),
            "masks": run(root / "masks", windows, R, t, masked=whole),
            "photo": run(root / "photo", windows, R, t, drawn=whole, masked=whole),
            "out": root / "cut" / "out"}


def test_a_window_cut_by_the_left_border_is_completed_to_its_row(scene, runs):
    """Exported whole, never at its visible size: its width is its row's whole windows' (1.2 m,
    within 1 % and the one-pixel quantisation of its right side), its true left edge off the
    photo is recovered (where the scene puts it), and its visible fraction is the visible width
    (where the ray of the image's left edge, u = -0.5, meets the wall) over the whole width."""
    R, t, windows = scene
    doc = by_id(runs["cut"])
    for k in CUT_IDS:
        w, P = doc[k], windows[k - 1]
        q = project(R, t, P)
        assert w["partial"] is True and w["cut"] == ["left"] and w["failure"] is None and w["exported"], w
        assert w["wall"] == doc[2]["wall"] is not None
        v_mid = float(np.mean(q[:, 1]))
        x_edge = [wall_point(R, t, -0.5, v)[0] for v in (q[0, 1], v_mid, q[3, 1])]
        assert np.ptp(x_edge) < 1e-9  # an image column is a vertical line on this wall
        visible_w = P[1, 0] - x_edge[0]
        m_per_px = WIN_W / float(np.linalg.norm(q[1] - q[0]))  # along the window's top side, near enough
        tol = m_per_px + 0.01 * WIN_W
        assert 0.3 < visible_w < WIN_W - 0.3
        assert w["width_m"] == pytest.approx(WIN_W, abs=0.01 * WIN_W), (k, w["width_m"])
        assert w["height_m"] == pytest.approx(WIN_H, abs=m_per_px + 0.01 * WIN_H)
        assert w["visible_fraction"] == pytest.approx(visible_w / WIN_W, abs=tol / WIN_W)
        # its left edge (BL corner) off the photo, where the scene puts it: the true offsets from
        # its whole neighbour's BL corner, along and up the reconstructed wall (its axes)
        n = doc[k + 1]
        Rn, d = np.asarray(n["R"]), np.asarray(w["t"]) - np.asarray(n["t"])
        truth = windows[k][3] - P[3]  # wall frame: the neighbour's BL minus this one's
        assert d @ Rn[:, 0] == pytest.approx(-truth[0], abs=tol) and d @ Rn[:, 1] == pytest.approx(-truth[1], abs=tol)
        assert w["aspect_interval"] is None and w["plausible"]
        # the visible quad: its left side on the image's left edge, its right side the window's;
        # the reprojected quad: the whole window, reaching past the photo's left edge
        vq, rq = np.asarray(w["quad_snapped"]), np.asarray(w["quad_reprojected"])
        assert np.allclose(vq[[0, 3], 0], -0.5) and np.allclose(vq[[1, 2], 0], q[[1, 2], 0], atol=1.0)
        assert np.abs(rq - q).max() < 2.0 and rq[:, 0].min() < -0.5
    assert all(not w["partial"] and w["cut"] == [] for k, w in doc.items() if k not in CUT_IDS)
    wall = runs["cut"]["walls"][0]
    assert sorted(wall["partial"]) == sorted(doc[k]["index"] for k in CUT_IDS)
    assert not set(wall["partial"]) & set(wall["members"])


def test_partial_windows_do_not_bias_their_wall(runs):
    """The whole windows' wall (its plane, scale) and their poses and sizes: exactly those of the
    same photo without the cut windows' masks, and, within the façade line fit's share of the
    cut windows' edges, those of the photo without the cut windows."""
    cut, masks, photo = runs["cut"], runs["masks"], runs["photo"]
    assert len(cut["walls"]) == len(masks["walls"]) == len(photo["walls"]) == 1
    a, b = cut["walls"][0], masks["walls"][0]
    assert a["distance_m"] == b["distance_m"] and a["normal"] == b["normal"]
    assert a["scale_source"] == b["scale_source"] == "known window height 1.5 m"
    assert len(a["members"]) == len(b["members"]) == 10
    for k, w in by_id(masks).items():
        v = by_id(cut)[k]
        assert (v["R"], v["t"], v["width_m"], v["height_m"], v["plausible"]) == \
               (w["R"], w["t"], w["width_m"], w["height_m"], w["plausible"]), k
    assert photo["walls"][0]["distance_m"] == pytest.approx(a["distance_m"], rel=1e-3)
    for k, w in by_id(photo).items():
        v = by_id(cut)[k]
        assert np.abs(np.asarray(v["R"]) - np.asarray(w["R"])).max() < 2e-3  # < 0.1 deg
        assert v["width_m"] == pytest.approx(w["width_m"], rel=1e-3)


def test_windows_json_the_ifc_pset_and_the_overlay_carry_the_flag(runs):
    import ifcopenshell
    import ifcopenshell.util.element

    out = runs["out"]
    saved = json.loads((out / "windows.json").read_text())
    flags = [(w["partial"], w["cut"]) for w in saved["windows"]]
    assert flags == [(w["partial"], w["cut"]) for w in runs["cut"]["windows"]]
    partial = {w["index"] for w in saved["windows"] if w["partial"]}
    assert len(partial) == 2 and partial <= set(saved["export"]["exported"])
    f = ifcopenshell.open(str(out / "model.ifc"))
    windows = f.by_type("IfcWindow")
    assert len(windows) == 12
    fen = {int(w.Name.split()[1]): ifcopenshell.util.element.get_psets(w)["Fenestra_Window"] for w in windows}
    assert {i for i, p in fen.items() if p["Partial"]} == partial
    assert all(fen[i]["CutBy"] == "left" for i in partial) and all("CutBy" not in p for i, p in fen.items()
                                                                 if i not in partial)
    walls = f.by_type("IfcWall")
    assert len(walls) == 1 and ifcopenshell.util.element.get_psets(walls[0])["Fenestra_Wall"]["WindowCount"] == 12
    # the overlay: the cut windows' visible quads dashed in the partial colour
    from fenestra.pipeline.export.overlay import COLOURS

    overlay = cv2.cvtColor(cv2.imread(str(out / "overlay.png")), cv2.COLOR_BGR2RGB)[:H, :W]
    cyan = np.all(overlay == COLOURS["partial"], axis=2)
    assert 0 < cyan[:, :40].sum() and cyan[:, 200:].sum() == 0


def test_a_photo_whose_windows_are_all_cut_gives_recorded_failures(scene, tmp_path):
    """No whole window, so no wall: every cut window is a failure row with a one-line reason and
    its cut sides, nothing is exported, and the command does not crash."""
    R, t, windows = scene
    doc = run(tmp_path / "all-cut", [windows[k - 1] for k in CUT_IDS], R, t, export=True)
    assert len(doc["windows"]) == 2 and doc["walls"] == []
    for w in doc["windows"]:
        assert w["partial"] and w["cut"] == ["left"] and not w["exported"]
        assert w["failure"].startswith("wall: partial window (cut by the photo's left edge): no wall")
        assert "\n" not in w["failure"] and w["not_exported"]
    assert (tmp_path / "all-cut" / "out" / "windows.json").is_file()
    assert (tmp_path / "all-cut" / "out" / "overlay.png").is_file()


def test_visible_extent_recovers_wall_points_on_the_true_plane(scene):
    """pipeline.facade_model.visible_extent with the true wall (R, plane distance): the rectangle
    around a quad of known wall points is their bounding box in the wall's axes, to float noise."""
    from fenestra.pipeline.facade_model import own_sides, visible_extent

    R, t, _ = scene
    P = np.array([[-0.3, 2.0, 0], [0.9, 2.2, 0], [1.1, 0.4, 0], [-0.2, 0.5, 0]])  # a quad on the wall, TL TR BR BL
    q = project(R, t, P)
    dist = -float(R[:, 2] @ t)  # the wall z = 0 in the camera frame: R[:, 2] . X = R[:, 2] . t
    t_est, w, h = visible_extent(q, K, R, dist)
    assert w == pytest.approx(1.4, abs=1e-9) and h == pytest.approx(1.8, abs=1e-9)
    assert np.allclose(R.T @ (t_est - t), [-0.3, 0.4, 0.0], atol=1e-9)  # its bottom-left corner on the wall
    assert own_sides(q, (), (W, H)) == (0, 1, 2, 3)
    for x_bl in (-0.5, 1.5):  # the left side on the image's edge, or tilted off it by a learned mask's fit
        edge = np.array([[-0.5, 10.0], [50.0, 10.0], [50.0, 60.0], [x_bl, 60.0]])
        assert own_sides(edge, ("left",), (W, H)) == (0, 1, 2)
    corner = np.array([[-0.5, -0.5], [50.0, -0.5], [50.0, 60.0], [-0.5, 60.0]])
    assert own_sides(corner, ("top", "left"), (W, H)) == (1, 2)


def test_the_visible_part_of_a_cut_mask_is_fitted_with_the_image_edge_as_a_side():
    """pipeline.quad.mask_to_quad of a rectangle cut by the image's left and top edges: refused as
    touches_border by default; with allow_border, the quad of the visible part, its left and top
    sides the image's edges (x, y = -0.5), the others the rectangle's (rasterised by pixel centres
    here: its edges within half a pixel)."""
    from fenestra.pipeline.quad import QuadParams, mask_to_quad

    rect = np.array([[-30.0, -20.3], [60.3, -20.3], [60.3, 80.7], [-30.0, 80.7]])  # TL TR BR BL, px
    mask = pixel_centre_mask(rect, (120, 160))
    assert mask_to_quad(mask).failure.code == "touches_border"
    qr = mask_to_quad(mask, QuadParams(allow_border=True))
    assert qr.failure is None and qr.cut == ("top", "left")
    visible = np.array([[-0.5, -0.5], [60.3, -0.5], [60.3, 80.7], [-0.5, 80.7]])
    assert np.abs(qr.quad - visible).max() < 0.5, qr.quad


def test_a_cut_window_with_no_whole_window_in_its_row_is_left_out_with_the_reason(scene, tmp_path):
    """Only the upper row's whole windows are masked: the upper cut window is completed from them,
    the lower one has no whole window in its row, so it is a recorded failure (code
    ``not_completed``, the reason in words), never exported at its visible size."""
    R, t, windows = scene
    upper = [k for k in range(1, len(windows) + 1) if k > len(COLUMNS)]
    doc = by_id(run(tmp_path / "one-row", windows, R, t, masked=[*upper, CUT_IDS[0]], export=True))
    low, high = doc[CUT_IDS[0]], doc[CUT_IDS[1]]
    assert high["failure"] is None and high["exported"] and high["width_m"] == pytest.approx(WIN_W, rel=0.01)
    assert low["partial"] and not low["exported"] and low["failure"].startswith("wall: not_completed: ")
    assert "no whole window in its row" in low["failure"] and low["not_exported"]
