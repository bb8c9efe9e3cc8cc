"""fenestra.files, the one atomic writer: what it writes reads back, a failed write keeps the old
file and leaves no temporary file, and replace_dir swaps a whole folder or nothing."""
import json
import os

import numpy as np
import pytest

from fenestra import files
from fenestra.images import read_image, read_instances


def test_writers_round_trip_and_leave_no_temporary_file(tmp_path):
    files.write_bytes(tmp_path / "a.bin", b"\x00\x01")
    files.write_text(tmp_path / "b.txt", "façade\n")
    files.write_json(tmp_path / "c.json", {"k": [1, 2]})
    rgb = np.arange(8 * 9 * 3, dtype=np.uint8).reshape(8, 9, 3)
    inst = np.array([[0, 65535], [7, 0]], np.uint16)
    files.write_image(tmp_path / os.fsdecode(b"d \xff.png"), rgb)  # any file name
    files.write_image(tmp_path / "e.png", inst)
    assert (tmp_path / "a.bin").read_bytes() == b"\x00\x01"
    assert (tmp_path / "b.txt").read_text(encoding="utf-8") == "façade\n"
    assert json.loads((tmp_path / "c.json").read_text()) == {"k": [1, 2]}
    np.testing.assert_array_equal(read_image(tmp_path / os.fsdecode(b"d \xff.png")), rgb)  # RGB in, RGB out
    np.testing.assert_array_equal(read_instances(tmp_path / "e.png"), inst)
    assert len(list(tmp_path.iterdir())) == 5


def test_a_failed_write_keeps_the_old_file(tmp_path):
    p = tmp_path / "x.json"
    files.write_json(p, {"old": 1})

    def fails(tmp):
        tmp.write_text("half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match=r"cannot write .*x.json: No space left on device"):
        files.write_atomic(p, fails)
    with pytest.raises(OSError, match=r"cannot write .*x.json \(disk full"):
        files.write_atomic(p, lambda tmp: False)
    with pytest.raises(ValueError, match=r"must be \(H, W, 3\) uint8 RGB"):
        files.write_image(tmp_path / "f.png", np.zeros((4, 4, 3), np.float32))
    assert json.loads(p.read_text()) == {"old": 1} and [q.name for q in tmp_path.iterdir()] == ["x.json"]


def test_replace_dir_swaps_the_whole_folder_or_nothing(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with files.replace_dir(out) as tmp:
            (tmp / "new.txt").write_text("new")
            raise RuntimeError("mid-way")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"] and sorted(os.listdir(out)) == ["old.txt"]
    with files.replace_dir(out) as tmp:
        (tmp / "new.txt").write_text("new")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"] and sorted(os.listdir(out)) == ["new.txt"]
