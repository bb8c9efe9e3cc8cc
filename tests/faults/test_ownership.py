"""File ownership and atomic output: nothing of the user's is replaced or deleted (issue 37: 1-3, 10).

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from fenestra.bench import manifest

from fault_helpers import (EXAMPLE, TINY_PROFILE, _photo, _reconstruct, fenestra, one_line_error, reconstruct)


def test_reconstruct_replaces_its_output_whole(tmp_path):
    assert reconstruct("o", cwd=tmp_path).returncode == 0
    umask = os.umask(0o022)
    os.umask(umask)
    assert (tmp_path / "o").stat().st_mode & 0o777 == 0o777 & ~umask  # a normal folder, not mkdtemp's 0700
    manifest = tmp_path / "o" / ".fenestra-output.json"
    written = json.loads(manifest.read_text())["files"]
    for name, digest in written.items():  # every file listed with its digest, computed here independently
        assert hashlib.sha256((tmp_path / "o" / name).read_bytes()).hexdigest() == digest, name
    assert "windows.json" in written and sorted(written) == sorted(
        str(p.relative_to(tmp_path / "o")) for p in (tmp_path / "o").rglob("*") if p.is_file() and p != manifest)
    (tmp_path / "o" / "model.glb.old").write_text("stale")  # as if an older version had written it
    manifest.write_text(json.dumps({"format": 2, "files": {**written, "model.glb.old": hashlib.sha256(b"stale").hexdigest()}}))
    (tmp_path / "o" / "notes.txt").write_text("the user's")  # not Fenestra's: never removed
    first = (tmp_path / "o" / "windows.json").read_bytes()
    # a failing export (disk full at 50 kB: texture.png is larger) leaves the complete first set
    r = reconstruct("o", cwd=tmp_path, limit_bytes=50_000)
    one_line_error(r)
    assert (tmp_path / "o" / "windows.json").read_bytes() == first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]  # no temporary folder beside it
    assert not list((tmp_path / "o").glob(".fenestra-stage-*"))  # nor inside it
    assert reconstruct("o", cwd=tmp_path).returncode == 0
    assert not (tmp_path / "o" / "model.glb.old").exists()  # nothing stale beside the new set
    assert (tmp_path / "o" / "notes.txt").read_text() == "the user's"


def test_reconstruct_refuses_bad_out(tmp_path):
    (tmp_path / "file").write_text("x")
    one_line_error(reconstruct("file", cwd=tmp_path), "existing file")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("x")
    one_line_error(reconstruct("mine", cwd=tmp_path), "not empty", "--force")
    assert reconstruct("mine", "--force", cwd=tmp_path).returncode == 0  # writes beside the user's files
    assert (tmp_path / "mine" / "thesis.tex").read_text() == "x" and (tmp_path / "mine" / "windows.json").is_file()
    one_line_error(reconstruct("x" * 300, cwd=tmp_path), "File name too long")


def test_reconstruct_force_never_deletes_an_input(tmp_path):
    (tmp_path / "o").mkdir()
    photo = tmp_path / "o" / "img017.jpg"
    shutil.copy(EXAMPLE / "img017.jpg", photo)
    for extra in ((), ("--force",)):
        one_line_error(reconstruct("o", *extra, cwd=tmp_path, photo=photo), "--out o holds the input", "img017.jpg")
    one_line_error(reconstruct(".", "--force", cwd=tmp_path / "o", photo="img017.jpg", K=EXAMPLE / "K.json"),
                   "holds the input img017.jpg")
    assert photo.read_bytes() == (EXAMPLE / "img017.jpg").read_bytes()
    shutil.copy(EXAMPLE / "K.json", tmp_path / "o" / "K.json")  # K inside the output folder: refused too
    one_line_error(reconstruct("o", "--force", cwd=tmp_path, K=tmp_path / "o" / "K.json"), "holds the input")


def snapshot(root: Path) -> dict[str, str]:
    """{relative path: sha256} of every file under root (symlinks as their target's name)."""
    return {str(p.relative_to(root)): (os.readlink(p) if p.is_symlink() else hashlib.sha256(p.read_bytes()).hexdigest())
            for p in sorted(root.rglob("*")) if p.is_file() or p.is_symlink()}


def _file(rel: str, text: str = "the user's"):
    def make(d: Path) -> None:
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_text(text)
    return make


def _with(*makers):
    """A builder: run each maker on the folder, then return the command line of the last one."""
    def build(d: Path) -> list:
        args = None
        for m in makers:
            args = m(d) or args
        return args
    return build


def _yolo_data(rel: str):
    def make(d: Path) -> None:
        _photo(d / rel / "images" / "a.png")
        (d / rel / "labels").mkdir(parents=True)
        (d / rel / "labels" / "a.txt").write_text("0 0.5 0.5 0.2 0.2\n")
    return make


def _bench_real(data: str, out: str, *extra: str):
    return lambda d: ["bench", "--profile", "real", "--data", data, "--format", "yolo", "--out", out, "--no-report",
                      *extra]


def _photos(rel: str, n: int = 2):
    def make(d: Path) -> None:
        for i in range(n):
            _photo(d / rel / f"p{i}.png")
    return make


def _earlier_output(out: str, edit: str):
    """A reconstruct output made by Fenestra in ``out``, then ``edit`` (one of its files) changed by the user."""
    def make(d: Path) -> None:
        r = fenestra(*_reconstruct(out)(d), cwd=d)
        assert r.returncode == 0, r.stderr[-2000:]
        (d / out / edit).write_bytes(b"edited by the user")
    return make


# (case, builder -> command line, needles of the one error line): each is refused up front, and
# every file in the folder is byte for byte as before the command (nothing added, nothing removed)
OWNERSHIP = [
    ("bench --force with --out the --data folder", _with(_yolo_data("ds"), _bench_real("ds", "ds", "--force")),
     ["--out ds is the input folder ds"]),
    ("bench --force with --out the parent of --data", _with(_yolo_data("work/ds"), _file("work/thesis.tex"),
                                                           _bench_real("work/ds", "work", "--force")),
     ["--out work holds the input work/ds"]),
    ("bench --force with --out inside --data", _with(_yolo_data("ds"), _file("ds/run/notes.txt"),
                                                    _bench_real("ds", "ds/run", "--force")),
     ["--out ds/run lies inside the input folder ds"]),
    ("bench --force into a folder of the user's", _with(_yolo_data("ds"), _file("mine/thesis.tex"),
                                                       _bench_real("ds", "mine", "--force")),
     ["mine is not empty", "thesis.tex", "--force replaces only a run Fenestra wrote"]),
    ("bench --force with --out holding the render cache", _with(_file("out/renders/x/view.json", "{}"), _file("tiny.toml", TINY_PROFILE),
                                                               lambda d: ["bench", "--profile", "tiny.toml", "--out", "out",
                                                                          "--force", "--no-report"]),
     ["--out out holds the input out/renders"]),
    ("reconstruct --force over the user's model.ifc", _with(_file("o/model.ifc"), _file("o/texture.png"),
                                                           _reconstruct("o", "--force")),
     ["would replace", "model.ifc", "texture.png", "which Fenestra did not write"]),
    ("reconstruct into a folder with the user's windows.json", _with(_file("o/windows.json", "{}"), _file("o/overlay.png"),
                                                                    _reconstruct("o")),
     ["--out o is not empty", "overlay.png, windows.json", "holds no Fenestra output"]),
    ("reconstruct over an output file the user edited", _with(_earlier_output("o", "overlay.png"), _reconstruct("o")),
     ["--out o: would replace overlay.png, which Fenestra did not write (or which changed since)"]),
    ("batch with --out the photo folder", _with(_photos("photos"), _file("photos/summary.json", "[1]"),
                                               lambda d: ["reconstruct", "photos", "--out", "photos", "--K", EXAMPLE / "K.json"]),
     ["--out photos is the input folder photos"]),
    ("batch with --out inside the photo folder", _with(_photos("photos"), lambda d: ["reconstruct", "photos", "--out",
                                                                                      "photos/o", "--K", EXAMPLE / "K.json"]),
     ["--out photos/o lies inside the input folder photos"]),
    ("batch --force over the user's summary.json", _with(_photos("photos"), _file("o/summary.json", "[1]"),
                                                        lambda d: ["reconstruct", "photos", "--out", "o", "--force",
                                                                   "--K", EXAMPLE / "K.json"]),
     ["would replace summary.json, which Fenestra did not write"]),
]


@pytest.mark.parametrize("case, build, needles", OWNERSHIP, ids=[c for c, _, _ in OWNERSHIP])
def test_nothing_of_the_users_is_replaced_or_deleted(case, build, needles, tmp_path):
    args = build(tmp_path)
    before = snapshot(tmp_path)
    one_line_error(fenestra(*args, cwd=tmp_path, timeout=300), *needles)
    assert snapshot(tmp_path) == before


@pytest.fixture
def other_device_dir(tmp_path):
    """An empty folder on another filesystem than tmp_path: under /dev/shm (a tmpfs on Linux, no
    privilege needed), else a tmpfs mounted here (root). Skipped, with why, only where neither
    exists: the cross-device rename cannot be provoked on a machine with one filesystem."""
    import tempfile

    if Path("/dev/shm").is_dir() and os.stat("/dev/shm").st_dev != os.stat(tmp_path).st_dev:
        d = Path(tempfile.mkdtemp(prefix="fenestra-xdev-", dir="/dev/shm"))
        try:
            yield d
        finally:
            shutil.rmtree(d, ignore_errors=True)  # the test's own folder
        return
    d = tmp_path / "mnt"
    d.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64m", "tmpfs", str(d)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"no second filesystem: /dev/shm is missing or on tmp's device, and mount refused ({r.stderr!r})")
    try:
        yield d
    finally:
        subprocess.run(["umount", str(d)], check=True)


def test_output_on_another_filesystem(tmp_path, other_device_dir):
    """--out on another device than the working folder: staged inside it, so the final renames
    stay on one device; a second run replaces the first whole."""
    out = other_device_dir / "out"
    assert os.stat(other_device_dir).st_dev != os.stat(tmp_path).st_dev
    for _ in range(2):
        r = fenestra(*_reconstruct(str(out))(tmp_path), cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-2000:]
    assert json.loads((out / "windows.json").read_text())["windows"]
    assert not list(out.glob(".fenestra-stage-*")) and [p for p in tmp_path.iterdir() if p != other_device_dir] == []


def test_concurrent_bench_runs_into_one_folder_are_refused_up_front(tmp_path):
    """While one run holds the folder, a second is refused at once, naming the lock, and changes nothing."""
    (tmp_path / "tiny.toml").write_text(TINY_PROFILE)
    with manifest.claimed(tmp_path / "run", "tiny", "0123abcd"):
        before = snapshot(tmp_path)
        one_line_error(fenestra("bench", "--profile", "tiny.toml", "--out", "run", "--no-report", cwd=tmp_path),
                       "another benchmark run is writing into this folder")
        assert snapshot(tmp_path) == before


@pytest.fixture
def read_only_dir(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    if os.geteuid() != 0:
        d.chmod(0o555)
        yield d
        d.chmod(0o755)
        return
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(d)], capture_output=True)
    if r.returncode != 0:
        # root ignores permission bits, so only a read-only filesystem makes --out unwritable; a
        # container that forbids mount(2) cannot provide one (CI runs as root with mount allowed)
        pytest.skip(f"root cannot make an unwritable folder here: mount -t tmpfs -o ro refused ({r.stderr!r})")
    try:
        yield d
    finally:
        subprocess.run(["umount", str(d)], check=True)


def test_read_only_output_folders(read_only_dir, tmp_path):
    one_line_error(reconstruct(read_only_dir / "out", cwd=tmp_path), "ro/")
    (tmp_path / "tiny.toml").write_text(TINY_PROFILE)
    one_line_error(fenestra("bench", "--profile", "tiny.toml", "--out", read_only_dir / "run", cwd=tmp_path), "ro/run")
