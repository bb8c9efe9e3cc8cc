"""Output folders by kind, and every writer under the ownership rule: no command replaces or deletes
what is not its own kind of output, nor a file it did not write, nor its own input; a bench run
lists its report and comparison pages, so bench -> report -> compare -> bench needs no rm; one
reconstruct at a time into a folder; gates and comparisons that cannot pass vacuously.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fenestra import outputs

from fault_helpers import (EXAMPLE, TINY_PROFILE, _photo, _reconstruct, fenestra, one_line_error, reconstruct,
                           run_with_status)
from test_ownership import snapshot


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> Path:
    """One output of each kind, made by the CLI: run/ (a tiny bench run), rec/ (one photo's
    reconstruction), batch/ (two photos), and photos/ (the batch's input)."""
    d = tmp_path_factory.mktemp("kinds")
    (d / "tiny.toml").write_text(TINY_PROFILE)
    r = fenestra("bench", "--profile", "tiny.toml", "--out", "run", "--workers", "1", "--no-report", cwd=d)
    assert r.returncode == 0, r.stderr[-3000:]
    r = fenestra(*_reconstruct("rec")(d), cwd=d)
    assert r.returncode == 0, r.stderr[-3000:]
    for i in range(2):
        _photo(d / "photos" / f"p{i}.png")
    r = fenestra("reconstruct", "photos", "--fx", "60", "--out", "batch", cwd=d)
    assert r.returncode == 0, r.stderr[-3000:]
    return d


def _copy(made: Path, d: Path, *names: str) -> None:
    for n in names:
        src = made / n
        shutil.copytree(src, d / n) if src.is_dir() else shutil.copy(src, d / n)


BATCH = ["reconstruct", "photos", "--fx", "60"]
TINY_BENCH = ["bench", "--profile", "tiny.toml", "--workers", "1", "--no-report"]

# (case, what to copy from `made`, command line, needles of the one error line): refused up front,
# every file under the test's folder byte for byte as before, --force or not
KIND_CASES = [
    ("reconstruct into a bench run", ("run",), [*_reconstruct("run")(None)],
     ["--out run holds a benchmark run, not one photo's reconstruction", "--force never"]),
    ("reconstruct --force into a bench run", ("run",), [*_reconstruct("run", "--force")(None)],
     ["--out run holds a benchmark run"]),
    ("a batch into a bench run", ("run", "photos"), [*BATCH, "--out", "run"],
     ["--out run holds a benchmark run, not a batch of reconstructions"]),
    ("a batch --force into a bench run", ("run", "photos"), [*BATCH, "--out", "run", "--force"],
     ["--out run holds a benchmark run"]),
    ("bench --force into a reconstruction", ("rec", "tiny.toml"), [*TINY_BENCH, "--out", "rec", "--force"],
     ["--out rec holds one photo's reconstruction, not a benchmark run"]),
    ("bench --force into a batch", ("batch", "tiny.toml"), [*TINY_BENCH, "--out", "batch", "--force"],
     ["--out batch holds a batch of reconstructions, not a benchmark run"]),
    ("reconstruct --force into a batch", ("batch",), [*_reconstruct("batch", "--force")(None)],
     ["--out batch holds a batch of reconstructions, not one photo's reconstruction"]),
    ("a batch --force into a reconstruction", ("rec", "photos"), [*BATCH, "--out", "rec", "--force"],
     ["--out rec holds one photo's reconstruction, not a batch"]),
    ("compare's page into a reconstruction", ("run", "rec"), ["compare", "run", "run", "--html", "rec/c.html"],
     ["--html rec holds one photo's reconstruction"]),
]


@pytest.mark.parametrize("case, copy, args, needles", KIND_CASES, ids=[c[0] for c in KIND_CASES])
def test_no_command_crosses_kinds(case, copy, args, needles, made, tmp_path):
    _copy(made, tmp_path, *copy)
    before = snapshot(tmp_path)
    one_line_error(fenestra(*args, cwd=tmp_path), *needles)
    assert snapshot(tmp_path) == before


def test_an_older_manifest_without_kind_has_its_files_kind(made, tmp_path):
    """A run made before folders recorded their kind: its manifest lists run.json, so it is a run."""
    _copy(made, tmp_path, "run")
    m = tmp_path / "run" / outputs.MANIFEST
    doc = json.loads(m.read_text())
    m.write_text(json.dumps({"format": doc["format"], "files": doc["files"]}))
    before = snapshot(tmp_path)
    one_line_error(fenestra(*_reconstruct("run", "--force")(tmp_path), cwd=tmp_path), "--out run holds a benchmark run")
    assert snapshot(tmp_path) == before


def test_bench_report_compare_bench_needs_no_rm(made, tmp_path):
    """The documented loop: a run, its report, a comparison page written into it, the run again
    (its earlier report and page cleared, nothing refused), and gate's verdict on it."""
    _copy(made, tmp_path, "run", "tiny.toml")
    shutil.copytree(tmp_path / "run", tmp_path / "base")
    assert fenestra("report", "run", cwd=tmp_path).returncode == 0
    r = fenestra("compare", "base", "run", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    listed = outputs.read_manifest(tmp_path / "run")
    assert {"report.html", "report.md", "compare-base.html", "figures/index.json"} <= set(listed)
    assert outputs.foreign_files(tmp_path / "run") == []  # everything the report and compare wrote is listed
    r = fenestra(*TINY_BENCH, "--out", "run", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    left = {p.name for p in (tmp_path / "run").iterdir()}
    assert not left & {"report.html", "report.md", "compare-base.html", "figures"}  # nothing stale beside new results
    assert json.loads((tmp_path / "run" / "run.json").read_text())["status"] == "complete"


# (case, builder -> command line, needles): a writer of one file never replaces a file Fenestra did
# not write, nor one of its inputs; the folder is byte for byte as before
def _user_file(rel: str, data: bytes = b"the user's"):
    def make(d: Path) -> None:
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_bytes(data)
    return make


def _case(copy: tuple, makers: tuple, args: list):
    def build(made: Path, d: Path) -> list:
        _copy(made, d, *copy)
        for m in makers:
            m(d)
        return args
    return build


WRITER_CASES = [
    ("compare --html over a user's page", _case(("run",), (_user_file("mine.html"),), ["compare", "run", "run", "--html", "mine.html"]),
     ["would replace mine.html, which Fenestra did not write"]),
    ("compare --html over the baseline's results.parquet", _case(("run",), (), ["compare", "run", "run", "--html", "run/results.parquet"]),
     ["--html run/results.parquet", "an .html file"]),
    ("compare --html over a photo", _case(("run",), (lambda d: shutil.copy(EXAMPLE / "img017.jpg", d / "img017.jpg"),),
                                          ["compare", "run", "run", "--html", "img017.jpg"]),
     ["--html img017.jpg", "an .html file"]),
    ("compare --html over the run's own report page", _case(("run",), (), ["compare", "run", "run", "--html", "run/report.html"]),
     ["named compare-*.html"]),
    ("compare --method with a typo", _case(("run",), (), ["compare", "run", "run", "--method", "oracle/nnoe/lm"]),
     ["--method 'oracle/nnoe/lm' is in neither run", "oracle/none/lm"]),
    ("report over a user's figure in the run", _case(("run",), (_user_file("run/figures/recall_curves.png"),), ["report", "run"]),
     ["would replace figures/recall_curves.png, which Fenestra did not write"]),
    ("report over a user's report.md in the run", _case(("run",), (_user_file("run/report.md"),), ["report", "run"]),
     ["would replace report.md"]),
    ("calibrate --out over its own input photo", _case((), (lambda d: shutil.copy(EXAMPLE / "img017.jpg", d / "board.jpg"),),
                                                      ["calibrate", "board.jpg", "--pattern", "9x6", "--out", "board.jpg"]),
     ["--out board.jpg is an input of this command"]),
    ("calibrate --out over a user's K.json", _case((), (_user_file("K.json"), lambda d: shutil.copy(EXAMPLE / "img017.jpg", d / "board.jpg")),
                                                   ["calibrate", "board.jpg", "--pattern", "9x6", "--out", "K.json"]),
     ["would replace K.json, which Fenestra did not write"]),
    ("scenes make over a user's IFC", _case((), (_user_file("house.ifc"),), ["scenes", "make", "house.ifc"]),
     ["would replace house.ifc, which Fenestra did not write"]),
    ("scenes make into a reconstruction", _case(("rec",), (), ["scenes", "make", "rec/house.ifc"]),
     ["--out rec holds one photo's reconstruction"]),
    ("scenes author over a user's authored-studio.ifc", _case((), (_user_file("houses/authored-studio.ifc"),),
                                                               ["scenes", "author", "houses"]),
     ["would replace authored-studio.ifc, which Fenestra did not write"]),
]


@pytest.mark.parametrize("case, build, needles", WRITER_CASES, ids=[c[0] for c in WRITER_CASES])
def test_no_writer_replaces_what_is_not_its_own(case, build, needles, made, tmp_path):
    args = build(made, tmp_path)
    before = snapshot(tmp_path)
    one_line_error(fenestra(*args, cwd=tmp_path), *needles)
    assert snapshot(tmp_path) == before


def test_single_file_writers_replace_their_own_file(tmp_path):
    """A second `scenes make` (another seed) replaces the first file, which Fenestra listed; the
    user's file beside it stays; `scenes author` writes twice into one folder."""
    (tmp_path / "notes.txt").write_text("the user's")
    for seed in (1, 2):
        r = fenestra("scenes", "make", "house.ifc", "--seed", str(seed), cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-2000:]
    assert outputs.read_manifest(tmp_path)["house.ifc"] == outputs.file_sha256(tmp_path / "house.ifc")
    assert outputs.read_kind(tmp_path) == "files" and (tmp_path / "notes.txt").read_text() == "the user's"
    for _ in range(2):
        r = fenestra("scenes", "author", "houses", cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-2000:]
    assert sorted(outputs.read_manifest(tmp_path / "houses")) == ["authored-studio.ifc", "authored-terrace.ifc"]


def test_gate_fails_a_run_whose_listed_run_json_is_gone(tmp_path):
    args = run_with_status("complete")(tmp_path)
    assert fenestra(*args, cwd=tmp_path).returncode == 0  # the sealed run passes as it is
    outputs.record(tmp_path / "run", ["run.json"])  # as bench lists it
    (tmp_path / "run" / "run.json").unlink()
    one_line_error(fenestra(*args, cwd=tmp_path), "run/run.json is missing", "lists it")


# ---------------------------------------------------------------- one reconstruct at a time

def test_a_second_reconstruct_into_a_folder_is_refused_up_front(tmp_path):
    """While a process holds the folder, a reconstruct into it stops at once (before its pipeline),
    naming that process, and changes nothing."""
    assert reconstruct("o", cwd=tmp_path).returncode == 0
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from fenestra import outputs\n"
                               "with outputs.locked(sys.argv[1], 'reconstruct'):\n print('held', flush=True); time.sleep(60)",
                               str(tmp_path / "o")], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])})
    try:
        assert holder.stdout.readline().strip() == "held"
        before = snapshot(tmp_path)
        r = reconstruct("o", cwd=tmp_path)
        one_line_error(r, f"o is in use by process {holder.pid}")
        assert "intrinsics:" not in r.stdout  # refused before the pipeline ran
        assert snapshot(tmp_path) == before
    finally:
        holder.kill()
        holder.wait()


def test_staging_folders_of_dead_processes_are_cleaned(tmp_path):
    """A reconstruct killed mid-write (kill -9) leaves its staging folder; the next one into the
    folder removes it (and an older Fenestra's), never one of a live process."""
    assert reconstruct("o", cwd=tmp_path).returncode == 0
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = [tmp_path / "o" / f"{outputs.STAGE_PREFIX}{dead.pid}-abc", tmp_path / "o" / f"{outputs.STAGE_PREFIX}k2j4_x"]
    live = tmp_path / "o" / f"{outputs.STAGE_PREFIX}{os.getpid()}-abc"
    for s in (*stale, live):
        s.mkdir()
        (s / "windows.json").write_text("{}")
    assert reconstruct("o", cwd=tmp_path).returncode == 0
    assert not any(s.exists() for s in stale) and (live / "windows.json").is_file()


def test_a_killed_runs_half_written_files_do_not_block_the_next_run(made, tmp_path):
    """kill -9 while a file was being written leaves its temporary name (fenestra.files.temp_name)
    of a process that is gone: the next run of the folder removes it and runs; one of a live
    process is not Fenestra's to remove, and is refused by name."""
    from fenestra.files import temp_name

    _copy(made, tmp_path, "run", "tiny.toml")
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    run = tmp_path / "run"
    (run / ".rows").mkdir()
    half = [temp_name(run / "results.parquet", dead.pid), temp_name(run / ".rows" / "000001.parquet", dead.pid)]
    for h in half:
        h.write_bytes(b"PAR1 half")
    live = temp_name(run / "run.json", os.getpid())
    live.write_text("{")
    one_line_error(fenestra(*TINY_BENCH, "--out", "run", cwd=tmp_path), live.name, "did not write")
    assert all(not h.exists() for h in half)  # a dead process's temporary files: removed
    live.unlink()
    r = fenestra(*TINY_BENCH, "--out", "run", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]


@pytest.mark.parametrize("after_s", [0.5, 4.0])
def test_a_bench_run_killed_at_any_point_runs_again(made, tmp_path, after_s):
    """kill -9 of a bench run (the whole process group: its workers and its report's process too)
    some time after it claimed its folder (evaluating, or writing its report: every file is listed
    before it takes its name); the same command then runs to the end in that folder, and --force
    with another profile replaces what is left."""
    import signal
    import time

    from fault_helpers import env

    _copy(made, tmp_path, "tiny.toml")
    shutil.copytree(made / "out", tmp_path / "out")  # the render cache: the run starts evaluating at once
    run = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-m", "fenestra", *TINY_BENCH[:-1], "--out", "run"], cwd=tmp_path, env=env(),
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not (run / "run.json").exists() and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(after_s)
    finally:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
    r = fenestra(*TINY_BENCH, "--out", "run", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert json.loads((run / "run.json").read_text())["status"] == "complete"
    (tmp_path / "other.toml").write_text(TINY_PROFILE.replace('name = "tiny"', 'name = "other"'))
    r = fenestra("bench", "--profile", "other.toml", "--workers", "1", "--no-report", "--out", "run", "--force",
                 cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
