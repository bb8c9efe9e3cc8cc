"""What the fault suite's files share: running the CLI as a user does (:func:`fenestra`),
the one-line error check, the example inputs and the builders of bad inputs that several tables use."""
from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from fenestra.bench import manifest

ROOT = Path(__file__).resolve().parent.parent.parent
EXAMPLE = ROOT / "examples" / "curtainwall"
TINY_PROFILE = """name = "tiny"
description = "fault-injection test profile"
seed = 0
[scenes]
houses = ["fzk-haus"]
procedural = 0
[render]
renderer = "pyrender"
views_per_house = 3
width = 320
height = 240
[methods]
detectors = ["oracle"]
snappers = ["none", "linefit"]
pose_solvers = ["lm"]
"""
TINY_GATES = """[[gate]]
profile = "tiny"
method = "oracle/*/*"
metric = "detection_rate"
min = 0.5
"""
RENDER_ARGS = ["render", "--views", "3", "--width", "160", "--height", "120"]


def env() -> dict:
    e = {**os.environ, "PYTHONPATH": str(ROOT), "PYOPENGL_PLATFORM": "egl", "MPLBACKEND": "Agg"}
    e.pop("PYTHONHASHSEED", None)
    return e


def fenestra(*args, cwd: Path, limit_bytes: int | None = None, timeout: float = 300,
             pythonpath: tuple = ()) -> subprocess.CompletedProcess:
    """Run the CLI in ``cwd`` (its out/ holds renders); a first argument ``lab.NAME`` runs that lab
    command of the checkout instead (``python -m lab.ship``, ``python -m lab.docs``); limit_bytes:
    the largest file it may write; pythonpath: folders put after the checkout on PYTHONPATH (a
    plug-in's distribution)."""
    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    e = env()
    e["PYTHONPATH"] = os.pathsep.join([e["PYTHONPATH"], *map(str, pythonpath)])
    module = ["fenestra"] if not args or not str(args[0]).startswith("lab.") else []
    return subprocess.run([sys.executable, "-m", *module, *map(str, args)], cwd=cwd, env=e,
                          capture_output=True, text=True, timeout=timeout,
                          preexec_fn=limit if limit_bytes is not None else None)


def one_line_error(r: subprocess.CompletedProcess, *needles: str) -> str:
    """Assert the run failed with exit 2 and one 'error:' line (no traceback) holding each needle."""
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    assert "Traceback" not in r.stderr, r.stderr[-2000:]
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("error: ")]
    assert len(lines) == 1, r.stderr[-2000:]
    for n in needles:
        assert n in lines[0], lines[0]
    return lines[0]


def view_dirs(root: Path) -> list[Path]:
    return sorted(root.glob("out/renders/*/views/*"))


# ---------------------------------------------------------------- 3. reconstruct's outputs

def reconstruct(out, *extra, cwd: Path, photo=EXAMPLE / "img017.jpg", masks=EXAMPLE / "panes017.png",
                K=EXAMPLE / "K.json", limit_bytes=None):
    args = ["reconstruct", photo, "--out", out, "--snapper", "none"]
    args += ["--K", K] if K is not None else []
    args += ["--masks", masks] if masks is not None else []
    return fenestra(*args, *extra, cwd=cwd, limit_bytes=limit_bytes)


def _reconstruct(out: str, *extra: str):
    return lambda d: ["reconstruct", EXAMPLE / "img017.jpg", "--K", EXAMPLE / "K.json", "--masks",
                      EXAMPLE / "panes017.png", "--snapper", "none", "--out", out, *extra]


# ---------------------------------------------------------------- 4. bounded memory and time

# A launcher between pytest and the CLI: Linux keeps a process's pre-exec memory high-water mark,
# so a CLI forked straight from this (large) pytest process would report pytest's RSS as its own.
MEASURE = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
           "print(f'MAXRSS_KB {resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss}', file=sys.stderr); "
           "sys.exit(r.returncode)")


def run_measured(args: list, cwd: Path, max_gb: float | None = None, timeout: float = 300) -> tuple[int, str, float]:
    """(exit code, stderr, peak RSS in GB) of one CLI run; max_gb: its address space's limit (a run
    that would grow without bound fails with MemoryError there instead of taking the machine)."""
    def limit():
        if max_gb is not None:
            n = int(max_gb * 2**30)
            resource.setrlimit(resource.RLIMIT_AS, (n, n))
    # a session of its own: on timeout the launcher and the CLI under it are killed together
    p = subprocess.Popen([sys.executable, "-c", MEASURE, sys.executable, "-m", "fenestra", *map(str, args)],
                         cwd=cwd, env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=limit)
    try:
        _, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        raise
    kb = int(err.rsplit("MAXRSS_KB ", 1)[1])
    return p.returncode, err, kb / 2**20


# ---------------------------------------------------------------- 7. a user's dataset and other inputs

def _photo(path: Path, w: int = 64, h: int = 48) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.random.default_rng(0).integers(60, 200, (h, w, 3), dtype=np.uint8))


def coco_case(edit=None, photos=("a.png",)):
    """A builder: a COCO folder ds/ (64x48 photos, one window each) whose document went through
    ``edit(doc)`` (which may return a replacement); the check-data command line for it."""
    def build(d: Path) -> list:
        for p in photos:
            _photo(d / "ds" / "images" / p)
        doc = {"images": [{"id": i + 1, "file_name": p, "width": 64, "height": 48} for i, p in enumerate(photos)],
               "categories": [{"id": 1, "name": "window"}],
               "annotations": [{"id": 1, "image_id": 1, "category_id": 1, "bbox": [10, 10, 20, 15]}]}
        new = edit(doc) if edit else None
        doc = doc if new is None else new
        (d / "ds" / "annotations.json").write_text(json.dumps(doc))
        return ["check-data", "ds", "--format", "coco"]
    return build


def _set(path: str, value):
    """An edit setting doc[k1][k2]...= value (path 'annotations.0.size_m')."""
    def edit(doc):
        *keys, last = [int(k) if k.isdigit() else k for k in path.split(".")]
        node = doc
        for k in keys:
            node = node[k]
        if value is KeyError:
            del node[last]
        else:
            node[last] = value
    return edit


def _then(build, after):
    def b(d: Path) -> list:
        args = build(d)
        after(d)
        return args
    return b


def _replace(rel: str, make):
    """After building: replace ds/<rel> by ``make(path)`` (a symlink, a FIFO, a sparse file...)."""
    def after(d: Path) -> None:
        p = d / "ds" / rel
        p.unlink(missing_ok=True)
        make(p)
    return after


def _sparse(size: int):
    def make(p: Path) -> None:
        with open(p, "wb") as f:
            f.truncate(size)
    return make


def _exif6(d: Path) -> None:
    from PIL import Image

    exif = Image.Exif()
    exif[0x0112] = 6  # displayed turned 90 deg: 300 wide, 400 high
    Image.fromarray(np.full((300, 400, 3), 150, np.uint8)).save(d / "ds" / "images" / "a.jpg", exif=exif)


def yolo_case(label: str, fmt: str = "yolo"):
    def build(d: Path) -> list:
        _photo(d / "ds" / "images" / "a.png")
        (d / "ds" / "labels").mkdir(parents=True)
        (d / "ds" / "labels" / "a.txt").write_text(label)
        return ["check-data", "ds", "--format", fmt]
    return build


def checkerboard_case(d: Path) -> list:
    """A 640x480 label map whose window class is a 1-px checkerboard: 153600 components."""
    _photo(d / "ds" / "images" / "a.png", 640, 480)
    lab = np.zeros((480, 640, 3), np.uint8)
    lab[(np.indices((480, 640)).sum(axis=0) % 2) == 0] = (0, 0, 255)  # red in RGB, written as BGR
    (d / "ds" / "labels").mkdir()
    cv2.imwrite(str(d / "ds" / "labels" / "a.png"), lab)
    return ["check-data", "ds", "--format", "labelmap"]


def gate_case(bound: str):
    def build(d: Path) -> list:
        (d / "g.toml").write_text(f'[[gate]]\nprofile = "tiny"\nmethod = "*"\nmetric = "detection_rate"\n{bound}\n')
        return ["gate", "run", "--gates", "g.toml"]
    return build


def big_K(d: Path) -> list:
    _sparse(65 * 2**20)(d / "K.json")
    return ["reconstruct", EXAMPLE / "img017.jpg", "--K", "K.json", "--out", "o"]


def bench_case(build):
    def b(d: Path) -> list:
        build(d)
        return ["bench", "--profile", "real", "--data", "ds", "--format", "coco", "--out", "run"]
    return b


def _fifo(p: Path) -> None:
    os.mkfifo(p)


def png_header(path: Path, w: int, h: int) -> None:
    """A PNG whose header states w x h px, with a few bytes of pixel data: a decompression bomb."""
    import struct
    import zlib

    path.parent.mkdir(parents=True, exist_ok=True)
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    idat = zlib.compress(bytes(4096))  # the first rows only
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b""))


def huge_photo(w: int, h: int):
    def build(d: Path) -> list:
        png_header(d / "big.png", w, h)
        return ["reconstruct", "big.png", "--K", EXAMPLE / "K.json", "--out", "o"]
    return build


def huge_image_in_dataset(d: Path) -> list:
    yolo_case("0 0.5 0.5 0.2 0.2\n")(d)
    png_header(d / "ds" / "images" / "b.png", 24000, 24000)
    return ["check-data", "ds", "--format", "yolo"]


def radiance(name: str, w: int, h: int):
    """A Radiance HDR file (which PIL's header reader does not know) stating w x h px, a few bytes of pixels."""
    def build(d: Path) -> list:
        (d / name).write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w) + bytes(4096))
        return ["reconstruct", name, "--K", EXAMPLE / "K.json", "--out", "o"]
    return build


def pam_photo(d: Path) -> list:
    """A PAM image (P7): OpenCV decodes it, neither PIL nor Fenestra reads its size from the header."""
    ok, buf = cv2.imencode(".pam", np.zeros((48, 64, 3), np.uint8))
    (d / "a.png").write_bytes(buf.tobytes())
    return ["reconstruct", "a.png", "--K", EXAMPLE / "K.json", "--out", "o"]


def run_with_status(status: str):
    """A run folder with a verified results table (sealed) whose run.json says ``status``."""
    def build(d: Path) -> list:
        from fenestra.bench import results
        from synthetic_results import synthetic_results

        df = synthetic_results(n_windows=20, seed=1)
        results.write_results(df, d / "run")
        manifest.seal(d / "run", df, "synthetic")
        results.write_summary(d / "run", {"profile": "synthetic"}, results.summarize(df))
        (d / "run" / "run.json").write_text(json.dumps({"profile": "synthetic", "profile_hash": "", "status": status,
                                                        "error": "KeyboardInterrupt: "}))
        (d / "g.toml").write_text('[[gate]]\nprofile = "synthetic"\nmethod = "*"\nmetric = "detection_rate"\nmin = 0\n')
        return ["gate", "run", "--gates", "g.toml"]
    return build


OUTSIDE = "../../outside/secret.png"
