"""Pin the conventions of fenestra/conventions.py with hand-checked geometry."""
import numpy as np

from fenestra import conventions as C


def test_look_at_axes_follow_opencv():
    # Camera 5 m south of a wall point, looking north (+y); world z is up.
    R, t = C.look_at(eye=[0.0, -5.0, 1.0], target=[0.0, 0.0, 1.0])
    K = C.make_K(500.0, 500.0, 320.0, 240.0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(R), 1.0)
    centre, right, up = C.project(K, R, t, [[0, 0, 1], [1, 0, 1], [0, 0, 2]])
    np.testing.assert_allclose(centre, [320.0, 240.0], atol=1e-9)
    # 1 m to the right at 5 m depth with f = 500 px -> +100 px in u; 1 m up -> -100 px in v.
    np.testing.assert_allclose(right, [420.0, 240.0], atol=1e-9)
    np.testing.assert_allclose(up, [320.0, 140.0], atol=1e-9)
    assert np.isclose(C.camera_depths(R, t, [[0, 0, 1]])[0], 5.0)


def test_roll_turns_content_clockwise():
    R, t = C.look_at([0, -5, 1], [0, 0, 1], roll_deg=90.0)
    K = C.make_K(500.0, 500.0, 320.0, 240.0)
    # A point to the right of the target moves to below the centre after a 90 deg clockwise turn.
    np.testing.assert_allclose(C.project(K, R, t, [[1, 0, 1]])[0], [320.0, 340.0], atol=1e-9)


def test_cv_to_gl_pose_is_camera_to_world_with_flipped_axes():
    R, t = C.look_at([2.0, -4.0, 1.5], [0.0, 0.0, 1.0])
    T = C.cv_to_gl_pose(R, t)
    np.testing.assert_allclose(T[:3, 3], [2.0, -4.0, 1.5], atol=1e-12)  # camera centre
    forward_gl = -T[:3, 2]  # OpenGL cameras look down -z
    np.testing.assert_allclose(forward_gl, R[2], atol=1e-12)
    up_gl = T[:3, 1]
    np.testing.assert_allclose(up_gl, -R[1], atol=1e-12)


def test_K_from_fov_centre_and_focal():
    K = C.K_from_fov(640, 480, 90.0)
    assert np.isclose(K[0, 0], 320.0) and np.isclose(K[1, 1], 320.0)
    np.testing.assert_allclose(K[:2, 2], [319.5, 239.5])


def test_rotation_error_deg():
    a = np.radians(30.0)
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    assert np.isclose(C.rotation_error_deg(Rz, np.eye(3)), 30.0)
    assert C.rotation_error_deg(np.eye(3), np.eye(3)) == 0.0


def test_window_frame_corner_order_matches_image_order():
    """DESIGN.md / conventions: image TL, TR, BR, BL are the window-frame corners (0, h), (w, h),
    (w, 0), (0, 0) (x along the wall, y up, z outward), seen from outside."""
    from fenestra.conventions import CORNER_NAMES, make_K, project
    from fenestra.pipeline.pose import object_points

    assert CORNER_NAMES == ("TL", "TR", "BR", "BL")
    w, h = 2.0, 1.0
    obj = object_points(w, h)
    np.testing.assert_array_equal(obj[:, :2], [[0, h], [w, h], [w, 0], [0, 0]])
    # seen from outside, square on: window x -> camera x, window y (up) -> camera -y, z (outward) -> -z
    R, t = np.diag([1.0, -1.0, -1.0]), np.array([-1.0, 0.5, 5.0])
    px = project(make_K(500.0, 500.0, 320.0, 240.0), R, t, obj)
    (tl, tr, br, bl) = px
    assert tl[0] < tr[0] and bl[0] < br[0]  # left before right
    assert tl[1] < bl[1] and tr[1] < br[1]  # top above bottom (image y down)
    assert tl[1] == tr[1] and tl[0] == bl[0]
