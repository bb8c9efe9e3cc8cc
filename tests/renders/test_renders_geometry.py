"""renders/: camera conventions, distortion, exact instance maps and occlusion against
ground truth computed independently (matplotlib point-in-polygon, shoelace areas)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from fenestra.conventions import look_at, project
from fenestra.tolerances import TOL
from fenestra.renders.camera import Camera, distort_image
from wall_scenes import Opening, box, wall_scene
from fenestra.scenes.model import ElementMesh, Scene


def _expected_mask(poly_px: np.ndarray, W: int, H: int) -> np.ndarray:
    """Pixel centres inside a polygon, by matplotlib (independent of renders/)."""
    uu, vv = np.meshgrid(np.arange(W), np.arange(H))
    return MplPath(poly_px).contains_points(np.c_[uu.ravel(), vv.ravel()]).reshape(H, W)


def _oblique_camera(W=320, H=240, dist=None) -> Camera:
    R, t = look_at([0.2, -4.5, 2.6], [1.6, 0.0, 1.7], roll_deg=8.0)
    return Camera.from_fov(W, H, 62.0, R, t, dist)


# ------------------------------------------------------------------------------------- camera
def test_camera_rejects_bad_values():
    R, t = np.eye(3), np.zeros(3)
    with pytest.raises(ValueError, match="R must be"):
        Camera.from_fov(64, 48, 60, np.diag([1.0, 1.0, -1.0]), t)
    with pytest.raises(ValueError, match="dist must have"):
        Camera.from_fov(64, 48, 60, R, t, dist=(0.1, 0.2, 0.3))
    with pytest.raises(ValueError, match="image size"):
        Camera(np.eye(3) * [100, 100, 1], 0, 48, R, t)


def test_distortion_round_trip_of_gt_corners():
    scene = wall_scene()
    cam = _oblique_camera(dist=(-0.25, 0.08, 0.001, -0.0005, 0.0))
    for w in scene.windows:
        distorted = cam.project(w.corners_world)
        pinhole = project(cam.K, cam.R, cam.t, w.corners_world)
        assert np.abs(distorted - pinhole).max() > 0.1  # the distortion does something
        assert np.abs(cam.undistort_px(distorted) - pinhole).max() < TOL.distortion_roundtrip_px


def test_distortion_maps_are_the_inverse_of_projection():
    cam = _oblique_camera(dist=(-0.3, 0.1, 0.0, 0.0, 0.0))
    mx, my = cam.canvas_maps()
    canvas = cam.canvas()
    off = canvas.K[:2, 2] - cam.K[:2, 2]
    pick = np.array([[0, 0], [319, 0], [319, 239], [17, 200], [160, 120]])
    src = np.c_[mx[pick[:, 1], pick[:, 0]], my[pick[:, 1], pick[:, 0]]] - off
    assert np.abs(cam.distort_px(src) - pick).max() < 1e-2  # float32 maps
    # barrel distortion sees more than the pinhole image: the canvas is larger
    assert canvas.width > cam.width and canvas.height > cam.height


# ------------------------------------------------------------------------------------- raster
@pytest.fixture(scope="module")
def gl():
    from fenestra.renders.raster import OccluderPass  # noqa: F401  (imports pyrender via fenestra.compat)

    return OccluderPass


def test_gl_pass_pixel_convention_matches_projection(gl):
    """pyrender's occluder pass vs pixel-centre point-in-polygon of projected corners."""
    quad = np.array([[0.3, 0.0, 2.6], [2.9, 0.0, 2.6], [2.9, 0.0, 0.9], [0.3, 0.0, 0.9]])
    plate = ElementMesh("p", "IfcPlate", "plate", quad, np.array([[0, 1, 2], [0, 2, 3]]), (1, 1, 1, 1))
    base = box([-50, -50, -10.0], [50, 50, -9.9])  # far below the view: keeps ground out of frame
    floor = ElementMesh("f", "IfcSlab", "f", np.asarray(base.vertices), np.asarray(base.faces), (1, 1, 1, 1))
    scene = Scene("plate", "<synthetic>", "IFC4", "0" * 64, (plate, floor), ())
    cam = _oblique_camera()
    occ = gl(scene)
    try:
        depth, code = occ.render(cam)
    finally:
        occ.close()
    px = project(cam.K, cam.R, cam.t, quad)
    expected = _expected_mask(px, cam.width, cam.height)
    got = (depth > 0) & (depth < 8)  # the plate; the ground is > 15 m away
    perimeter = np.linalg.norm(px - np.roll(px, 1, axis=0), axis=1).sum()
    mismatch = int((got != expected).sum())
    # a 0.5 px convention error would flip ~0.5 * perimeter pixels; allow pixels on the edges only
    assert mismatch <= TOL.projection_vs_mask_px * perimeter, (mismatch, perimeter)
    # and the rendered depth is the camera z of the plane
    Xc = quad @ cam.R.T + cam.t
    assert np.isclose(depth[expected & got].min(), Xc[:, 2].min(), atol=0.05)


def test_instance_map_of_unoccluded_window_matches_projected_corners():
    from fenestra.renders.raster import RasterRenderer

    scene = wall_scene()
    cam = _oblique_camera()
    with RasterRenderer(scene) as r:
        out = r.render(cam)
    for i, w in enumerate(scene.windows):
        px = project(cam.K, cam.R, cam.t, w.corners_world)
        expected = _expected_mask(px, cam.width, cam.height)
        got = out.instances == i + 1
        assert expected.sum() > 500
        assert int((got != expected).sum()) <= 2
        # mask area and centroid against the exact polygon (shoelace): edge offset << 0.1 px
        x, y = px[:, 0], px[:, 1]
        x1, y1 = np.roll(x, -1), np.roll(y, -1)
        cross = x * y1 - x1 * y
        area = cross.sum() / 2
        cx, cy = ((x + x1) * cross).sum() / (6 * area), ((y + y1) * cross).sum() / (6 * area)
        vv, uu = np.nonzero(got)
        assert abs(uu.mean() - cx) < TOL.projection_vs_mask_px and abs(vv.mean() - cy) < TOL.projection_vs_mask_px
        assert out.windows[i].visible_fraction > 0.97
        assert all(out.windows[i].corner_visible)
        np.testing.assert_allclose(out.windows[i].corners_px, px, atol=1e-9)


def test_sill_in_front_of_void_hides_its_pixels():
    """A box flush with the wall, 0.3 m above the void's lower edge, hides exactly that strip."""
    from fenestra.renders.raster import RasterRenderer

    o = Opening(1.0, 2.2, 1.0, 2.4)
    top = o.z0 + 0.3
    scene = wall_scene(openings=(o,), sill_top=top)
    cam = _oblique_camera()
    with RasterRenderer(scene) as r:
        out = r.render(cam)
    visible_world = np.array([[o.x0, 0, o.z1], [o.x1, 0, o.z1], [o.x1, 0, top], [o.x0, 0, top]])
    full = _expected_mask(project(cam.K, cam.R, cam.t, scene.windows[0].corners_world), cam.width, cam.height)
    px = project(cam.K, cam.R, cam.t, visible_world)
    expected = _expected_mask(px, cam.width, cam.height)
    got = out.instances == 1
    edge_len = np.linalg.norm(px[2] - px[3])
    assert (full & ~expected).sum() > 0.15 * full.sum()  # the sill hides a real strip
    assert int((got != expected).sum()) <= TOL.projection_vs_mask_px * edge_len + 2
    w = out.windows[0]
    assert w.corner_visible == (True, True, False, False)
    assert abs(w.visible_fraction - expected.sum() / full.sum()) < 0.02
    # the window's own frame and glass (recessed inside the hole) never hide its void
    assert not (full & expected & ~got).any()


def test_distorted_render_keeps_masks_and_corners_consistent():
    from fenestra.renders.raster import RasterRenderer

    scene = wall_scene()
    cam = _oblique_camera(dist=(-0.2, 0.05, 0.0, 0.0, 0.0))
    with RasterRenderer(scene) as r:
        out = r.render(cam)
        pin = r.render(Camera(cam.K, cam.width, cam.height, cam.R, cam.t))
    assert out.rgb.shape == (240, 320, 3) and out.instances.shape == (240, 320)
    # expected: undistort every pixel centre with OpenCV, test it against the pinhole polygon
    uu, vv = np.meshgrid(np.arange(320.0), np.arange(240.0))
    und = cv2.undistortPoints(np.c_[uu.ravel(), vv.ravel()].reshape(-1, 1, 2), cam.K, np.array(cam.dist),
                              None, None, cam.K, (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    und = und.reshape(-1, 2)
    for i, w in enumerate(out.windows):
        pin_px = project(cam.K, cam.R, cam.t, w.corners_world)
        expected = MplPath(pin_px).contains_points(und).reshape(240, 320)
        got = out.instances == i + 1
        perimeter = np.linalg.norm(w.corners_px - np.roll(w.corners_px, 1, axis=0), axis=1).sum()
        assert expected.sum() > 500
        assert int((got != expected).sum()) <= TOL.projection_vs_mask_px * perimeter
        np.testing.assert_allclose(w.corners_px, cam.distort_px(pin_px), atol=1e-6)
        assert np.abs(w.corners_px - pin.windows[i].corners_px).max() > 0.1
    # instance map of a camera without distortion is untouched by the remap code
    assert distort_image(Camera(cam.K, 320, 240, cam.R, cam.t), pin.instances, nearest=True) is pin.instances
