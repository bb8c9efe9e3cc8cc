"""fenestra.checks: each check passes a good value through as its documented array and names the
caller's value and the problem in a ValueError otherwise."""
import numpy as np
import pytest

from fenestra import checks
from fenestra.errors import PipelineError


@pytest.mark.parametrize("bad, word", [
    (np.eye(2), "3x3"),
    (np.array([[np.nan, 0, 1], [0, 1, 1], [0, 0, 1]]), "non-finite"),
    (np.array([[-5.0, 0, 1], [0, 5, 1], [0, 0, 1]]), "positive"),
    (np.array([[5.0, 0, 1], [0, 5, 1], [0, 1, 1]]), "last row"),
])
def test_check_K_names_the_problem(bad, word):
    with pytest.raises(ValueError, match=f"K_photo .*{word}|K_photo {word}"):
        checks.check_K(bad, "K_photo")


def test_check_K_passes_float64():
    K = checks.check_K([[500, 0, 320], [0, 500, 240], [0, 0, 1]])
    assert K.dtype == np.float64 and K.shape == (3, 3)


@pytest.mark.parametrize("bad, word", [(np.zeros((3, 2)), r"shape \(4, 2\)"),
                                       (np.array([[0, 0], [1, 0], [1, np.inf], [0, 1]]), "non-finite")])
def test_check_quad_names_the_problem(bad, word):
    with pytest.raises(ValueError, match=f"quad_gt .*{word}"):
        checks.check_quad(bad, "quad_gt")


def test_check_rotation():
    a = np.radians(40.0)
    R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    np.testing.assert_array_equal(checks.check_rotation(R), R)
    with pytest.raises(ValueError, match=r"R_est is not a rotation matrix .*det = -1.0000"):
        checks.check_rotation(np.diag([1.0, 1.0, -1.0]), "R_est")  # a reflection
    with pytest.raises(ValueError, match="R_gt is not a rotation"):
        checks.check_rotation(1.01 * R, "R_gt")
    with pytest.raises(ValueError, match=r"R must have shape \(3, 3\)"):
        checks.check_rotation(np.eye(4))
    with pytest.raises(ValueError, match="non-finite"):
        checks.check_rotation(np.full((3, 3), np.nan))


def test_check_instances():
    m = np.array([[0, 3], [65535, 0]], np.uint16)
    out = checks.check_instances(m, (2, 2, 3))
    assert out.dtype == np.int32 and out.tolist() == [[0, 3], [65535, 0]]
    for bad, word in [(None, "got None"), (np.zeros((2, 2, 1), int), r"\(H, W\)"),
                      (np.zeros((2, 2), float), "integer"), (np.array([[0, -1]]), "min -1"),
                      (np.array([[0, 2**31]], np.int64), "<= 2147483647")]:
        with pytest.raises(ValueError, match=f"instances .*{word}"):
            checks.check_instances(bad)
    with pytest.raises(ValueError, match=r"does not match image shape \(3, 2\)"):
        checks.check_instances(m, (3, 2, 3))


def test_check_image():
    img = np.zeros((8, 9, 3), np.uint8)
    assert checks.check_image(img) is img
    for bad, word in [(np.zeros((8, 9), np.uint8), r"\(H, W, 3\) RGB"), (np.zeros((8, 9, 3), float), "uint8"),
                      (np.zeros((7, 9, 3), np.uint8), "too small: 9x7 px")]:
        with pytest.raises(checks.ImageError, match=f"photo .*{word}") as e:
            checks.check_image(bad, "photo")
        assert isinstance(e.value, PipelineError) and isinstance(e.value, ValueError)


def test_allclose_is_numpys_on_finite_arrays():
    """The checks' _allclose answers as np.allclose on finite values, at and around its tolerances."""
    rng = np.random.default_rng(0)
    b = np.array([0.0, 0.0, 1.0])
    for step in (0.0, 1e-9, 1e-8, 1.0000001e-8, 1e-5, 1.001e-5, 1.0001e-5, 1e-3):
        for a in (b + step, b - step, b + step * rng.normal(size=3)):
            assert checks._allclose(a, b) == np.allclose(a, b)
            assert checks._allclose(a, b, atol=1e-6) == np.allclose(a, b, atol=1e-6)
    for _ in range(200):
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0] * (1.0 + rng.choice([0.0, 1e-7, 1e-6, 1e-5]))
        assert checks._allclose(R @ R.T, np.eye(3), atol=1e-6) == np.allclose(R @ R.T, np.eye(3), atol=1e-6)


def test_det3_has_the_sign_of_numpys_determinant():
    rng = np.random.default_rng(1)
    for _ in range(200):
        M = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        for m in (M, M + rng.normal(0.0, 1e-7, (3, 3)), rng.normal(size=(3, 3))):
            assert checks._det3(m) == pytest.approx(np.linalg.det(m), abs=1e-12)
            assert (checks._det3(m) < 0) == (np.linalg.det(m) < 0)
