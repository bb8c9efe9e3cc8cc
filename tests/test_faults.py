"""Fault injection, as a user meets faults: every case runs ``python -m fenestra ...`` (the ``fenestra`` command) in a
subprocess (README: "What Fenestra guarantees").

Disk full is a real failing write: the child runs under RLIMIT_FSIZE (a file-size limit the
kernel enforces with EFBIG, SIGXFSZ ignored), so cv2.imwrite and friends fail mid-run exactly as
on a full disk. A read-only output is a read-only tmpfs when running as root (root ignores file
modes), else a folder with mode 0o555.
"""
from __future__ import annotations

import hashlib
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest

from fenestra.bench import manifest

ROOT = Path(__file__).resolve().parent.parent
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
    """Run the CLI in ``cwd`` (its out/ holds renders); limit_bytes: the largest file it may write;
    pythonpath: folders put after the checkout on PYTHONPATH (a plug-in's distribution)."""
    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    e = env()
    e["PYTHONPATH"] = os.pathsep.join([e["PYTHONPATH"], *map(str, pythonpath)])
    return subprocess.run([sys.executable, "-m", "fenestra", *map(str, args)], cwd=cwd, env=e,
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


# ---------------------------------------------------------------- 1. gates see dropped samples

@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    """A complete tiny benchmark run (3 views, oracle x 2 snappers) and its gates file."""
    d = tmp_path_factory.mktemp("bench")
    (d / "tiny.toml").write_text(TINY_PROFILE)
    (d / "gates.toml").write_text(TINY_GATES)
    r = fenestra("bench", "--profile", "tiny.toml", "--out", "run", "--workers", "1", cwd=d)
    assert r.returncode == 0, r.stderr[-3000:]
    ok = fenestra("gate", "run", "--gates", "gates.toml", cwd=d)
    assert ok.returncode == 0 and "all gates passed" in ok.stdout, ok.stderr
    return d


def tampered(bench_run: Path, name: str, edit) -> Path:
    """A copy of the run whose results.parquet went through ``edit(df) -> df``."""
    dst = bench_run / name
    shutil.copytree(bench_run / "run", dst)
    df = edit(pd.read_parquet(dst / "results.parquet"))
    df.to_parquet(dst / "results.parquet", index=False)
    return dst


def test_gate_refuses_a_table_missing_a_method(bench_run):
    run = tampered(bench_run, "no-linefit", lambda df: df[df.method != "oracle/linefit/lm"])
    n = json.loads((bench_run / "run" / "manifest.json").read_text())["n_rows"] // 2
    line = one_line_error(fenestra("gate", run.name, "--gates", "gates.toml", cwd=bench_run),
                          f"lacks {n} of {2 * n} expected rows", f"oracle/linefit/lm: {n}")
    assert "oracle/none/lm" not in line
    one_line_error(fenestra("report", run.name, cwd=bench_run), f"lacks {n} of {2 * n}")


def test_gate_refuses_a_table_missing_single_windows(bench_run):
    def drop_worst(df):  # the two worst evaluable rows of one method, as a cherry-picker would
        worst = df[df.method == "oracle/none/lm"].sort_values("corner_err_px_snap").index[-2:]
        return df.drop(index=worst)
    run = tampered(bench_run, "no-worst", drop_worst)
    one_line_error(fenestra("gate", run.name, "--gates", "gates.toml", cwd=bench_run),
                   "lacks 2 of", "oracle/none/lm: 2")


def test_gate_refuses_overwritten_values(bench_run):
    def hide_errors(df):
        df = df.copy()
        df["status"] = "ok"
        df["corner_err_px_snap"] = df["corner_err_px_snap"].fillna(0.0) * 0.5
        return df
    run = tampered(bench_run, "edited", hide_errors)
    one_line_error(fenestra("gate", run.name, "--gates", "gates.toml", cwd=bench_run),
                   "results.parquet was modified after the run")


def test_gate_refuses_a_run_without_manifest(bench_run):
    run = tampered(bench_run, "no-manifest", lambda df: df)
    (run / "manifest.json").unlink()
    one_line_error(fenestra("gate", run.name, "--gates", "gates.toml", cwd=bench_run), "no manifest.json")


def test_manifest_lists_every_gt_window_of_every_view(bench_run):
    """Expected rows = each view.json's windows x methods, computed here from the renders."""
    m = manifest.load_manifest(bench_run / "run")
    want = sorted([("fzk-haus", v.name, str(w["id"]), meth) for v in view_dirs(bench_run)
                   for w in json.loads((v / "view.json").read_text())["windows"]
                   for meth in ("oracle/none/lm", "oracle/linefit/lm")])
    assert sorted(m["rows"]) == want and m["n_rows"] == len(want) > 0
    # stored compactly (each view's windows, the methods), and only the Parquet table is written
    assert "rows" not in json.loads((bench_run / "run" / "manifest.json").read_text())
    assert set(m["sha256"]) == {"results.parquet"} and not (bench_run / "run" / "results.csv").exists()


def test_manifest_rows_compact_form_round_trips_and_falls_back_to_rows():
    views = [("h", "000", ["w1", "w2"]), ("h", "001", ["w3"]), ("g", "000", ["w1"])]
    product = [(h, v, w, m) for h, v, ws in views for w in ws for m in ("a/x/lm", "b/y/wall")]
    doc = manifest.compact_rows(product)
    assert doc == {"methods": ["a/x/lm", "b/y/wall"], "views": [list(v) for v in views]}
    assert manifest.expand_rows(doc) == product
    for odd in (product[:-1], product + [product[0]], [product[1], product[0], *product[2:]]):
        doc = manifest.compact_rows(odd)  # not every window x method once, in order: row by row
        assert "views" not in doc and manifest.expand_rows(doc) == odd
    assert manifest.expand_rows(manifest.compact_rows([])) == []


def test_bench_refuses_a_foreign_folder_and_force_leaves_nothing_stale(bench_run):
    foreign = bench_run / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    one_line_error(fenestra("bench", "--profile", "tiny.toml", "--out", "foreign", cwd=bench_run),
                   "not empty", "--force")
    other = bench_run / "other-profile"
    shutil.copytree(bench_run / "run", other)
    (bench_run / "tiny2.toml").write_text(TINY_PROFILE.replace("views_per_house = 3", "views_per_house = 2"))
    one_line_error(fenestra("bench", "--profile", "tiny2.toml", "--out", other.name, "--no-report", cwd=bench_run),
                   "holds a run of profile 'tiny'", "--force")
    r = fenestra("bench", "--profile", "tiny2.toml", "--out", other.name, "--no-report", "--force",
                 "--workers", "1", cwd=bench_run)
    assert r.returncode == 0, r.stderr[-2000:]
    assert not (other / "report.html").exists() and not (other / "figures").exists()  # the old run's
    assert json.loads((other / "run.json").read_text())["profile_hash"] != \
        json.loads((bench_run / "run" / "run.json").read_text())["profile_hash"]
    assert fenestra("gate", other.name, "--gates", "gates.toml", cwd=bench_run).returncode == 0


def test_profile_with_infinite_min_window_px_is_refused(tmp_path):
    (tmp_path / "p.toml").write_text(TINY_PROFILE + "[evaluation]\nmin_window_px = inf\n")
    one_line_error(fenestra("bench", "--profile", "p.toml", cwd=tmp_path), "min_window_px = inf")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- 2. the render cache

def test_disk_full_mid_render_then_resume(tmp_path):
    r = fenestra(*RENDER_ARGS, cwd=tmp_path, limit_bytes=5_000)  # a 160x120 render PNG is larger (~26 kB)
    one_line_error(r, "cannot write", "image.png")
    assert not list(tmp_path.glob("out/renders/*/views/*/view.json"))  # no view counts as done
    assert not list(tmp_path.glob("out/renders/**/.*tmp*"))  # no temporary file left
    r = fenestra(*RENDER_ARGS, cwd=tmp_path)
    assert r.returncode == 0 and "3 views rendered, 0 reused" in r.stdout, r.stderr[-2000:]


def test_poisoned_cache_is_rerendered_with_a_message(tmp_path):
    assert fenestra(*RENDER_ARGS, cwd=tmp_path).returncode == 0
    v0, v1, v2 = view_dirs(tmp_path)
    good = (v0 / "image.png").read_bytes()
    (v0 / "image.png").write_bytes(good[: len(good) // 2])  # truncated
    (v1 / "image.png").unlink()  # view.json without its image
    (v2 / "instances.png").write_bytes(b"not a png")
    r = fenestra(*RENDER_ARGS, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "3 views rendered, 0 reused" in r.stdout
    for v in (v0, v1, v2):
        assert f"cached view {v.relative_to(tmp_path)} is damaged" in r.stderr
    assert (v0 / "image.png").read_bytes() == good  # renders are deterministic
    r = fenestra(*RENDER_ARGS, cwd=tmp_path)
    assert "0 views rendered, 3 reused" in r.stdout and "damaged" not in r.stderr


def test_sigterm_mid_render_then_resume(tmp_path):
    args = [*RENDER_ARGS[:2], "40", *RENDER_ARGS[3:]]
    p = subprocess.Popen([sys.executable, "-m", "fenestra", *args], cwd=tmp_path, env=env(),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not list(tmp_path.glob("out/renders/*/views/000001/view.json")) and time.time() < deadline:
        time.sleep(0.02)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 128 + signal.SIGTERM, err[-2000:]
    done = len(list(tmp_path.glob("out/renders/*/views/*/view.json")))
    assert 2 <= done < 40
    assert not list(tmp_path.glob("out/renders/**/.*tmp*"))
    r = fenestra(*args, cwd=tmp_path)
    assert r.returncode == 0 and f"{40 - done} views rendered, {done} reused" in r.stdout, r.stderr[-2000:]


def test_negative_seed_leaves_no_folder(tmp_path):
    one_line_error(fenestra(*RENDER_ARGS, "--seed", "-5", cwd=tmp_path), "seed must be >= 0, got -5")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- 3. reconstruct's outputs

def reconstruct(out, *extra, cwd: Path, photo=EXAMPLE / "img017.jpg", masks=EXAMPLE / "panes017.png",
                K=EXAMPLE / "K.json", limit_bytes=None):
    args = ["reconstruct", photo, "--out", out, "--snapper", "none"]
    args += ["--K", K] if K is not None else []
    args += ["--masks", masks] if masks is not None else []
    return fenestra(*args, *extra, cwd=cwd, limit_bytes=limit_bytes)


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


def _reconstruct(out: str, *extra: str):
    return lambda d: ["reconstruct", EXAMPLE / "img017.jpg", "--K", EXAMPLE / "K.json", "--masks",
                      EXAMPLE / "panes017.png", "--snapper", "none", "--out", out, *extra]


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


def test_output_on_another_filesystem(tmp_path):
    """--out a mount point (another device than its parent): staged inside it, so the final renames
    stay on one device; a second run replaces the first whole."""
    out = tmp_path / "mnt"
    out.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64m", "tmpfs", str(out)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr!r})")
    try:
        assert os.stat(out).st_dev != os.stat(tmp_path).st_dev
        for _ in range(2):
            r = fenestra(*_reconstruct("mnt")(tmp_path), cwd=tmp_path)
            assert r.returncode == 0, r.stderr[-2000:]
        assert json.loads((out / "windows.json").read_text())["windows"]
        assert not list(out.glob(".fenestra-stage-*")) and sorted(p.name for p in tmp_path.iterdir()) == ["mnt"]
    finally:
        subprocess.run(["umount", str(out)], check=True)


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


# ---------------------------------------------------------------- 4. bounded memory and time

# A launcher between pytest and the CLI: Linux keeps a process's pre-exec memory high-water mark,
# so a CLI forked straight from this (large) pytest process would report pytest's RSS as its own.
MEASURE = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
           "print(f'MAXRSS_KB {resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss}', file=sys.stderr); "
           "sys.exit(r.returncode)")


def run_measured(args: list, cwd: Path) -> tuple[int, str, float]:
    """(exit code, stderr, peak RSS in GB) of one CLI run."""
    r = subprocess.run([sys.executable, "-c", MEASURE, sys.executable, "-m", "fenestra", *map(str, args)],
                       cwd=cwd, env=env(), capture_output=True, text=True, timeout=300)
    kb = int(r.stderr.rsplit("MAXRSS_KB ", 1)[1])
    return r.returncode, r.stderr, kb / 2**20


def test_65535_instance_ids_are_a_clear_error_in_bounded_memory(tmp_path):
    ids = np.arange(1, 256 * 256, dtype=np.uint16).tolist() + [0]
    cv2.imwrite(str(tmp_path / "m.png"), np.array(ids, np.uint16).reshape(256, 256))
    cv2.imwrite(str(tmp_path / "p.png"), np.full((256, 256, 3), 128, np.uint8))
    rc, err, gb = run_measured(["reconstruct", "p.png", "--fx", "300", "--masks", "m.png", "--out", "o"], tmp_path)
    assert rc == 2 and "instance map has 65535 window ids, more than the 1000 per photo" in err, err[-2000:]
    assert gb < 1.0 and not (tmp_path / "o").exists()


def test_many_windows_sparse_masks_large_photo():
    """1000 windows (the stated maximum) in a 4000x3000 instance map: one Detection per id with
    its bounding-box crop (not a full-size mask each: 12 GB), quads where the rectangles are.
    In process: the CLI run of this case (export included) is measured by tools/bench_memory.py."""
    from fenestra.pipeline.detectors.oracle import detections_from_instance_map
    from fenestra.pipeline.reconstruct import fit_quads

    inst = np.zeros((3000, 4000), np.uint16)
    rects = {}
    for k in range(1000):
        r, c = divmod(k, 40)
        x0, y0 = 20 + c * 98, 20 + r * 118
        inst[y0:y0 + 60, x0:x0 + 40] = 7 + 3 * k
        rects[7 + 3 * k] = (x0, y0, x0 + 39, y0 + 59)
    dets = detections_from_instance_map(inst)
    assert [d.instance_id for d in dets] == sorted(rects)
    assert sum(d.mask.nbytes for d in dets) == 1000 * 60 * 40  # crops exactly the windows' boxes
    fits = fit_quads(dets, image_shape=inst.shape)
    for d, f in list(zip(dets, fits))[::37]:
        x0, y0, x1, y1 = rects[d.instance_id]
        # the void's outline runs half a pixel outside the outer pixel centres
        want = np.array([[x0 - .5, y0 - .5], [x1 + .5, y0 - .5], [x1 + .5, y1 + .5], [x0 - .5, y1 + .5]])
        np.testing.assert_allclose(f.result.quad, want, atol=0.05)
    with pytest.raises(Exception, match="1000 window ids, more than the 999 per photo"):
        detections_from_instance_map(inst, max_windows=999)


def test_large_photo_with_the_learned_detector(tmp_path):
    """A 3000x2000 photo: the network sees it at 1024 px, the quad comes back at full resolution
    (tools/bench_memory.py measures the 6000x4000 case)."""
    img = np.full((2000, 3000, 3), 180, np.uint8)
    img[500:800, 750:950] = 30  # a dark 200 x 300 px window void
    cv2.imwrite(str(tmp_path / "big.jpg"), img)
    rc, err, gb = run_measured(["reconstruct", "big.jpg", "--fx", "2500", "--out", "o", "--snapper", "none"],
                               tmp_path)
    assert rc == 0, err[-2000:]
    assert gb < 2.0, gb
    doc = json.loads((tmp_path / "o" / "windows.json").read_text())
    assert doc["image_size"] == [3000, 2000] and len(doc["windows"]) == 1
    want = [[749.5, 499.5], [949.5, 499.5], [949.5, 799.5], [749.5, 799.5]]
    # one network pixel is 2.9 photo pixels: the corners within a few of them
    np.testing.assert_allclose(doc["windows"][0]["quad_mask"], want, atol=12.0)


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
    ("--substitute nosuch", lambda d: [*_reconstruct("o")(d), "--substitute", "nosuch"],
     ["--substitute: unknown window style 'nosuch'; choose one of"]),
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
                       env=env(), capture_output=True, timeout=120)  # bytes: the name is printed as it is
    out = r.stdout.decode(errors="surrogateescape")
    assert r.returncode == 0 and "1 window(s)" in out and Path(name).stem in out, (out[-2000:], r.stderr[-2000:])


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


# ---------------------------------------------------------------- 8. dataset paths, label bounds, names (issue 37: 6, 7, 9)

SECRET = "root:x:0:0:fenestra-secret-line"  # content of a file outside the dataset: never printed


def _outside_file(d: Path, name: str, content: bytes | None = None) -> Path:
    """A file beside the dataset folder ds/ (outside it): the target of a symlink leading out."""
    p = d / name
    if content is None:
        _photo(p)
    else:
        p.write_bytes(content)
    return p


def labelmap_case(d: Path) -> list:
    """A label-map folder: a 64x48 photo and its label map (a red window on blue)."""
    _photo(d / "ds" / "images" / "a.png")
    lab = np.zeros((48, 64, 3), np.uint8)
    lab[:] = (255, 0, 0)  # blue, written as BGR
    lab[10:20, 10:30] = (0, 0, 255)  # red
    (d / "ds" / "labels").mkdir(parents=True)
    cv2.imwrite(str(d / "ds" / "labels" / "a.png"), lab)
    return ["check-data", "ds", "--format", "labelmap"]


def _link_out(rel: str, target: str, content: bytes | None = None):
    """After building: ds/<rel> becomes a symlink to ``target`` beside ds/ (outside the dataset)."""
    def after(d: Path) -> None:
        (d / "ds" / rel).unlink()
        (d / "ds" / rel).symlink_to(_outside_file(d, target, content))
    return after


def _photos_also(*names: str):
    def after(d: Path) -> None:
        for n in names:
            _photo(d / "ds" / "images" / n)
    return after


def _many_windows(n: int):
    def edit(doc):
        doc["annotations"] = [{"id": i + 1, "image_id": 1, "category_id": 1, "bbox": [10, 10, 20, 15]} for i in range(n)]
    return edit


def _no_stated_size(seg):
    def edit(doc):
        del doc["images"][0]["width"], doc["images"][0]["height"]
        doc["annotations"][0]["segmentation"] = seg
    return edit


# (case, builder, needles of the one error line); every case fails before a label is parsed or a mask decoded
DATASET_FAULTS = [
    ("yolo label symlinked to a file outside", _then(yolo_case("0 0.5 0.5 0.2 0.2\n"),
                                                     _link_out("labels/a.txt", "passwd", (SECRET + "\n").encode())),
     ["YOLO label file", "a.txt", "leads outside the dataset folder"]),
    ("label map symlinked to a file outside", _then(labelmap_case, _link_out("labels/a.png", "other.png")),
     ["label map", "a.png", "leads outside the dataset folder"]),
    ("yolo label file of 5 MB", _then(yolo_case(""), _replace("labels/a.txt", _sparse(5 * 2**20))),
     ["a.txt is 5.0 MB, more than the 4 MB limit (fenestra.conventions.LIMITS.max_label_bytes)"]),
    ("yolo label file of 100001 lines", yolo_case("0 0.5 0.5 0.01 0.01\n" * 100_001),
     ["a.txt has 100001 lines, more than the 100000 limit (fenestra.conventions.LIMITS.max_label_lines)"]),
    ("yolo 1001 window boxes", yolo_case("0 0.5 0.5 0.01 0.01\n" * 1001),
     ["a.txt: 1001 window boxes, more than the 1000 per photo"]),
    ("yolo box 30 times the photo", yolo_case("0 0.5 0.5 30 30\n"),
     ["a.txt:1: box w 30, h 30 is larger than the 64x48 photo"]),
    ("yolo photos a.png and a.jpg", _then(yolo_case("0 0.5 0.5 0.2 0.2\n"), _photos_also("a.jpg")),
     ["photos 'a.jpg' and 'a.png' differ only by case or extension"]),
    ("yolo photos a.png and A.PNG", _then(yolo_case("0 0.5 0.5 0.2 0.2\n"), _photos_also("A.PNG")),
     ["photos 'A.PNG' and 'a.png' differ only by case or extension"]),
    ("labelmap photos a.png and a.jpeg", _then(labelmap_case, _photos_also("a.jpeg")),
     ["photos 'a.jpeg' and 'a.png' differ only by case or extension"]),
    ("coco photos a.png and A.png", coco_case(photos=("a.png", "A.png")),
     ["images[1] file_name 'A.png' has the name 'A' of images[0] 'a.png'"]),
    ("coco unknown category_id", coco_case(_set("annotations.0.category_id", 7)),
     ["annotations[0] (id 1): category_id 7 matches no category (the file's: [1])"]),
    ("bench on coco with an unknown category_id", bench_case(coco_case(_set("annotations.0.category_id", 7))),
     ["annotations[0] (id 1): category_id 7 matches no category"]),
    ("coco RLE of 40000 x 40000 px, no stated size", coco_case(_no_stated_size({"size": [40000, 40000],
                                                                                 "counts": [1_600_000_000]})),
     ["annotations.json: annotations[0] (id 1): RLE size [40000, 40000] is 1600 Mpx, over the limit of 150 Mpx"]),
    ("coco RLE of another size than its photo, no stated size",
     coco_case(_no_stated_size({"size": [10, 10], "counts": [5, 95]})),
     ["annotations.json: annotations[0] (id 1): RLE size [10, 10] != the photo's [height, width] [48, 64]"]),
    ("coco RLE counts not covering its size", coco_case(_set("annotations.0.segmentation",
                                                             {"size": [48, 64], "counts": [5, 95]})),
     ["annotations[0] (id 1): RLE counts cover 100 pixels, not the 48 x 64 = 3072 of its size"]),
    ("coco 1001 window annotations on one photo", coco_case(_many_windows(1001)),
     ["image 1 (a.png) has 1001 window annotations, more than the 1000 per photo"]),
]


@pytest.mark.parametrize("case, build, needles", DATASET_FAULTS, ids=[c for c, _, _ in DATASET_FAULTS])
def test_dataset_fault_is_one_line_error(case, build, needles, tmp_path):
    r = fenestra(*build(tmp_path), cwd=tmp_path, timeout=120)
    one_line_error(r, *needles)
    assert SECRET not in r.stderr + r.stdout


# ---------------------------------------------------------------- 8. plug-ins cannot take the CLI down

def plugin(d: Path, code: str, name: str = "badplug") -> Path:
    """An installed plug-in distribution, as pip leaves one (a module and its dist-info with a
    ``fenestra.plugins`` entry point), in d/site: put that folder on PYTHONPATH."""
    site = d / "site"
    info = site / f"{name}-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[fenestra.plugins]\n{name} = {name}\n")
    (site / f"{name}.py").write_text(code)
    return site


ENTRY = 'class E:\n    name = "lsd"\n    description = "a plug-in lsd"\n'
# (case, the plug-in's code, the one warning line's needles): `fenestra --version` still prints the
# version and exits 0, with that one warning line naming the plug-in, and the built-in 'lsd' stays
PLUGINS = [
    ("raises at import", 'raise ImportError("no module named fancy")\n',
     ["fenestra plug-in 'badplug' (badplug) failed to load and is ignored: ImportError: no module named fancy"]),
    ("calls sys.exit(0) at import", "import sys\nsys.exit(0)\n", ["'badplug'", "it called sys.exit(0)"]),
    ("registers a built-in's name", "from fenestra.pipeline.snappers import SNAPPERS\n" + ENTRY + "SNAPPERS.register(E())\n",
     ["'badplug'", "snapper 'lsd' is already registered"]),
    ("replaces a built-in without override", "from fenestra.pipeline.snappers import SNAPPERS\n" + ENTRY
     + 'SNAPPERS["lsd"] = E()\n', ["'badplug'", "a plug-in replaces it only with an explicit override = True"]),
    ("replaces a built-in, then fails", "from fenestra.pipeline.snappers import SNAPPERS\n" + ENTRY
     + 'E.override = True\nSNAPPERS["lsd"] = E()\nraise RuntimeError("half done")\n', ["RuntimeError: half done"]),
]
SHOW_LSD = ["-c", "from fenestra.pipeline.snappers import SNAPPERS; from fenestra.registry import plugin_metadata; "
                  "print(SNAPPERS['lsd'].description); print(plugin_metadata())"]


@pytest.mark.parametrize("case, code, needles", PLUGINS, ids=[c for c, _, _ in PLUGINS])
def test_a_failing_plugin_is_one_warning(case, code, needles, tmp_path):
    site = plugin(tmp_path, code)
    r = fenestra("--version", cwd=tmp_path, pythonpath=(site,))
    assert r.returncode == 0 and r.stdout.startswith("fenestra "), (r.returncode, r.stdout, r.stderr[-2000:])
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr[-2000:]
    for n in needles:
        assert n in r.stderr, r.stderr
    shown = subprocess.run([sys.executable, *SHOW_LSD], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                           env={**env(), "PYTHONPATH": f"{ROOT}{os.pathsep}{site}"})
    assert shown.returncode == 0 and "a plug-in lsd" not in shown.stdout, shown.stdout + shown.stderr[-2000:]
    assert "'overrides': {}" in shown.stdout and "'badplug'" in shown.stdout.splitlines()[1]  # named as failed


def test_a_plugin_replaces_a_builtin_only_with_override_and_is_recorded(tmp_path):
    code = "from fenestra.pipeline.snappers import SNAPPERS\n" + ENTRY + 'E.override = True\nSNAPPERS["lsd"] = E()\n'
    site = plugin(tmp_path, code, name="goodplug")
    shown = subprocess.run([sys.executable, *SHOW_LSD], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                           env={**env(), "PYTHONPATH": f"{ROOT}{os.pathsep}{site}"})
    assert shown.returncode == 0 and shown.stderr == "", shown.stderr[-2000:]
    lsd, meta = shown.stdout.splitlines()
    assert lsd == "a plug-in lsd"
    assert meta == str({"loaded": ["goodplug"], "failed": {}, "overrides": {"snapper lsd": "goodplug"}})


# ---------------------------------------------------------------- 9. what feeds a figure is covered by a digest

def _shard_outcomes():
    from fenestra.bench.evaluate import ViewOutcome

    gt = [{"image": "h/000000", "rle": {"size": [4, 5], "counts": "52"}, "bbox": [1.0, 2.0, 3.0, 1.0],
           "area": 3.0, "iscrowd": 0}]
    dt = {"oracle": [{"image": "h/000000", "bbox": [1.5, 2.0, 3.0, 1.0], "score": 0.75}]}
    row = {"house": "h", "view": "000000", "window_id": "w", "method": "oracle/none/lm", "corner_err_px_snap": 0.5}
    return [ViewOutcome([row], {"detect": 0.5}, gt, dt, {"oracle": 1})]


def _set_in_index(edit):
    def apply(doc: dict) -> None:
        edit(doc["views"][0])
    return apply


# (case, an edit of a shard index's JSON, the rows file and its digest untouched): the shard is
# recomputed with a warning, never trusted (issue 37: one digit moved a detector's box AP)
SHARD_EDITS = [
    ("a detection's box moved", _set_in_index(lambda v: v["coco_dt"]["oracle"][0]["bbox"].__setitem__(0, 1.0))),
    ("detections replaced by the ground truth", _set_in_index(lambda v: v["coco_dt"].__setitem__(
        "oracle", [{**{k: g[k] for k in ("image", "bbox")}, "score": 1.0} for g in v["coco_gt"]]))),
    ("false-positive count lowered", _set_in_index(lambda v: v["n_false_positives"].__setitem__("oracle", 0))),
    ("stage seconds changed", _set_in_index(lambda v: v["stage_s"].__setitem__("detect", 0.001))),
    ("a ground-truth window dropped", _set_in_index(lambda v: v["coco_gt"].clear())),
]


@pytest.mark.parametrize("case, edit", SHARD_EDITS, ids=[c for c, _ in SHARD_EDITS])
def test_an_edited_shard_index_is_recomputed(case, edit, tmp_path, capsys):
    from fenestra.bench.executors import _load_shard, write_shard

    idx = write_shard(tmp_path / "k.json", "d", _shard_outcomes(), 1.0)
    assert _load_shard(str(idx)) is not None
    doc = json.loads(idx.read_text())
    edit(doc)
    idx.write_text(json.dumps(doc))
    assert _load_shard(str(idx)) is None
    assert "index does not match its own digest" in capsys.readouterr().err


# ---------------------------------------------------------------- 10. Ctrl-C

def test_ctrl_c_prints_interrupted(tmp_path):
    p = subprocess.Popen([sys.executable, "-m", "fenestra", *RENDER_ARGS[:2], "400", *RENDER_ARGS[3:]], cwd=tmp_path,
                         env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not list(tmp_path.glob("out/renders/*/views/000001/view.json")) and time.time() < deadline:
        time.sleep(0.02)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err, (p.returncode, err[-2000:])
    assert [ln for ln in err.splitlines() if ln.startswith("error: ")] == ["error: interrupted; partial outputs removed"]
