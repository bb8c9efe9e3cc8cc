"""fenestra.images, the one reader: any file name, EXIF orientation applied, RGB uint8 images,
int32 instance maps, and errors that name the file."""
import os

import cv2
import numpy as np
import pytest
from PIL import Image

from fenestra.errors import DatasetError, FenestraError
from fenestra.images import read_image, read_instances


def test_odd_file_names_read_like_any_other(tmp_path):
    """A non-UTF-8 name (bytes 0xff 0xfe: a surrogate-escaped str in Python), spaces and non-ASCII
    letters: the bytes are read by Python, decoded by cv2 from the buffer."""
    rgb = np.zeros((12, 16, 3), np.uint8)
    rgb[..., 0] = 200  # red
    ok, png = cv2.imencode(".png", rgb[..., ::-1])
    inst = np.array([[0, 1], [65535, 7]], np.uint16)
    ok2, ipng = cv2.imencode(".png", inst)
    assert ok and ok2
    for name in (os.fsdecode(b"photo \xff\xfe.png"), "façade été 1.png"):
        p = tmp_path / name
        p.write_bytes(png.tobytes())
        out = read_image(p)
        assert out.dtype == np.uint8 and out.shape == (12, 16, 3)
        np.testing.assert_array_equal(out, rgb)
        m = tmp_path / ("m " + name)
        m.write_bytes(ipng.tobytes())
        got = read_instances(m, (2, 2))
        assert got.dtype == np.int32 and got.tolist() == [[0, 1], [65535, 7]]


def test_exif_orientation_is_applied_as_displayed(tmp_path):
    """EXIF orientation 6 (rotate 90 deg clockwise to display): a 40x20 JPEG comes out 20x40, its
    bright left band on top, as cv2.imread gives it."""
    a = np.zeros((20, 40, 3), np.uint8)
    a[:, :10] = 255
    im = Image.fromarray(a)
    exif = im.getexif()
    exif[0x0112] = 6
    p = tmp_path / "rot.jpg"
    im.save(p, exif=exif.tobytes(), quality=95)
    out = read_image(p)
    assert out.shape == (40, 20, 3)
    assert out[:8].mean() > 200 and out[12:].mean() < 30
    np.testing.assert_array_equal(out, cv2.cvtColor(cv2.imread(str(p), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB))


def test_errors_name_the_file(tmp_path):
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "junk.jpg").write_bytes(b"not an image")
    cv2.imwrite(str(tmp_path / "rgb.png"), np.zeros((4, 4, 3), np.uint8))
    cases = [(lambda: read_image(tmp_path / "missing.jpg", "photo"), "photo not found: .*missing.jpg"),
             (lambda: read_image(tmp_path / "empty.png"), "cannot read image .*empty.png"),
             (lambda: read_image(tmp_path / "junk.jpg"), "cannot read image .*junk.jpg"),
             (lambda: read_instances(tmp_path / "rgb.png"), "rgb.png must be a single-channel 8/16-bit PNG"),
             (lambda: read_instances(tmp_path / "junk.jpg"), "cannot read instance map .*junk.jpg")]
    for call, msg in cases:
        with pytest.raises(DatasetError, match=msg) as e:
            call()
        assert isinstance(e.value, FenestraError) and isinstance(e.value, ValueError)


def test_a_truncated_jpeg_decodes_as_cv2_imread_does(tmp_path):
    """The first part of a JPEG: its missing rows grey, pixel for pixel what cv2.imread gives."""
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.integers(0, 255, (120, 160, 3), dtype=np.uint8), (7, 7), 2)
    ok, jpg = cv2.imencode(".jpg", img)
    p = tmp_path / "cut.jpg"
    p.write_bytes(jpg.tobytes()[: jpg.size // 2])
    want = cv2.cvtColor(cv2.imread(str(p), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(read_image(p), want)
    assert np.all(want[-1] == 128)  # the missing part: grey
