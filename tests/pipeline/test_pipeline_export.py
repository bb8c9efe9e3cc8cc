"""fenestra/pipeline/export (with export/substitute), fenestra/pipeline/catalogue against an independent synthetic view.

Ground truth: a planar facade with window voids, photographed by a known camera. The photo is made
here with cv2.warpPerspective of a metric facade canvas (the plane homography K [r1 r2 t]); quads
are the void corners projected with K by this file's own pinhole formula. Nothing below uses the
exporters' geometry helpers to produce expected values.
"""
from __future__ import annotations

import json

import cv2
import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.placement
import ifcopenshell.validate
import numpy as np
import pytest
import trimesh

from fenestra.conventions import K_from_fov, look_at
from fenestra.errors import PipelineError
from fenestra.pipeline.catalogue import CATALOGUE, window_mesh
from fenestra.pipeline.export import write_outputs
from fenestra.pipeline.export.substitute import substitute
from fenestra.pipeline.types import Failure, WindowResult

IMG_W, IMG_H = 640, 480
K = K_from_fov(IMG_W, IMG_H, 65.0)
# Camera pose w.r.t. the facade frame (x along the wall, y up, z outward), OpenCV convention.
R_F, T_F = look_at([1.8, 1.0, 6.5], [0.8, 0.8, 0.0], up=(0.0, 1.0, 0.0))
# Voids on the facade: (x0, y0, w, h) m. The third one's reconstruction "fails".
VOIDS = [(0.0, 0.0, 1.2, 1.5), (2.2, 0.2, 1.0, 1.3), (-2.0, 0.0, 1.0, 1.5)]
# glTF's y-up frame from a z-up one: (x, y, z) -> (x, z, -y)
Z_TO_Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])


def export_to_camera(manifest: dict) -> np.ndarray:
    """Export world -> camera rotation (3, 3) as export.json states it (its inverse, camera ->
    export, is checked against the true façade's vertical by test_export_world_is_upright...)."""
    return np.asarray(manifest["world_frame"]["camera_to_export"], dtype=np.float64).T


def export_offset(manifest: dict) -> np.ndarray:
    """The export world's origin shift (3,) m as export.json states it: X_E = M @ X_C + offset
    (the ground plane at z = 0; the camera at ``offset``)."""
    return np.asarray(manifest["world_frame"]["offset_m"], dtype=np.float64)


def camera_points(manifest: dict, X: np.ndarray) -> np.ndarray:
    """Export-world points (N, 3) m -> camera frame (N, 3) m, by export.json's world_frame."""
    return (np.asarray(X, dtype=np.float64).reshape(-1, 3) - export_offset(manifest)) @ export_to_camera(manifest).T


def pinhole(X_cam: np.ndarray, K: np.ndarray = K) -> np.ndarray:
    """Camera-frame points (N, 3) -> pixels (N, 2), this test's own projection."""
    x = np.asarray(X_cam, dtype=np.float64) @ K.T
    return x[:, :2] / x[:, 2:3]


def void_corners_facade(x0, y0, w, h) -> np.ndarray:
    """TL TR BR BL on the facade, (4, 3) m."""
    return np.array([[x0, y0 + h, 0], [x0 + w, y0 + h, 0], [x0 + w, y0, 0], [x0, y0, 0]], dtype=np.float64)


def gt_quad(i: int) -> np.ndarray:
    return pinhole(void_corners_facade(*VOIDS[i]) @ R_F.T + T_F)


def quad_mask(quad: np.ndarray) -> np.ndarray:
    m = np.zeros((IMG_H, IMG_W), dtype=np.uint8)
    cv2.fillPoly(m, [np.round(quad * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    return m.astype(bool)


def read_rgb(path) -> np.ndarray:
    """An output PNG as (H, W, 3) uint8 RGB (the pipeline's colour order; cv2 reads BGR)."""
    return cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)


def synthetic_photo() -> np.ndarray:
    """The facade (bricks with noise, dark voids) seen by the camera: (H, W, 3) uint8 RGB."""
    rng = np.random.default_rng(0)
    s, xmin, ymax, xs, ys = 100.0, -4.0, 5.0, 12.0, 9.0  # px per m, canvas extent (m)
    cw, ch = int(xs * s), int(ys * s)
    canvas = np.empty((ch, cw, 3), dtype=np.float64)
    canvas[:] = (90, 120, 170)
    yy, xx = np.mgrid[0:ch, 0:cw]
    canvas[(yy % 8 == 0) | ((xx + 12 * ((yy // 8) % 2)) % 24 == 0)] = (200, 200, 205)  # mortar
    canvas += rng.normal(0, 12, canvas.shape)
    for x0, y0, w, h in VOIDS:
        a0, a1 = int((x0 - xmin) * s), int((x0 + w - xmin) * s)
        b0, b1 = int((ymax - y0 - h) * s), int((ymax - y0) * s)
        canvas[b0:b1, a0:a1] = (45, 40, 35) + rng.normal(0, 5, (b1 - b0, a1 - a0, 3))
    canvas = np.clip(canvas, 0, 255).astype(np.uint8)
    A = np.array([[1 / s, 0, xmin + 0.5 / s], [0, -1 / s, ymax - 0.5 / s], [0, 0, 1.0]])
    Hm = K @ np.column_stack([R_F[:, 0], R_F[:, 1], T_F]) @ A
    return cv2.warpPerspective(canvas, Hm, (IMG_W, IMG_H), flags=cv2.INTER_LINEAR)


def window_result(i: int, height_m: float) -> WindowResult:
    """The exact reconstruction of void i, with its pose solved at scale ``height_m``."""
    x0, y0, w, h = VOIDS[i]
    k = height_m / h  # scale of the pose's metric frame relative to the true one
    R = R_F
    t = k * (T_F + R_F @ np.array([x0, y0, 0.0]))
    q = gt_quad(i)
    return WindowResult(i, 0.95, q + 0.3, q, w / h, "general", None, R, t, height_m, q, None)


def all_results() -> list[WindowResult]:
    good = [window_result(0, 1.0), window_result(1, 1.3)]  # window 0 at the 1 m default scale
    failed = WindowResult(2, 0.8, gt_quad(2), gt_quad(2), None, None, None, None, None, 1.0, None,
                          Failure("pose", None, "solvePnP did not converge"))
    bad_R = WindowResult(3, 0.5, None, None, 1.0, "general", None, 2.0 * np.eye(3), np.array([0, 0, 5.0]),
                         1.0, None, None)
    behind = WindowResult(4, 0.5, None, None, 1.0, "general", None, np.eye(3), np.array([0, 0, -5.0]),
                          1.0, None, None)
    return good + [failed, bad_R, behind]


@pytest.fixture(scope="module")
def photo() -> np.ndarray:
    return synthetic_photo()


@pytest.fixture(scope="module")
def outputs(tmp_path_factory, photo):
    out = tmp_path_factory.mktemp("export")
    paths = write_outputs(out, photo, K, all_results(), substitute="two-by-two-mullion")
    return paths, json.loads(paths["manifest"].read_text())


@pytest.fixture(scope="module")
def ifc(outputs):
    return ifcopenshell.open(str(outputs[0]["ifc"]))


def test_outputs_written_and_failed_windows_reported(outputs):
    paths, manifest = outputs
    for key in ("ifc", "texture", "obj", "mtl", "glb", "overlay", "inpainted", "substituted", "manifest"):
        assert paths[key].is_file() and paths[key].stat().st_size > 0, key
    assert [e["index"] for e in manifest["exported"]] == [0, 1]
    skipped = {e["index"]: e["reason"] for e in manifest["skipped"]}
    assert set(skipped) == {2, 3, 4}
    assert "solvePnP" in skipped[2] and "rotation" in skipped[3] and "in front" in skipped[4]


def test_ifc_reopens_and_every_product_geometry_iterates(ifc):
    assert ifc.schema == "IFC4"
    assert len(ifc.by_type("IfcWindow")) == 2 and len(ifc.by_type("IfcWall")) == 2
    assert len(ifc.by_type("IfcRelVoidsElement")) == 2 and len(ifc.by_type("IfcRelFillsElement")) == 2
    expected = {p.GlobalId for p in ifc.by_type("IfcProduct") if p.Representation is not None}
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    it = ifcopenshell.geom.iterator(settings, ifc, 1)
    assert it.initialize()
    got = set()
    while True:
        shape = it.get()
        assert len(shape.geometry.faces) > 0, shape.guid
        got.add(shape.guid)
        if not it.next():
            break
    assert {p.GlobalId for p in ifc.by_type("IfcWall") + ifc.by_type("IfcWindow")} <= got
    assert expected - got <= {o.GlobalId for o in ifc.by_type("IfcOpeningElement")}  # iterator may skip openings
    for product in ifc.by_type("IfcProduct"):  # ... so build every product's shape one by one too
        if product.Representation is not None:
            shape = ifcopenshell.geom.create_shape(settings, product)
            assert len(shape.geometry.faces) > 0, product


def test_ifc_is_schema_valid(ifc):
    logger = ifcopenshell.validate.json_logger()
    ifcopenshell.validate.validate(ifc, logger, express_rules=True)
    assert logger.statements == []


def _window_corners_px(window, manifest: dict) -> np.ndarray:
    """The window's void corners TL TR BR BL in the photo: its placement is IFC's window frame
    (x along the wall, y into it, z up), the origin at the void's bottom-left."""
    M = ifcopenshell.util.placement.get_local_placement(window.ObjectPlacement)
    w, h = window.OverallWidth, window.OverallHeight
    local = np.array([[0, 0, h, 1], [w, 0, h, 1], [w, 0, 0, 1], [0, 0, 0, 1]], dtype=np.float64)
    world = (local @ M.T)[:, :3]
    return pinhole(camera_points(manifest, world))


def test_ifc_window_placement_and_size_match_pose(ifc, outputs):
    by_name = {wnd.Name.split()[1]: wnd for wnd in ifc.by_type("IfcWindow")}
    for i, height_m in ((0, 1.0), (1, 1.3)):
        wnd = by_name[str(i)]
        assert wnd.OverallHeight == pytest.approx(height_m, abs=1e-9)
        assert wnd.OverallWidth / wnd.OverallHeight == pytest.approx(VOIDS[i][2] / VOIDS[i][3], rel=1e-9)
        assert np.abs(_window_corners_px(wnd, outputs[1]) - gt_quad(i)).max() < 0.5
        # Exact in practice, not just within the 0.5 px requirement.
        assert np.abs(_window_corners_px(wnd, outputs[1]) - gt_quad(i)).max() < 1e-6


def _iterated_meshes(ifc, ifc_class):
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    meshes = {}
    for product in ifc.by_type(ifc_class):
        shape = ifcopenshell.geom.create_shape(settings, product)
        meshes[product.Name.split()[1]] = (np.asarray(shape.geometry.verts).reshape(-1, 3),
                                           np.asarray(shape.geometry.faces).reshape(-1, 3))
    return meshes


def test_ifc_window_rerendered_covers_void(ifc, outputs):
    for name, (V, F) in _iterated_meshes(ifc, "IfcWindow").items():
        px = pinhole(camera_points(outputs[1], V))
        render = np.zeros((IMG_H, IMG_W), dtype=np.uint8)
        for tri in F:
            cv2.fillPoly(render, [np.round(px[tri] * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
        gt = quad_mask(gt_quad(int(name)))
        iou = (gt & render.astype(bool)).sum() / (gt | render.astype(bool)).sum()
        assert iou >= 0.95, (name, iou)


def test_ifc_wall_has_void_cut_and_photo_texture(ifc, outputs):
    paths, manifest = outputs
    # The iterated wall is the holed fragment: void + 1 m margin, 0.30 m thick behind the 0.01 m photo
    # cladding (an IfcCovering), minus the void box.
    for name, (V, F) in _iterated_meshes(ifc, "IfcWall").items():
        i = int(name)
        k = (1.0 if i == 0 else 1.3) / VOIDS[i][3]
        x0, y0, w, h = VOIDS[i]
        cam = camera_points(manifest, V)
        facade = ((cam / k - T_F) @ R_F)  # back to the true facade frame (R_F orthonormal)
        assert facade[:, 0].min() == pytest.approx(x0 - 1.0 / k, abs=1e-6)
        assert facade[:, 2].min() == pytest.approx(-0.31 / k, abs=1e-6)
        assert facade[:, 2].max() == pytest.approx(-0.01 / k, abs=1e-6)
        tri_area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
        front = np.all(np.abs(facade[F][:, :, 2] + 0.01 / k) < 1e-6, axis=1)
        assert tri_area[front].sum() == pytest.approx((w + 2 / k) * (h + 2 / k) * k * k - w * h * k * k, rel=1e-6)
    styles = ifc.by_type("IfcSurfaceStyleWithTextures")
    assert len(styles) == 1 and styles[0].Textures[0].URLReference == "texture.png"
    assert (paths["ifc"].parent / "texture.png").is_file()


def test_ifc_texture_coordinates_reproduce_projection(ifc, outputs):
    paths, manifest = outputs
    tex = manifest["texture"]
    texture = read_rgb(paths["texture"])
    assert texture.shape[:2] == (tex["height"], tex["width"])
    maps = ifc.by_type("IfcIndexedTriangleTextureMap")
    assert len(maps) == 2
    checked = 0
    for m in maps:
        faceset = m.MappedTo
        wall = next(p for p in ifc.by_type("IfcCovering")  # the photo cladding carries the texture
                    if faceset in p.Representation.Representations[0].Items)
        M = ifcopenshell.util.placement.get_local_placement(wall.ObjectPlacement)
        local = np.asarray(faceset.Coordinates.CoordList)
        uv = np.asarray(m.TexCoords.TexCoordsList)
        assert uv.min() >= 0.0 and uv.max() <= 1.0
        for tri_xyz, tri_uv in zip(faceset.CoordIndex, m.TexCoordIndex):
            for a, b in zip(tri_xyz, tri_uv):
                p = local[a - 1]
                if abs(p[2]) > 1e-9:
                    continue  # only the exterior face is seen in the photo
                world = M[:3, :3] @ p + M[:3, 3]
                expected = pinhole(camera_points(manifest, world))[0]
                s, t = uv[b - 1]
                got = np.array([s * tex["width"] - 0.5 - tex["pad_left"],
                                (1 - t) * tex["height"] - 0.5 - tex["pad_top"]])
                assert np.abs(got - expected).max() < 1e-3
                checked += 1
    assert checked >= 2 * 6  # at least the two exterior-face triangles of each wall
    # The texture's photo region is the inpainted photo.
    inpainted = read_rgb(paths["inpainted"])
    crop = texture[tex["pad_top"]:tex["pad_top"] + IMG_H, tex["pad_left"]:tex["pad_left"] + IMG_W]
    assert np.array_equal(crop, inpainted)


def test_inpainting_fills_every_void_and_keeps_the_rest(outputs, photo):
    inpainted = read_rgb(outputs[0]["inpainted"])
    far = ~cv2.dilate(np.any([quad_mask(gt_quad(i)) for i in range(3)], axis=0).astype(np.uint8),
                      np.ones((31, 31), np.uint8)).astype(bool)
    assert np.array_equal(inpainted[far], photo[far])
    wall_level = np.median(photo[far].astype(float), axis=0)
    for i in range(3):  # the failed window's void is inpainted too
        inside = cv2.erode(quad_mask(gt_quad(i)).astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
        before = np.abs(photo[inside].astype(float).mean(axis=0) - wall_level).max()
        after = np.abs(inpainted[inside].astype(float).mean(axis=0) - wall_level).max()
        assert after < 0.3 * before, (i, before, after)


def test_a_huge_photo_is_inpainted_and_textured_at_the_capped_size(tmp_path, photo):
    """Issue #37 item 9: with ``max_px`` 400 the 640 x 480 photo's padded texture (wider than 400
    px) is made at the reduced size: texture.png at most 400 px along its longer side, inpainted.png
    and substituted.png the reduced photo; the IFC's texture coordinates still land on this test's
    own projection of each wall vertex (mapped to the reduced photo by the pixel-centre rule,
    u' = (u + 0.5) W' / W - 0.5), and every void is still filled."""
    full = json.loads(write_outputs(tmp_path / "full", photo, K, all_results())["manifest"].read_text())
    assert max(full["texture"]["width"], full["texture"]["height"]) > 400  # the cap has work to do
    paths = write_outputs(tmp_path / "cap", photo, K, all_results(), substitute="two-by-two-mullion", max_px=400)
    tex = json.loads(paths["manifest"].read_text())["texture"]
    texture, inpainted = read_rgb(paths["texture"]), read_rgb(paths["inpainted"])
    assert max(texture.shape[:2]) <= 400 and texture.shape[:2] == (tex["height"], tex["width"])
    w, h = tex["photo_width"], tex["photo_height"]
    assert inpainted.shape[:2] == (h, w) == read_rgb(paths["substituted"]).shape[:2]
    assert w < IMG_W and abs(w / IMG_W - h / IMG_H) < 2 / IMG_H and tex["scale"] == pytest.approx(w / IMG_W)
    assert np.array_equal(texture[tex["pad_top"]:tex["pad_top"] + h, tex["pad_left"]:tex["pad_left"] + w], inpainted)
    sx, sy = w / IMG_W, h / IMG_H
    ifc_model = ifcopenshell.open(str(paths["ifc"]))
    manifest = json.loads(paths["manifest"].read_text())
    checked = 0
    for m in ifc_model.by_type("IfcIndexedTriangleTextureMap"):
        wall = next(p for p in ifc_model.by_type("IfcCovering")  # the photo cladding carries the texture
                    if m.MappedTo in p.Representation.Representations[0].Items)
        M = ifcopenshell.util.placement.get_local_placement(wall.ObjectPlacement)
        local, uv = np.asarray(m.MappedTo.Coordinates.CoordList), np.asarray(m.TexCoords.TexCoordsList)
        for tri_xyz, tri_uv in zip(m.MappedTo.CoordIndex, m.TexCoordIndex):
            for a, b in zip(tri_xyz, tri_uv):
                if abs(local[a - 1][2]) > 1e-9:
                    continue
                u, v = pinhole(camera_points(manifest, M[:3, :3] @ local[a - 1] + M[:3, 3]))[0]
                s, t = uv[b - 1]
                got = np.array([s * tex["width"] - 0.5 - tex["pad_left"], (1 - t) * tex["height"] - 0.5 - tex["pad_top"]])
                assert np.abs(got - [(u + 0.5) * sx - 0.5, (v + 0.5) * sy - 0.5]).max() < 1e-3
                checked += 1
    assert checked >= 2 * 6
    small = cv2.resize(photo, (w, h), interpolation=cv2.INTER_AREA)
    voids = [cv2.fillPoly(np.zeros((h, w), np.uint8), [np.round(((gt_quad(i) + 0.5) * [sx, sy] - 0.5) * 16)
                                                         .astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
             for i in range(3)]
    far = ~cv2.dilate(np.any(voids, axis=0).astype(np.uint8), np.ones((15, 15), np.uint8)).astype(bool)
    wall_level = np.median(small[far].astype(float), axis=0)
    for i, void in enumerate(voids):  # the failed window's void too
        inside = cv2.erode(void, np.ones((5, 5), np.uint8)).astype(bool)
        before = np.abs(small[inside].astype(float).mean(axis=0) - wall_level).max()
        after = np.abs(inpainted[inside].astype(float).mean(axis=0) - wall_level).max()
        assert inside.sum() > 100 and after < 0.3 * before, (i, before, after)


def test_obj_and_glb_reload_with_trimesh(outputs):
    paths, _ = outputs
    counts = {}
    for key in ("obj", "glb"):
        scene = trimesh.load(str(paths[key]), force="scene")
        meshes = list(scene.geometry.values())
        walls = [m for m in meshes if m.visual.kind == "texture" and getattr(m.visual, "uv", None) is not None
                 and len(m.visual.uv)]
        counts[key] = sum(len(m.vertices) for m in walls)
        # two gridded, holed wall fragments: more than the 16 corners each, far fewer than a dense scan
        assert 2 * 16 < counts[key] < 2 * 5000, key
        for m in walls:
            assert m.visual.uv.min() >= 0.0 and m.visual.uv.max() <= 1.0
            image = getattr(m.visual.material, "baseColorTexture", None) or getattr(m.visual.material, "image", None)
            assert image is not None and image.size == (IMG_W, IMG_H), key  # the texture came along
        windows = [m for m in meshes if all(m is not x for x in walls)]
        # 2 windows of style two-by-two-mullion: 4 frame + 2 bar + 1 glass boxes, 8 corners each
        # (trimesh's OBJ loader merges the corners that neighbouring frame boxes share)
        n_window = sum(len(m.vertices) for m in windows)
        assert n_window == 2 * 7 * 8 if key == "glb" else 2 * 8 < n_window <= 2 * 7 * 8, (key, n_window)
        lo, hi = np.min([m.bounds[0] for m in meshes], axis=0), np.max([m.bounds[1] for m in meshes], axis=0)
        assert np.all(np.isfinite(lo)) and np.all(hi - lo < 20.0)
    assert counts["obj"] == counts["glb"]
    # Each GLB wall is a closed solid: (outline - void) x 0.31 m (0.30 m wall + 0.01 m photo cladding), at
    # the scale its pose was solved with.
    scene = trimesh.load(str(paths["glb"]), force="scene")
    for i, height_m in ((0, 1.0), (1, 1.3)):
        wall = scene.geometry[f"wall_{i}"]
        k = height_m / VOIDS[i][3]
        w, h = VOIDS[i][2] * k, VOIDS[i][3] * k
        assert wall.is_watertight
        assert wall.volume == pytest.approx(((w + 2) * (h + 2) - w * h) * 0.31, rel=1e-6)


def test_glb_and_obj_agree_on_wall_uvs(outputs):
    """glTF stores v downwards; after trimesh's reload both formats must map each vertex alike."""
    rows = {}
    for key in ("obj", "glb"):
        scene = trimesh.load(str(outputs[0][key]), force="scene")
        walls = [m for m in scene.dump() if m.visual.kind == "texture" and getattr(m.visual, "uv", None) is not None
                 and len(m.visual.uv)]
        to_y_up = np.eye(3) if key == "glb" else Z_TO_Y_UP  # the GLB's root node turned its world y-up
        r = np.round(np.concatenate([np.column_stack([m.vertices @ to_y_up.T, m.visual.uv]) for m in walls]), 4)
        rows[key] = r[np.lexsort(r.T[::-1])]
    assert rows["obj"].shape == rows["glb"].shape
    assert np.abs(rows["obj"] - rows["glb"]).max() < 1e-3


def test_obj_wall_uvs_reproduce_projection(outputs):
    paths, manifest = outputs
    tex = manifest["texture"]
    lines = paths["obj"].read_text().splitlines()
    V = np.array([list(map(float, line.split()[1:])) for line in lines if line.startswith("v ")])
    VT = np.array([list(map(float, line.split()[1:])) for line in lines if line.startswith("vt ")])
    pairs = {tuple(map(int, c.split("/"))) for line in lines if line.startswith("f ") and "/" in line
             for c in line.split()[1:]}
    errs = []
    for vi, ti in pairs:
        cam = camera_points(manifest, V[vi - 1])[0]
        expected = pinhole(cam[None])[0]
        s, t = VT[ti - 1]
        got = np.array([s * tex["width"] - 0.5 - tex["pad_left"], (1 - t) * tex["height"] - 0.5 - tex["pad_top"]])
        # exterior-face vertices only: those whose facade depth is 0 (checked against the true facade)
        for i, k in ((0, 1.0 / VOIDS[0][3]), (1, 1.0)):
            facade = (cam / k - T_F) @ R_F
            if abs(facade[2]) < 1e-5 and VOIDS[i][0] - 1 / k - 1e-5 <= facade[0] <= VOIDS[i][0] + VOIDS[i][2] + 1 / k + 1e-5:
                errs.append(np.abs(got - expected).max())
                break
    assert len(errs) >= 16 and max(errs) < 0.01  # OBJ stores 6 decimals


def _far_from_windows(margin_px: float) -> np.ndarray:
    """Pixels farther than margin_px from the good voids and the failed one, outside the legend."""
    near = np.zeros((IMG_H, IMG_W), dtype=np.uint8)
    for i in range(3):
        near |= quad_mask(gt_quad(i)).astype(np.uint8)
    dist = cv2.distanceTransform(1 - near, cv2.DIST_L2, 5)
    far = dist > margin_px
    far[:120, :260] = False  # legend
    return far


def test_overlay_draws_on_the_windows_only(outputs, photo):
    overlay = read_rgb(outputs[0]["overlay"])  # the photo, then the side panel on its right
    assert overlay.shape[0] >= photo.shape[0] and overlay.shape[1] > photo.shape[1]
    overlay = overlay[:photo.shape[0], :photo.shape[1]]
    for i in range(3):
        edge = quad_mask(gt_quad(i)) & ~cv2.erode(quad_mask(gt_quad(i)).astype(np.uint8),
                                                 np.ones((5, 5), np.uint8)).astype(bool)
        assert np.mean(np.any(overlay[edge] != photo[edge], axis=1)) > 0.5, i
    far = _far_from_windows(120.0)
    assert far.sum() > 0.2 * far.size
    assert np.array_equal(overlay[far], photo[far])


def test_substitution_renders_into_void(outputs, photo):
    sub = read_rgb(outputs[0]["substituted"])
    inpainted = read_rgb(outputs[0]["inpainted"])
    assert sub.shape == photo.shape
    for i in (0, 1):
        inside = cv2.erode(quad_mask(gt_quad(i)).astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
        changed = np.any(np.abs(sub.astype(int) - inpainted.astype(int)) > 3, axis=2)
        assert changed[inside].mean() > 0.95, i
        # The new frame is white: the void's border ring becomes bright.
        ring = inside & ~cv2.erode(inside.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
        assert sub[ring].mean() > 180
    far = _far_from_windows(10.0)
    assert np.array_equal(sub[far], photo[far])
    # the failed window (2) is inpainted but gets no substituted window
    inside2 = cv2.erode(quad_mask(gt_quad(2)).astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    assert np.array_equal(sub[inside2], inpainted[inside2])


def test_substitute_single_window_matches_silhouette(photo):
    r = window_result(1, 1.3)
    gt = quad_mask(gt_quad(1))
    # Over the untouched photo the changed pixels are exactly the rendered window's silhouette.
    changed = np.any(substitute(photo, K, r, "dark-frame", background=photo) != photo, axis=2)
    iou = (changed & gt).sum() / (changed | gt).sum()
    assert iou > 0.95, iou
    # Default: the void is inpainted first, so only the void and a few px around it change.
    changed = np.any(substitute(photo, K, r, "dark-frame") != photo, axis=2)
    assert changed[gt].mean() > 0.95
    near = cv2.dilate(gt.astype(np.uint8), np.ones((15, 15), np.uint8)).astype(bool)
    assert not changed[~near].any()
    with pytest.raises(PipelineError, match="solvePnP"):
        substitute(photo, K, all_results()[2], "dark-frame")
    with pytest.raises(ValueError, match="no-such-style"):
        substitute(photo, K, r, "no-such-style")


@pytest.mark.parametrize("name", sorted(CATALOGUE))
def test_catalogue_geometry_fills_the_void(name):
    w, h = 1.1, 1.4
    mesh = window_mesh(name, w, h)
    style = CATALOGUE[name]
    assert np.allclose(mesh.vertices.min(axis=0), [0, 0, -style.frame_depth_m])
    assert np.allclose(mesh.vertices.max(axis=0), [w, h, 0])
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    parts = tm.split(only_watertight=False)
    assert all(p.is_watertight and p.volume > 0 for p in parts)  # closed boxes, outward normals
    assert set(mesh.part) == {"frame", "glass"}
    n_boxes = 4 + style.mullions + style.transoms + 1
    assert len(mesh.faces) == 12 * n_boxes


def test_bad_inputs_raise_clear_errors(tmp_path, photo):
    with pytest.raises(ValueError, match="too small"):
        window_mesh("sash-cross", 0.1, 1.0, fit=False)
    with pytest.raises(ValueError, match="positive"):
        window_mesh("sash-cross", -1.0, 1.0)
    with pytest.raises(PipelineError, match="shape"):
        write_outputs(tmp_path, photo[:, :, :2], K, [])
    with pytest.raises(ValueError, match="K"):
        write_outputs(tmp_path, photo, np.eye(2), [])
    with pytest.raises(ValueError, match="no-such-style"):
        write_outputs(tmp_path, photo, K, [], substitute="no-such-style")
    # No usable window at all: still a valid (empty) model, every window reported.
    paths = write_outputs(tmp_path / "none", photo, K, all_results()[2:], substitute="sash-cross")
    skipped = {e["index"]: e["reason"] for e in json.loads(paths["manifest"].read_text())["skipped"]}
    assert set(skipped) == {2, 3, 4}
    assert "glb" not in paths and paths["substituted"].is_file()
    assert len(ifcopenshell.open(str(paths["ifc"])).by_type("IfcWindow")) == 0


def test_a_void_smaller_than_the_style_exports_with_the_style_scaled(tmp_path, photo):
    """A 5 x 100 cm void is too small for sash-cross's 8 cm frame: the style is scaled down so its
    frame and bars take half the width; the window exports, its frame inside the void."""
    from fenestra.pipeline.catalogue import fitted_style  # noqa: PLC0415

    s = fitted_style("sash-cross", 0.05, 1.0)
    assert 2 * s.frame_width_m + s.mullions * s.bar_width_m == pytest.approx(0.025)
    mesh = window_mesh("sash-cross", 0.05, 1.0)
    assert np.allclose(mesh.vertices[:, :2].min(axis=0), 0) and np.allclose(mesh.vertices[:, :2].max(axis=0), [0.05, 1.0])
    tiny = WindowResult(5, 0.5, None, None, 0.05, "general", None, R_F, T_F, 1.0, None, None)
    paths = write_outputs(tmp_path, photo, K, [tiny], substitute="sash-cross")
    manifest = json.loads(paths["manifest"].read_text())
    assert [e["index"] for e in manifest["exported"]] == [5] and manifest["exported"][0]["style_scaled"]
    assert len(ifcopenshell.open(str(paths["ifc"])).by_type("IfcWindow")) == 1


def test_texture_is_padded_when_the_wall_leaves_the_photo(tmp_path, photo):
    """Zoomed in 2.5x: the 1 m wall margin projects outside the photo; the texture grows instead of
    clipping, so every wall vertex's UV still reproduces its projection and lies in [0, 1]."""
    K_zoom = K.copy()
    K_zoom[0, 0] *= 2.5
    K_zoom[1, 1] *= 2.5
    x0, y0, w, h = VOIDS[0]
    q = pinhole(void_corners_facade(*VOIDS[0]) @ R_F.T + T_F, K_zoom)
    r = WindowResult(0, 0.9, q, q, w / h, "general", None, R_F, T_F + R_F @ [x0, y0, 0.0], h, q, None)
    paths = write_outputs(tmp_path, photo, K_zoom, [r])
    manifest = json.loads(paths["manifest"].read_text())
    tex = manifest["texture"]
    assert tex["pad_left"] + tex["pad_right"] + tex["pad_top"] + tex["pad_bottom"] > 0
    texture = read_rgb(paths["texture"])
    assert texture.shape[:2] == (tex["height"], tex["width"])
    lines = paths["obj"].read_text().splitlines()
    V = np.array([list(map(float, line.split()[1:])) for line in lines if line.startswith("v ")])
    VT = np.array([list(map(float, line.split()[1:])) for line in lines if line.startswith("vt ")])
    assert VT.min() >= 0.0 and VT.max() <= 1.0
    pairs = {tuple(map(int, c.split("/"))) for line in lines if line.startswith("f ") and "/" in line
             for c in line.split()[1:]}
    corners = []
    for vi, ti in pairs:
        cam = camera_points(manifest, V[vi - 1])[0]
        facade = (cam - T_F) @ R_F
        if abs(facade[2]) > 1e-5:
            continue
        s_, t_ = VT[ti - 1]
        got = np.array([s_ * tex["width"] - 0.5 - tex["pad_left"], (1 - t_) * tex["height"] - 0.5 - tex["pad_top"]])
        expected = pinhole(cam[None], K_zoom)[0]
        assert np.abs(got - expected).max() < 0.01
        corners.append(expected)
    corners = np.array(corners)
    outside = (corners[:, 0] < -0.5) | (corners[:, 0] > IMG_W - 0.5) | (corners[:, 1] < -0.5) | (corners[:, 1] > IMG_H - 0.5)
    assert outside.any()  # the case under test really happens


def test_glb_rerendered_from_the_photo_camera_reproduces_the_photo(outputs):
    """End to end: render model.glb with pyrender from the photo's camera (at the export origin).

    Every wall pixel must show the inpainted photo at the same place: phase correlation of 64 px
    crops of the render against the photo finds no shift (< 0.1 px). This catches UV conventions
    (v flip, half-pixel) and the affine-vs-projective texture interpolation error a coarse wall
    mesh would have (several px on this slanted view).
    """
    from fenestra.compat import import_pyrender
    from fenestra.conventions import CV_TO_GL, PYRENDER_PIXEL_OFFSET

    pyrender = import_pyrender()
    paths, manifest = outputs
    scene = pyrender.Scene.from_trimesh_scene(trimesh.load(str(paths["glb"]), force="scene"),
                                              bg_color=[0, 0, 0, 0], ambient_light=[1, 1, 1])
    camera = pyrender.IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2] + PYRENDER_PIXEL_OFFSET,
                                       K[1, 2] + PYRENDER_PIXEL_OFFSET, znear=0.05, zfar=100.0)
    pose = np.eye(4)
    # camera frame axes in the GLB's (y-up) world, GL style
    pose[:3, :3] = Z_TO_Y_UP @ export_to_camera(manifest).T @ CV_TO_GL
    pose[:3, 3] = Z_TO_Y_UP @ export_offset(manifest)  # the camera stands above the export origin
    scene.add(camera, pose=pose)
    renderer = pyrender.OffscreenRenderer(IMG_W, IMG_H)
    try:
        colour, depth = renderer.render(scene, flags=pyrender.RenderFlags.FLAT)
    finally:
        renderer.delete()
    render = cv2.cvtColor(np.ascontiguousarray(colour[:, :, ::-1]), cv2.COLOR_BGR2GRAY).astype(np.float64)
    photo_in = cv2.cvtColor(cv2.imread(str(paths["inpainted"])), cv2.COLOR_BGR2GRAY).astype(np.float64)
    wall = cv2.erode((depth > 0).astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    wall &= _far_from_windows(6.0) | (np.arange(IMG_H)[:, None] < 120)  # legend rows are fine here
    hann = cv2.createHanningWindow((64, 64), cv2.CV_64F)
    for y0, x0 in ((80, 170), (80, 330), (320, 170), (320, 330)):
        ys, xs = slice(y0, y0 + 64), slice(x0, x0 + 64)
        assert wall[ys, xs].all(), (y0, x0)  # the crop is plain textured wall
        (dx, dy), response = cv2.phaseCorrelate(render[ys, xs], photo_in[ys, xs], window=hann)
        assert response > 0.9 and np.hypot(dx, dy) < 0.1, (y0, x0, dx, dy, response)


@pytest.mark.parametrize("hole", [False, True])
def test_wall_mesh_is_a_closed_gridded_slab(hole):
    from fenestra.pipeline.export.geometry import place, void_hole, wall_mesh

    pw = place(window_result(1, 1.3))
    V, F = wall_mesh(pw, [void_hole(pw)], cut=hole)
    tm = trimesh.Trimesh(V, F, process=False)
    assert tm.is_watertight and tm.is_winding_consistent
    w, h = VOIDS[1][2], VOIDS[1][3]
    expected = ((w + 2) * (h + 2) - (w * h if hole else 0.0)) * 0.30
    assert tm.volume == pytest.approx(expected, rel=1e-9)  # positive: normals point outward
    front = V[np.abs(V[:, 2]) < 1e-12]
    for x in (0.0, w):  # the void's edges are grid lines (clean booleans, exact reveals)
        assert np.isclose(front[:, 0], x).sum() >= 3
    assert 16 < len(V) < 2 * 65 * 65


@pytest.mark.parametrize("holes, open_area", [
    ([(0.0, 0.0, 1.0, 1.5), (2.0, 0.2, 3.2, 1.0)], 1.5 + 1.2 * 0.8),  # two windows of one wall
    ([(0.0, 0.0, 1.0, 1.5), (0.5, 1.0, 2.0, 2.0)], 1.5 + 1.5 - 0.25),  # overlapping voids: their union
    ([(0.0, 0.0, 1.0, 1.0), (1.0, 0.0, 2.0, 1.0)], 2.0),  # touching voids
])
def test_a_fitted_wall_is_one_closed_slab_with_every_void(holes, open_area):
    """OBJ/GLB: a fitted wall is one solid with a hole per window (as model.ifc's IfcWall with its
    openings): watertight, outward normals, volume (outline - union of voids) x thickness, every
    void edge a grid line (areas computed by hand above, not by the mesher)."""
    from fenestra.pipeline.export.geometry import PlacedWindow, wall_mesh

    wall = PlacedWindow(7, 3.2, 2.0, np.eye(3), np.array([0.0, 0.0, 8.0]))
    V, F = wall_mesh(wall, holes, margin_m=0.5, thickness_m=0.3)
    tm = trimesh.Trimesh(V, F, process=False)
    assert tm.is_watertight and tm.is_winding_consistent
    assert tm.volume == pytest.approx(((3.2 + 1.0) * (2.0 + 1.0) - open_area) * 0.3, rel=1e-9)
    front = V[np.abs(V[:, 2]) < 1e-12]
    for x0, y0, x1, y1 in holes:
        for x in (x0, x1):
            assert np.isclose(front[:, 0], x).sum() >= 2
        for y in (y0, y1):
            assert np.isclose(front[:, 1], y).sum() >= 2


def test_glb_texture_is_at_most_8192_px_and_keeps_its_uvs(tmp_path):
    """A GLB's texture is area-downscaled to GLB_MAX_TEXTURE_PX along its longer side (viewers refuse
    larger ones); the texture coordinates are fractions, so they are unchanged."""
    from fenestra.pipeline.export.mesh import GLB_MAX_TEXTURE_PX, MeshPart, write_glb

    tex = np.zeros((16, 2 * GLB_MAX_TEXTURE_PX, 3), np.uint8)
    tex[:, GLB_MAX_TEXTURE_PX:] = 200  # right half bright: its mean survives an area resize
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    part = MeshPart("wall_0", "photo", np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0]]), np.array([[0, 1, 2]]), uv)
    path = write_glb(tmp_path / "m.glb", [part], tex)
    mesh = next(iter(trimesh.load(str(path), force="scene").geometry.values()))
    image = np.asarray(mesh.visual.material.baseColorTexture)
    assert image.shape[:2] == (8, GLB_MAX_TEXTURE_PX)
    assert image[..., :3].mean() == pytest.approx(100.0, abs=0.5)
    assert np.allclose(mesh.visual.uv, uv, atol=1e-6)


def _glb_json(path) -> dict:
    """The JSON chunk of a binary glTF, parsed here (header, then chunk 0: length, type 'JSON')."""
    data = path.read_bytes()
    assert data[:4] == b"glTF"
    length = int.from_bytes(data[12:16], "little")
    assert data[16:20] == b"JSON"
    return json.loads(data[20:20 + length])


def _rect_axes(V: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A slab's (normal, side a, side b), unit (3,) each: the normal is its thinnest principal axis;
    the sides are those of the smallest rectangle (cv2.minAreaRect) around its vertices in that plane."""
    c = V - V.mean(axis=0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    e1, e2, n = vt
    xy = np.column_stack([c @ e1, c @ e2]).astype(np.float32)
    (_, _), (_, _), ang = cv2.minAreaRect(xy)
    a = np.radians(ang)
    return n, np.cos(a) * e1 + np.sin(a) * e2, -np.sin(a) * e1 + np.cos(a) * e2


def _up_error_deg(V: np.ndarray, up: np.ndarray) -> float:
    """How far (deg) a wall slab (vertices (N, 3)) is from standing along ``up``: the angle between
    ``up`` and the nearer of its rectangle's side directions."""
    _, a, b = _rect_axes(V)
    cos = max(abs(a @ up), abs(b @ up))
    return float(np.degrees(np.arccos(np.clip(cos, 0.0, 1.0))))


def test_export_world_is_upright_with_the_facade_vertical(outputs):
    """The camera looks slightly down at the façade (R_F): the export world's z is the façade's up
    (R_F's y axis, the truth here), the camera's heading is +y, and the rotation is proper."""
    _, manifest = outputs
    M = np.asarray(manifest["world_frame"]["camera_to_export"])
    assert np.allclose(M @ M.T, np.eye(3), atol=1e-12) and np.linalg.det(M) == pytest.approx(1.0)
    assert np.allclose(M @ (R_F @ np.array([0.0, 1.0, 0.0])), [0, 0, 1], atol=1e-9)
    heading = M @ np.array([0.0, 0.0, 1.0])
    assert abs(heading[0]) < 1e-12 and heading[1] > 0.9
    g = manifest["world_frame"]["gravity"]
    assert g["windows"] == 2 and "up axes" in g["source"] and g["tilt_deg"] > 1.0  # the camera is not level


def test_glb_root_node_turns_the_model_y_up(outputs):
    """glTF is y-up: the GLB's one root node holds (x, y, z) -> (x, z, -y) (column-major, read from
    the file's JSON), and a viewer's world (trimesh applies the node) has each wall standing on +y."""
    paths, _ = outputs
    gltf = _glb_json(paths["glb"])
    roots = gltf["scenes"][gltf.get("scene", 0)]["nodes"]
    assert len(roots) == 1
    node, M = gltf["nodes"][roots[0]], np.eye(4)
    while len(node.get("children", [])) == 1:  # trimesh's "world" node, then ours: the transforms compose
        M = M @ np.asarray(node.get("matrix", np.eye(4).ravel()), dtype=np.float64).reshape(4, 4).T  # column-major
        node = gltf["nodes"][node["children"][0]]
    M = M @ np.asarray(node.get("matrix", np.eye(4).ravel()), dtype=np.float64).reshape(4, 4).T
    assert np.allclose(M[:3, :3], Z_TO_Y_UP) and np.allclose(M[:3, 3], 0)
    parts = [n for n in gltf["nodes"] if "mesh" in n]
    assert len(node["children"]) == len(parts) and all("matrix" not in n for n in parts)  # every part under it
    meshes = trimesh.load(str(paths["glb"]), force="scene").dump(concatenate=False)
    walls = [m for m in meshes if m.visual.kind == "texture" and getattr(m.visual, "uv", None) is not None
             and len(m.visual.uv)]
    assert len(walls) == 2
    for m in walls:
        assert _up_error_deg(m.vertices, np.array([0.0, 1.0, 0.0])) < 1e-3
        n, _, _ = _rect_axes(m.vertices)
        assert abs(n[1]) < 1e-5  # vertical: its normal is horizontal


def _tilted_two_wall_results(noise_px: float = 0.5, seed: int = 3):
    """A building corner (front wall z = 0 facing +z, side wall x = 0 facing +x; world y up) seen by
    a camera pitched up ~22 deg and rolled 4 deg: window quads with corner noise, fitted by the real
    per-wall strategy ('wall', K known), then pipeline.facade_model. Returns (K, results, walls,
    true up in the camera frame, image shape)."""
    from fenestra.conventions import project  # noqa: PLC0415
    from fenestra.pipeline import walls as wallpkg  # noqa: PLC0415
    from fenestra.pipeline.facade_model import Known, facade_model  # noqa: PLC0415

    shape = (960, 1280)
    Kt = np.array([[1000.0, 0, 639.5], [0, 1000.0, 479.5], [0, 0, 1]])
    R0, t0 = look_at([11.0, 1.6, 15.0], [3.5, 7.5, 3.5], up=(0.0, 1.0, 0.0))
    roll = np.radians(4.0)
    Rz = np.array([[np.cos(roll), -np.sin(roll), 0], [np.sin(roll), np.cos(roll), 0], [0, 0, 1.0]])
    R_cam, t_cam = Rz @ R0, Rz @ t0  # world -> camera, rolled about the optical axis
    side = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # side wall frame: x along world -z, facing +x
    rng = np.random.default_rng(seed)
    quads, truth = [], []
    for R_f, xs in ((np.eye(3), (1.0, 3.2, 5.4)), (side, (-7.0, -4.8, -2.6))):
        for x0 in xs:
            for y0 in (1.0, 4.2, 7.4):
                R = R_cam @ R_f
                t = R_cam @ (R_f @ np.array([x0, y0, 0.0])) + t_cam
                q = project(Kt, R, t, np.array([[0, 1.6, 0], [1.2, 1.6, 0], [1.2, 0, 0], [0, 0, 0]], dtype=float))
                quads.append(q + rng.normal(0.0, noise_px, q.shape))
    base = [WindowResult(i, 1.0, q, q, None, "general", None, None, None, 1.0, None, None) for i, q in enumerate(quads)]
    fitted = wallpkg.apply_walls(base, Kt, shape, 1.0, None, wallpkg.WallParams())
    assert all(r.failure is None for r in fitted)
    results, model = facade_model(fitted, Known(window_height_m=1.6))
    assert len(model.walls) == 2 and not model.flags
    walls = {k: w.id for w in model.walls for k in w.members}
    return Kt, results, walls, R_cam @ np.array([0.0, 1.0, 0.0]), shape


def test_a_tilted_camera_gives_vertical_walls(tmp_path):
    """Issue 35: the model came out in the camera frame, walls leaning by the camera's tilt. With a
    camera pitched ~22 deg and rolled 4 deg (true gravity known), gravity from the fitted walls'
    up axes makes every wall vertical within 1 deg in model.ifc (z up), model.obj (z up) and
    model.glb (y up, read back); the camera-level frame (gravity=False) leaves them leaning."""
    Kt, results, walls, up_true, (H, W) = _tilted_two_wall_results()
    photo = np.full((H, W, 3), 128, np.uint8)
    paths = write_outputs(tmp_path / "up", photo, Kt, results, walls=walls)
    manifest = json.loads(paths["manifest"].read_text())
    up_est = np.asarray(manifest["world_frame"]["gravity"]["up_camera"])
    assert np.degrees(np.arccos(np.clip(up_est @ up_true, -1, 1))) < 1.0
    assert manifest["world_frame"]["gravity"]["windows"] == 18
    meshes = trimesh.load(str(paths["glb"]), force="scene").dump(concatenate=False)
    glb_walls = [m for m in meshes if m.visual.kind == "texture" and getattr(m.visual, "uv", None) is not None
                 and len(m.visual.uv)]
    assert len(glb_walls) == 2
    for m in glb_walls:
        assert _up_error_deg(m.vertices, np.array([0.0, 1.0, 0.0])) < 1.0
    f = ifcopenshell.open(str(paths["ifc"]))
    for wall in f.by_type("IfcWall"):
        M = ifcopenshell.util.placement.get_local_placement(wall.ObjectPlacement)
        lean = np.degrees(np.arccos(np.clip(M[2, 2], -1, 1)))  # the wall placement's z (its up) against world z
        assert lean < 1.0, (wall.Name, lean)
    level = write_outputs(tmp_path / "level", photo, Kt, results, walls=walls, gravity=False)
    meshes = trimesh.load(str(level["glb"]), force="scene").dump(concatenate=False)
    leans = [_up_error_deg(m.vertices, np.array([0.0, 1.0, 0.0])) for m in meshes
             if m.visual.kind == "texture" and getattr(m.visual, "uv", None) is not None and len(m.visual.uv)]
    assert min(leans) > 10.0  # the test can fail: without gravity the walls lean by the camera's tilt


def test_gravity_argument_and_fallbacks():
    """gravity_up: walls vote (the larger agreeing set wins over a lone wall whose axes are off);
    a winner over GRAVITY_MAX_TILT_DEG falls back to the camera level; bad values are one-line errors."""
    from fenestra.pipeline.export import export_gravity  # noqa: PLC0415
    from fenestra.pipeline.export.geometry import CAMERA_TO_EXPORT, PlacedWindow, camera_to_world, gravity_up  # noqa: PLC0415

    def pw(i, R):
        return PlacedWindow(i, 1.0, 1.5, R, np.array([0.0, 0.0, 10.0]))

    def rot_x(deg):
        a = np.radians(deg)
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    level = np.diag([1.0, -1.0, -1.0])  # window frame y up = camera -y, facing the camera
    placed = [pw(i, rot_x(10.0) @ level) for i in range(3)] + [pw(3, rot_x(40.0) @ level)]
    g = gravity_up(placed, {0: 0, 1: 0, 2: 0, 3: 1})
    assert g.windows == 3 and g.tilt_deg == pytest.approx(10.0, abs=1e-9)
    M = camera_to_world(g.up)
    assert np.allclose(M @ g.up, [0, 0, 1])
    assert np.allclose(camera_to_world(np.array([0.0, -1.0, 0.0])), CAMERA_TO_EXPORT)
    lying = gravity_up([pw(0, rot_x(75.0) @ level)])
    assert lying.up is None and "75 deg" in lying.source
    assert gravity_up([]).up is None
    with pytest.raises(ValueError, match=r"gravity must be .* got \[0, 0, 0\]"):
        export_gravity(placed, None, [0, 0, 0])


def _grid_results(n: int, detail: str = "too small a window here, a long reason to wrap") -> list[WindowResult]:
    """n failed windows on a 640 x 480 photo, ten per row, the first row touching the top edge."""
    out = []
    for i in range(n):
        x, y = 20 + (i % 10) * 60, (i // 10) * 75
        q = np.array([[x, y], [x + 40, y], [x + 40, y + 60], [x, y + 60]], dtype=np.float64)
        out.append(WindowResult(i, 0.9, q, q, None, None, None, None, None, 1.0, None, Failure("quad", "too_small", detail)))
    return out


@pytest.mark.parametrize("n", [3, 25, 60])
def test_overlay_panel_stays_within_the_photo_height_with_every_entry(n):
    """Issue 35: with more than ~20 windows the panel ran past the photo. Now the overlay is the
    photo's height; every window's entry is laid out once, inside the panel, entries not overlapping."""
    from fenestra.pipeline.export.overlay import MIN_PANEL_SCALE, draw_overlay, panel_layout  # noqa: PLC0415

    photo = np.full((480, 640, 3), 128, np.uint8)
    results = _grid_results(n)
    img = draw_overlay(photo, K, results, header=["K: prior", "scale: assumed"])
    assert img.shape[0] == 480 and np.array_equal(img[:, :640], draw_overlay(photo, K, results)[:, :640])
    width = max(360, int(0.4 * 640))
    scale, n_cols, columns = panel_layout(480, width, results, {}, ["K: prior", "scale: assumed"], 0.4)
    assert img.shape[1] == 640 + n_cols * width
    firsts = [(x, y, t) for col in columns for x, y, t, _ in col if t.startswith("#")]
    assert sorted(int(t.split()[0][1:]) for _, _, t in firsts) == list(range(n))
    placed = [(x, y) for col in columns for x, y, _, _ in col]
    assert len(placed) == len(set(placed)) and all(0 <= x < n_cols * width and 0 < y <= 480 for x, y in placed)
    if n == 3:
        assert n_cols == 1 and scale == 0.4  # a short list keeps the font and one column
    if n == 60:
        assert n_cols >= 2 and scale == MIN_PANEL_SCALE


def test_overlay_labels_at_the_top_edge_are_not_clipped():
    """A window touching the top edge: its number is drawn inside the photo (it was drawn above it)."""
    from fenestra.pipeline.export.overlay import COLOURS, draw_overlay  # noqa: PLC0415

    photo = np.full((480, 640, 3), 128, np.uint8)
    img = draw_overlay(photo, K, _grid_results(1))[:, :640]
    (w, h), _ = cv2.getTextSize("#0", cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
    label = img[3:h + 4, 23:18 + w + 4].astype(int)  # inside the quad's top and left edges (red too)
    red = np.abs(label - COLOURS["failed"]).sum(axis=2) < 120
    dark = np.abs(label - 20).sum(axis=2) < 30
    assert red.sum() > 10  # the glyphs, inside the photo
    assert dark.any(axis=1).sum() >= h - 2  # on their dark box, its whole height inside the photo
