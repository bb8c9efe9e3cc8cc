"""Bad input through the CLI: one error line and exit 2 (intrinsics, OS errors, odd files, a user's inputs), and Ctrl-C.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from fault_helpers import (EXAMPLE, OUTSIDE, RENDER_ARGS, ROOT, _exif6, _fifo, _photo, _reconstruct, _replace,
                           _set, _sparse, _then, bench_case, big_K, checkerboard_case, coco_case, env, fenestra,
                           gate_case, huge_image_in_dataset, huge_photo, one_line_error, pam_photo, radiance,
                           reconstruct, run_measured, run_with_status, yolo_case)


# ---------------------------------------------------------------- 5. intrinsics that don't fit the photo

def write_K(path: Path, fx=1000.0, cx=383.5, cy=511.5, **extra) -> Path:
    path.write_text(json.dumps({"K": [[fx, 0, cx], [0, fx, cy], [0, 0, 1]], **extra}))
    return path


def test_K_for_another_image_size(tmp_path):
    one_line_error(reconstruct("o", cwd=tmp_path, K=write_K(tmp_path / "a.json", width=1000, height=1000)),
                   "K is for a 1000x1000 image but the photo is 768x1024")
    # half the resolution, same aspect: rescaled (pixel centres at integers) with a warning
    r = reconstruct("o", cwd=tmp_path, K=write_K(tmp_path / "h.json", fx=500, cx=191.5, cy=255.5,
                                                 width=384, height=512))
    assert r.returncode == 0, r.stderr[-2000:]
    doc = json.loads((tmp_path / "o" / "windows.json").read_text())
    np.testing.assert_allclose(doc["K"], [[1000, 0, 383.5], [0, 1000, 511.5], [0, 0, 1]])
    assert any("rescaled by 2" in w for w in doc["warnings"]) and "rescaled by 2" in r.stderr


def test_exif_rotated_photo_with_sensor_K_is_an_error(tmp_path):
    from PIL import Image

    raw = np.full((300, 400, 3), 150, np.uint8)
    exif = Image.Exif()
    exif[0x0112] = 6  # rotate 90 deg clockwise on display: cv2 reads it 300 wide, 400 high
    Image.fromarray(raw).save(tmp_path / "p.jpg", exif=exif)
    assert cv2.imread(str(tmp_path / "p.jpg")).shape[:2] == (400, 300)
    K = write_K(tmp_path / "K.json", fx=400, cx=199.5, cy=149.5, width=400, height=300)
    one_line_error(reconstruct("o", cwd=tmp_path, photo=tmp_path / "p.jpg", masks=None, K=K),
                   "EXIF orientation 6", "give K for the upright 300x400 photo")


def test_principal_point_outside_and_absurd_fov_are_warned(tmp_path):
    K = write_K(tmp_path / "K.json", fx=1e6, cx=5000.0, cy=511.5)
    r = reconstruct("o", cwd=tmp_path, K=K)
    assert r.returncode == 0, r.stderr[-2000:]
    warnings = json.loads((tmp_path / "o" / "windows.json").read_text())["warnings"]
    assert any("principal point (5000.0, 511.5)" in w for w in warnings)
    # 2 atan(768 / 2e6) = 0.044 deg
    assert any("horizontal field of view 0.044 deg" in w for w in warnings), warnings
    assert all(f"warning: {w}" in r.stderr for w in warnings)


# ---------------------------------------------------------------- 6. OS errors and odd input

def test_truncated_jpeg_is_a_warning(tmp_path):
    data = (EXAMPLE / "img017.jpg").read_bytes()
    (tmp_path / "cut.jpg").write_bytes(data[: len(data) // 2])
    r = reconstruct("o", cwd=tmp_path, photo=tmp_path / "cut.jpg")
    assert r.returncode == 0, r.stderr[-2000:]
    warnings = json.loads((tmp_path / "o" / "windows.json").read_text())["warnings"]
    assert any("is damaged" in w and "truncated" in w for w in warnings), warnings


def test_windows_json_carries_instance_ids(tmp_path):
    inst = cv2.imread(str(EXAMPLE / "panes017.png"), cv2.IMREAD_UNCHANGED)
    assert reconstruct("o", cwd=tmp_path).returncode == 0
    wins = json.loads((tmp_path / "o" / "windows.json").read_text())["windows"]
    assert [w["instance_id"] for w in wins] == sorted(int(i) for i in np.unique(inst) if i)


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    d = tmp_path_factory.mktemp("ds")
    assert fenestra(*RENDER_ARGS, cwd=d).returncode == 0
    return next(d.glob("out/renders/*"))


def test_evaluate_detector_bad_options(small_dataset, tmp_path):
    one_line_error(fenestra("evaluate-detector", "--data", small_dataset, "--max-images", "0", cwd=tmp_path),
                   "--max-images must be >= 1, got 0")
    one_line_error(fenestra("evaluate-detector", "--data", small_dataset, "--weights", ROOT / "README.md",
                            cwd=tmp_path), "README.md is not a model checkpoint")
    one_line_error(fenestra("evaluate-detector", "--data", small_dataset, "--device", "cuda:99", cwd=tmp_path),
                   "--device cuda:99")
# (case, builder of the input in a fresh folder -> command line, the one error line's needles)
FAULTS = [
    ("coco top level a list", coco_case(lambda doc: []), ["the top level must be a JSON object", "got list"]),
    ("coco annotation without image_id", coco_case(_set("annotations.0.image_id", KeyError)),
     ["annotations.json: annotations[0] (id 1) has no 'image_id'"]),
    ("coco unknown image_id", coco_case(_set("annotations.0.image_id", 99)),
     ["annotations[0] (id 1): image_id 99 matches no image"]),
    ("coco duplicate image ids", coco_case(_set("images.1.id", 1), photos=("a.png", "b.png")),
     ["images[1] 'id' 1 duplicates images[0]"]),
    ("coco duplicate annotation ids", coco_case(lambda doc: doc["annotations"].append(dict(doc["annotations"][0]))),
     ["annotations[1] 'id' 1 duplicates annotations[0]"]),
    ("coco category_id a list", coco_case(_set("annotations.0.category_id", [1])),
     ["annotations[0] (id 1): 'category_id' must be an integer or string, got [1]"]),
    ("coco two photos of one name", coco_case(_set("images.1.file_name", "sub/a.png"), photos=("a.png", "b.png")),
     ["images[1] file_name 'sub/a.png' has the name 'a' of images[0]"]),
    ("coco image without file_name", coco_case(_set("images.0.file_name", KeyError)),
     ["images[0] needs a 'file_name' string, got None"]),
    ("coco category without id", coco_case(_set("categories.0.id", KeyError)), ["categories[0] has no 'id'"]),
    ("coco size_m [1, 0]", coco_case(_set("annotations.0.size_m", [1, 0])),
     ["annotations[0] (id 1): size_m must be [width, height] positive metres, got [1, 0]"]),
    ("coco size_m 'ab'", coco_case(_set("annotations.0.size_m", "ab")), ["size_m must be", "got 'ab'"]),
    ("coco polygon with odd coordinates", coco_case(_set("annotations.0.segmentation", [[10, 10, 30, 10, 30, 25, 10]])),
     ["segmentation[0] has an odd number of coordinates (7)"]),
    ("coco 1-point polygon", coco_case(_set("annotations.0.segmentation", [[10, 10]])),
     ["segmentation[0] has 1 point(s); a polygon needs at least 3"]),
    ("coco RLE of another size", coco_case(_set("annotations.0.segmentation", {"size": [10, 10], "counts": [5, 95]})),
     ["RLE size [10, 10] != the image's stated [height, width] [48, 64]"]),
    ("coco bbox outside the photo", coco_case(_set("annotations.0.bbox", [100, 10, 20, 15])),
     ["annotations[0] (id 1): bbox lies outside the 64x48 photo"]),
    ("coco file_name ../..", coco_case(_set("images.0.file_name", OUTSIDE)),
     [f"file_name '{OUTSIDE}' must be a path inside the dataset folder"]),
    ("coco absolute file_name", coco_case(_set("images.0.file_name", "/etc/hostname")),
     ["file_name '/etc/hostname' must be a path inside the dataset folder"]),
    ("coco photo symlinked outside", _then(coco_case(), _replace("images/a.png", lambda p: (
        _photo(p.parents[2] / "secret.png"), p.symlink_to(p.parents[2] / "secret.png")))),
     ["'images/a.png' leads outside the dataset folder"]),
    ("coco photo a FIFO", _then(coco_case(), _replace("images/a.png", _fifo)), ["a.png is not a regular file"]),
    ("coco EXIF-rotated photo, sensor size stated",
     _then(coco_case(lambda doc: doc["images"][0].update(file_name="a.jpg", width=400, height=300)), _exif6),
     ["image 1 (a.jpg) states width 400, height 300 but the photo decodes to 300x400 (EXIF orientation 6 applied)"]),
    ("coco annotations.json of 65 MB", _then(coco_case(), _replace("annotations.json", _sparse(65 * 2**20))),
     ["annotations.json is 65.0 MB, more than the 64 MB limit"]),
    ("coco annotations.json a FIFO", _then(coco_case(), _replace("annotations.json", _fifo)),
     ["annotations.json is not a regular file"]),
    ("bench on coco with an unknown image_id", bench_case(coco_case(_set("annotations.0.image_id", 99))),
     ["annotations[0] (id 1): image_id 99 matches no image"]),
    ("yolo class inf", yolo_case("inf 0.5 0.5 0.2 0.2\n"), ["a.txt:1: class 'inf' is not a non-negative integer"]),
    ("yolo line of 3 fields", yolo_case("0 0.5 0.5\n"), ["a.txt:1: bad YOLO line '0 0.5 0.5'"]),
    ("yolo box of zero width", yolo_case("0 0.5 0.5 0 0.2\n"), ["a.txt:1: box", "w, h > 0"]),
    ("yolo label file a FIFO", _then(yolo_case(""), _replace("labels/a.txt", _fifo)), ["a.txt is not a regular file"]),
    ("label map of 153600 components", checkerboard_case, ["153600 window components, more than the 1000 per photo"]),
    ("gate max = inf", gate_case("max = inf"), ["gate #1 (detection_rate) has max = inf; a bound must be finite"]),
    ("gate min = -inf", gate_case("min = -inf"), ["has min = -inf; a bound must be finite"]),
    ("gate min = nan", gate_case("min = nan"), ["has min = nan; a bound must be finite"]),
    ("K.json of 65 MB", big_K, ["K.json is 65.0 MB, more than the 64 MB limit"]),
    ("binary K.json", lambda d: [(d / "K.json").write_bytes(b"\x89PNG\r\n\x1a\n\xff\x00"), "reconstruct",
                                 EXAMPLE / "img017.jpg", "--K", "K.json", "--out", "o"][1:],
     ["intrinsics file K.json is not JSON (not UTF-8 text: byte 0x89 at offset 0)"]),
    ("binary profile", lambda d: [(d / "p.toml").write_bytes(b"name = \xff\xfe\x00"), "bench", "--profile", "p.toml",
                                  "--out", "o"][1:],
     ["p.toml: not a TOML profile file (not UTF-8 text: byte 0xff at offset 7)"]),
    ("photo of 24000 x 24000 px", huge_photo(24000, 24000),
     ["big.png is 24000x24000 = 576 Mpx, over the limit of 150 Mpx (--max-pixels raises it"]),
    ("dataset photo of 24000 x 24000 px", huge_image_in_dataset, ["b.png is 24000x24000 = 576 Mpx, over the limit"]),
    ("photo a Radiance HDR of 16000 x 16000 px named .jpg", radiance("big.jpg", 16000, 16000),
     ["big.jpg is 16000x16000 = 256 Mpx, over the limit of 150 Mpx"]),
    ("Radiance HDR photo over --max-pixels", lambda d: [*radiance("a.hdr", 2000, 2000)(d), "--max-pixels", "1000000"],
     ["a.hdr is 2000x2000 = 4 Mpx, over the limit of 1 Mpx"]),
    ("photo whose size no header reader knows (PAM)", pam_photo,
     ["cannot read photo a.png: not an image format whose size Fenestra can read before decoding"]),
    ("--known-height 1e300", lambda d: [*_reconstruct("o")(d), "--known-height", "1e300"],
     ["--known-height 1e+300 m is outside the physical range [0.01, 30] m"]),
    ("--known-storey 0.2", lambda d: [*_reconstruct("o")(d), "--known-storey", "0.2"],
     ["--known-storey 0.2 m is outside the physical range [1, 50] m"]),
    ("--wall-thickness 30 (cm, not m)", lambda d: [*_reconstruct("o")(d), "--wall-thickness", "30"],
     ["--wall-thickness 30.0 m is outside the physical range [0.01, 2] m"]),
    ("--substitute nosuch", lambda d: [*_reconstruct("o")(d), "--substitute", "nosuch"],
     ["--substitute: unknown window style 'nosuch'; choose one of"]),
    ("--detector nosuch", lambda d: [*_reconstruct("o")(d), "--detector", "nosuch"],
     ["--detector must be one of [", "got 'nosuch'"]),
    ("--quad-source nosuch", lambda d: [*_reconstruct("o")(d), "--quad-source", "nosuch"],
     ["--quad-source must be one of ['mask'", "got 'nosuch'"]),
    ("gate --suggest --margin nan", lambda d: [*run_with_status("complete")(d), "--suggest", "--margin", "nan"],
     ["--margin must be a finite number >= 0, got nan"]),
    ("gate on a run marked failed", run_with_status("failed"),
     ["run.json says status 'failed': KeyboardInterrupt", "not 'complete'"]),
    ("gate on a run still running", run_with_status("running"), ["says status 'running'"]),
    ("render 20000 px wide", lambda d: ["render", "--views", "1", "--width", "20000", "--height", "120"],
     ["image size 20000x120: a side may be at most 8192 px"]),
]


@pytest.mark.parametrize("case, build, needles", FAULTS, ids=[c for c, _, _ in FAULTS])
def test_bad_input_is_one_line_error(case, build, needles, tmp_path):
    args = build(tmp_path)
    one_line_error(fenestra(*args, cwd=tmp_path, timeout=120), *needles)


# (case, builder, needles in stdout): the dataset is usable, the label or file is left out with its reason
REFUSED = [
    ("yolo box entirely off the photo", yolo_case("0 1.5 1.5 0.2 0.2\n0 0.5 0.5 0.2 0.2\n"),
     ["1 window(s), 1 refused", "a.txt:1: box (cx 1.5, cy 1.5, w 0.2, h 0.2) lies entirely outside the photo; dropped"]),
    ("yolo photo a FIFO", _then(yolo_case(""), lambda d: os.mkfifo(d / "ds" / "images" / "b.jpg")),
     ["1 photo(s)", "b.jpg: not a regular file (a folder, FIFO or device); skipped"]),
    ("yolo labels without photo", _then(yolo_case(""), lambda d: (d / "ds" / "labels" / "z.txt").write_text("")),
     ["z.txt: no photo z.* in"]),
]


@pytest.mark.parametrize("case, build, needles", REFUSED, ids=[c for c, _, _ in REFUSED])
def test_bad_label_is_refused_with_its_reason(case, build, needles, tmp_path):
    r = fenestra(*build(tmp_path), cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    for n in needles:
        assert n in r.stdout, r.stdout


def test_file_names_that_are_not_utf8(tmp_path):
    """A photo whose name is not valid UTF-8 (a lone surrogate once decoded) reconstructs, and a
    dataset holding one is read: bytes are decoded from a buffer, never by cv2.imread(name)."""
    name = os.fsdecode(b"fa\xe7ade-\xff.png")
    photo = tmp_path / name
    shutil.copy(EXAMPLE / "img017.jpg", tmp_path / "x.jpg")
    cv2.imwrite(str(tmp_path / "x.png"), cv2.imread(str(tmp_path / "x.jpg")))
    os.rename(tmp_path / "x.png", photo)
    r = fenestra("reconstruct", photo, "--K", EXAMPLE / "K.json", "--masks", EXAMPLE / "panes017.png",
                 "--out", "o", cwd=tmp_path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert json.loads((tmp_path / "o" / "windows.json").read_text())["windows"], "no window reconstructed"
    yolo_case("0 0.5 0.5 0.2 0.2\n")(tmp_path / "y")
    os.rename(tmp_path / "y" / "ds" / "images" / "a.png", tmp_path / "y" / "ds" / "images" / name)
    os.rename(tmp_path / "y" / "ds" / "labels" / "a.txt", tmp_path / "y" / "ds" / "labels" / (Path(name).stem + ".txt"))
    r = subprocess.run([sys.executable, "-m", "fenestra", "check-data", "ds", "--format", "yolo"], cwd=tmp_path / "y",
                       env=env(), capture_output=True, timeout=120)
    out = r.stdout.decode()  # the name's undecodable bytes are printed escaped (backslashreplace), never raw
    shown = Path(name).stem.encode("utf-8", "backslashreplace").decode()
    assert r.returncode == 0 and "1 window(s)" in out and shown in out, (out[-2000:], r.stderr[-2000:])


def test_an_internal_error_is_one_line_and_a_log(tmp_path, monkeypatch, capsys):
    """A bug (an exception no user input explains) ends with one line, exit 3, 'please report',
    and its traceback in a log file, not on the terminal."""
    import fenestra.app.cli as cli

    def boom() -> None:
        {}["no such key"]  # noqa: B018  (the bug)

    cli.app.command("boom-for-test")(boom)
    monkeypatch.setattr(sys, "argv", ["fenestra", "boom-for-test"])
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr("tempfile.tempdir", None)
    try:
        with pytest.raises(SystemExit) as e:
            cli.main()
    finally:
        cli.app.registered_commands[:] = [c for c in cli.app.registered_commands if c.name != "boom-for-test"]
    err = capsys.readouterr().err
    assert e.value.code == 3 and "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "internal error (KeyError" in lines[0] and "please report" in lines[0], err
    logs = list(tmp_path.glob("fenestra-error-*.log"))
    assert len(logs) == 1 and "Traceback" in logs[0].read_text() and "no such key" in logs[0].read_text()


def test_label_map_checkerboard_in_bounded_memory(tmp_path):
    rc, err, gb = run_measured(checkerboard_case(tmp_path), tmp_path)
    assert rc == 2 and "153600 window components, more than the 1000 per photo" in err, err[-2000:]
    assert gb < 0.5, gb


def test_a_failed_bench_run_is_marked_failed(tmp_path):
    """A run that stops after its folder was claimed (here a disk-full error inside the run's block)
    leaves run.json saying 'failed' with the error's one line, and no manifest for gate/report."""
    from fenestra.bench.manifest import RUN_JSON, claim_run_dir, run_status

    run = claim_run_dir(tmp_path / "run", "tiny", "abc")
    assert json.loads((run / RUN_JSON).read_text())["status"] == "running"
    with pytest.raises(OSError):
        with run_status(run):
            raise OSError("No space left on device")
    doc = json.loads((run / RUN_JSON).read_text())
    assert doc["status"] == "failed" and doc["error"] == "OSError: No space left on device"
    assert doc["profile"] == "tiny" and not (run / "manifest.json").exists()
    with run_status(claim_run_dir(run, "tiny", "abc")):  # the same profile reclaims it and completes
        pass
    assert json.loads((run / RUN_JSON).read_text())["status"] == "complete"


# ---------------------------------------------------------------- 10. Ctrl-C

def test_ctrl_c_prints_interrupted(tmp_path):
    """Ctrl-C during a render: exit 130 and one line. The child gets SIGINT's default disposition:
    a test run started as a background job of a non-interactive shell (CI, nohup ... &) inherits
    SIGINT ignored, and Python then keeps ignoring it (the render ran to the end: exit 0)."""
    p = subprocess.Popen([sys.executable, "-m", "fenestra", *RENDER_ARGS[:2], "400", *RENDER_ARGS[3:]], cwd=tmp_path,
                         env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 120
    while not list(tmp_path.glob("out/renders/*/views/000001/view.json")) and time.time() < deadline:
        time.sleep(0.02)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err, (p.returncode, err[-2000:])
    assert [ln for ln in err.splitlines() if ln.startswith("error: ")] == ["error: interrupted; partial outputs removed"]


def test_ctrl_c_during_a_foreign_call_is_an_interrupt_not_a_bug():
    """Ctrl-C landing while ctypes converts a foreign call's arguments (pyrender's EGL) surfaces as
    ctypes.ArgumentError "argument 1: KeyboardInterrupt: ", unchained: the CLI must call it an
    interrupt (seen once in test_ctrl_c_prints_interrupted: exit 3 "internal error")."""
    import ctypes

    from fenestra.app.cli import was_interrupted

    class Interrupting:
        @classmethod
        def from_param(cls, obj):
            raise KeyboardInterrupt

    libc_abs = ctypes.CDLL(None).abs
    libc_abs.argtypes = [Interrupting]
    with pytest.raises(ctypes.ArgumentError) as info:
        libc_abs(1)
    assert was_interrupted(info.value)
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as inner:
            raise RuntimeError("cleanup failed") from inner
    except RuntimeError as chained:
        assert was_interrupted(chained)
    assert not was_interrupted(RuntimeError("a bug")) and not was_interrupted(ctypes.ArgumentError("argument 1: TypeError: x"))


# ---------------------------------------------------------------- 11. EXIF focal lengths outside the physical range (issue 37: 8)

def test_an_exif_focal_length_outside_the_physical_range_is_never_used(tmp_path):
    """A photo whose EXIF says a 35 mm equivalent of 65535 mm (a 2 atan(18 / 65535) = 0.031 deg
    view) is reconstructed (exit 0) without it: K_source says why EXIF is unavailable, with the
    range, and the focal length comes from a later source of the chain."""
    from PIL import Image

    photo = tmp_path / "exif65535.jpg"
    exif = Image.Exif()
    exif[0x8769] = {0xA405: 65535}
    Image.open(EXAMPLE / "img017.jpg").convert("RGB").save(photo, exif=exif, quality=95)
    r = fenestra("reconstruct", photo, "--masks", EXAMPLE / "panes017.png", "--out", "o", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    ks = json.loads((tmp_path / "o" / "windows.json").read_text())["K_source"]
    assert ks["source"] != "exif" and "exif" not in [c["source"] for c in ks["candidates"]]
    assert ks["unavailable"]["exif"].startswith("exif FocalLengthIn35mmFilm 65535 mm")
    assert "0.0315 deg field of view, outside the physical 0.5-170 deg" in ks["unavailable"]["exif"]


# ---------------------------------------------------------------- 12. the Python API's arguments (issue 37: 8)

# (case, keyword arguments of reconstruct_photo (photo first), needles of its one PipelineError line)
API_FAULTS = [
    ("photo an int", dict(photo=123), ["photo must be a path (str or os.PathLike), got 123 (int)"]),
    ("photo None", dict(photo=None), ["photo must be a path", "got None"]),
    ("photo missing", dict(photo="nosuch.jpg"), ["photo must be an existing regular file (not found)", "nosuch.jpg"]),
    ("photo a folder", dict(photo="."), ["photo must be an existing regular file, got '.'"]),
    ("out an int", dict(out=5), ["out must be a folder path (str or os.PathLike) or None, got 5 (int)"]),
    ("K_json a float", dict(K_json=1.5), ["K_json must be a path", "got 1.5 (float)"]),
    ("masks missing", dict(masks="nosuch.png"), ["masks must be an existing regular file (not found)"]),
    ("fx a string", dict(fx="800"), ["fx must be a finite number (px) or None, got '800' (str)"]),
    ("fx a bool", dict(fx=True), ["fx must be a finite number (px) or None, got True (bool)"]),
    ("fy nan", dict(fx=800.0, fy=float("nan")), ["fy must be a finite number", "got nan"]),
    ("fx negative", dict(fx=-800.0), ["fx must be positive (px), got -800.0"]),
    ("cx a list", dict(fx=800.0, cx=[1]), ["cx must be a finite number", "got [1] (list)"]),
    ("force a string", dict(force="yes"), ["force must be True or False, got 'yes' (str)"]),
    ("options a dict", dict(options={"detector": "oracle"}), ["options must be a fenestra.pipeline.photo.PhotoOptions"]),
    ("unknown detector", dict(options="detector=nosuch"), ["PhotoOptions: detector must be one of", "got 'nosuch'"]),
    ("unknown snapper", dict(options="snapper=nosuch"), ["PhotoOptions: snapper must be one of", "'linefit'"]),
    ("unknown pose", dict(options="pose=nosuch"), ["PhotoOptions: pose must be one of", "'wall'"]),
    ("unknown quad source", dict(options="quad_source=nosuch"), ["PhotoOptions: quad_source must be one of ['mask'"]),
    ("unknown substitute", dict(options="substitute=nosuch"), ["PhotoOptions: substitute must be None or one of"]),
    ("known a number", dict(options="known=3.2"), ["PhotoOptions: known must be a fenestra.pipeline.facade_model.Known"]),
    ("export_all a string", dict(options="export_all='no'"), ["PhotoOptions: export_all must be True or False"]),
    ("max_pixels a string", dict(options="max_pixels='x'"), ["PhotoOptions: max_pixels must be a positive int or None"]),
    ("max_pixels 0", dict(options="max_pixels=0"), ["PhotoOptions: max_pixels must be a positive int or None, got 0"]),
    ("wall thickness 30 (cm, not m)", dict(options="wall_thickness_m=30.0"),
     ["PhotoOptions: wall_thickness_m must be a number of metres in 0.01-2, got 30.0"]),
]


@pytest.mark.parametrize("case, kwargs, needles", API_FAULTS, ids=[c for c, _, _ in API_FAULTS])
def test_the_python_api_raises_only_pipeline_error(case, kwargs, needles, tmp_path, monkeypatch):
    """reconstruct_photo (fenestra's Python API) with one bad argument: one PipelineError line
    naming it, before anything is read or written (no TypeError, ValueError or AttributeError). A
    bad PhotoOptions field is refused when the options are built (``PhotoOptions: ...``), the
    other arguments by reconstruct_photo (``reconstruct_photo: ...``)."""
    from fenestra import reconstruct_photo
    from fenestra.errors import PipelineError
    from fenestra.pipeline.photo import PhotoOptions

    monkeypatch.chdir(tmp_path)
    kw = {"photo": EXAMPLE / "img017.jpg", "out": tmp_path / "o", **kwargs}
    field = None
    if isinstance(kw.get("options"), str):  # "field=value": PhotoOptions with that one field
        field, value = kw.pop("options").split("=", 1)
    photo = kw.pop("photo")
    with pytest.raises(PipelineError) as e:
        if field is not None:
            kw["options"] = PhotoOptions(**{field: value if value.isidentifier() else eval(value)})
        reconstruct_photo(photo, **kw)
    line = str(e.value)
    assert "\n" not in line and line.startswith("PhotoOptions: " if field else "reconstruct_photo: "), line
    for n in needles:
        assert n in line, line
    assert not (tmp_path / "o").exists()
