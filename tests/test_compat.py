"""pyrender through fenestra.compat: NumPy 2 alias, EGL, and torch usable after GL in one process."""
import subprocess
import sys


def test_pyrender_then_torch_optimizer_in_one_process():
    # A child process, because the failure mode is a segfault of the whole interpreter.
    code = (
        "from fenestra.compat import import_pyrender\n"
        "pr = import_pyrender()\n"
        "r = pr.OffscreenRenderer(32, 24)\n"
        "import numpy as np, torch\n"
        "p = torch.nn.Parameter(torch.ones(3))\n"
        "opt = torch.optim.AdamW([p], lr=0.1)\n"
        "(p ** 2).sum().backward(); opt.step()\n"
        "s = pr.Scene(); s.add(pr.Mesh.from_points(np.zeros((1, 3)))); print(s.bounds.shape)\n"
        "r.delete(); print('ok', float(p[0]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "(2, 3)" in out.stdout  # Scene.bounds works under NumPy 2 (np.infty alias)
    # First AdamW step by hand: p*(1 - lr*wd) - lr * m_hat/sqrt(v_hat) = 1*(1 - 0.1*0.01) - 0.1
    value = float(out.stdout.split("ok ")[1])
    assert abs(value - 0.899) < 1e-5


def _pyrender_coverage(offset: float):
    """Render a tilted flat white rectangle with pyrender's IntrinsicsCamera (cx, cy + offset).

    Returns (coverage (H, W) in [0, 1] (pyrender renders with 4x MSAA), exact polygon (4, 2) px).
    """
    import numpy as np

    from fenestra.compat import import_pyrender
    from fenestra.conventions import cv_to_gl_pose, look_at, make_K, project

    pyrender = import_pyrender()
    W, H = 160, 120
    K = make_K(150.0, 150.0, 79.5, 59.5)
    corners = np.array([[-0.8, 0.0, 0.5], [0.7, 0.0, 0.62], [0.75, 0.0, -0.4], [-0.7, 0.0, -0.55]])
    R, t = look_at(eye=[0.6, -3.0, 0.3], target=[0.0, 0.0, 0.0])
    mesh = pyrender.Mesh([pyrender.Primitive(positions=corners.astype(np.float32),
                                             indices=np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                                             mode=4, color_0=np.ones((4, 4), np.float32))])
    scene = pyrender.Scene(bg_color=[0, 0, 0, 0], ambient_light=[1, 1, 1])
    scene.add(mesh)
    cam = pyrender.IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2] + offset, K[1, 2] + offset,
                                    znear=0.05, zfar=50.0)
    scene.add(cam, pose=cv_to_gl_pose(R, t))
    r = pyrender.OffscreenRenderer(W, H)
    try:
        flags = pyrender.RenderFlags.FLAT | pyrender.RenderFlags.SKIP_CULL_FACES
        color, _ = r.render(scene, flags=flags)
    finally:
        r.delete()
    return color[..., 0].astype(np.float64) / 255.0, project(K, R, t, corners)


def _polygon_area_centroid(P):
    """Shoelace area (px^2) and centroid (2,) of a simple polygon P (N, 2)."""
    import numpy as np

    x, y = P[:, 0], P[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    A = cross.sum() / 2.0
    cx = ((x + np.roll(x, -1)) * cross).sum() / (6.0 * A)
    cy = ((y + np.roll(y, -1)) * cross).sum() / (6.0 * A)
    return abs(A), np.array([cx, cy])


def test_pyrender_intrinsics_camera_needs_half_pixel_offset():
    """pyrender's IntrinsicsCamera puts pixel centres at half-integers: cx+0.5, cy+0.5 fixes it.

    Ground truth: the exact area and centroid of the projected rectangle (shoelace formula, OpenCV
    pixel-centre convention), independent of any renderer; the render's coverage-weighted centroid
    must land on it.
    """
    import numpy as np

    cov, poly = _pyrender_coverage(offset=0.5)
    area, centroid = _polygon_area_centroid(poly)
    v, u = np.mgrid[0:cov.shape[0], 0:cov.shape[1]]
    got = np.array([(cov * u).sum(), (cov * v).sum()]) / cov.sum()
    assert abs(cov.sum() - area) / area < 0.005
    assert np.linalg.norm(got - centroid) < 0.05, (got, centroid)
    cov0, _ = _pyrender_coverage(offset=0.0)
    got0 = np.array([(cov0 * u).sum(), (cov0 * v).sum()]) / cov0.sum()
    np.testing.assert_allclose(got0 - centroid, [-0.5, -0.5], atol=0.05)  # the quirk itself
