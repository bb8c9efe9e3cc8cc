"""Output folders by kind, and every writer under the ownership rule: no command replaces or deletes
what is not its own kind of output, nor a file it did not write, nor its own input; a bench run
lists its report and comparison pages, so bench -> report -> compare -> bench needs no rm; one
reconstruct at a time into a folder; gates and comparisons that cannot pass vacuously.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fenestra import outputs

from fault_helpers import (EXAMPLE, RENDER_ARGS, TINY_PROFILE, _photo, _reconstruct, fenestra, one_line_error,
                           reconstruct, run_with_status)
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
    ("reconstruct into a new folder inside a bench run", ("run",), [*_reconstruct("run/sub")(None)],
     ["--out run/sub lies inside", "which holds a benchmark run"]),
    ("bench into a new folder inside a reconstruction", ("rec", "tiny.toml"), [*TINY_BENCH, "--out", "rec/run"],
     ["--out rec/run lies inside", "which holds one photo's reconstruction"]),
    ("a batch into a photo's folder of a batch", ("batch", "photos"), [*BATCH, "--out", "batch/p0/more"],
     ["lies inside", "p0, which holds one photo's reconstruction"]),
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


ROOT = Path(__file__).resolve().parents[2]
WEIGHTS = ROOT / "fenestra" / "pipeline" / "models" / "winnet.pt"  # a real weights file, shipped
CONFIGS = ROOT / "fenestra" / "training" / "configs"
METRICS = json.dumps({"detector": "oracle", "dataset": "ds", "n_images": 3})  # what evaluate-detector --json writes


def _dataset(d: Path) -> str:
    """The render cache's one dataset folder (the tiny bench run's renders, copied from `made`)."""
    return str(next((d / "out" / "renders").iterdir()).relative_to(d))


def _copied(src: Path, rel: str):
    def make(d: Path) -> None:
        shutil.copy(src, d / rel)
    return make


def _on_renders(*args: str):
    """A builder: `made`'s render cache copied; the command line ``args`` ({ds}: its dataset)."""
    def build(made: Path, d: Path) -> list:
        _copy(made, d, "out")
        return [a.format(ds=_dataset(d)) for a in args]
    return build


def _evaluate(json_out: str):
    return _on_renders("evaluate-detector", "--data", "{ds}", "--detector", "oracle", "--json", json_out)


def _train(out: str, config: str = str(CONFIGS / "winnet.toml")):
    return _on_renders("train", "--config", config, "--data", "{ds}", "--iterations", "1", "--out", out)


def _init_config(d: Path) -> None:
    """configs/init.toml: WinNet starting from init.pt (a copy of the shipped weights)."""
    shutil.copytree(CONFIGS, d / "configs")
    (d / "configs" / "init.toml").write_text('based_on = "winnet.toml"\n[train]\ninit_weights = "init.pt"\n')
    shutil.copy(WEIGHTS, d / "init.pt")


def _rendered(d: Path) -> None:
    """A dataset rendered by `fenestra render` into renders/, its coco.json then edited by the user."""
    r = fenestra(*RENDER_ARGS, "--out", "renders", cwd=d)
    assert r.returncode == 0, r.stderr[-2000:]
    next((d / "renders").iterdir()).joinpath("coco.json").write_text("the user's")


def _then_call(build, *makers):
    def b(made: Path, d: Path) -> list:
        args = build(made, d)
        for m in makers:
            m(d)
        return args
    return b


# (case, builder, needles): the writers that once bypassed fenestra.outputs (evaluate-detector
# --json, ship-weights --to, train --out, report --markdown, render --out)
WRITER_CASES += [
    ("evaluate-detector --json over a user's file", _then_call(_evaluate("mine.json"), _user_file("mine.json")),
     ["--json .: would replace mine.json, which Fenestra did not write"]),
    ("evaluate-detector --json into its dataset", _evaluate("{ds}/metrics.json"),
     ["--json", "metrics.json lies inside the input folder"]),
    ("evaluate-detector --json over a metrics file no manifest lists", _then_call(_evaluate("m.json"), _user_file("m.json", METRICS.encode())),
     ["--json m.json is a detector evaluation's metrics file that Fenestra did not list", "pass --force"]),
    ("ship-weights --to over a user's file", _case((), (_copied(WEIGHTS, "w.pt"), _user_file("mine.pt")),
                                                   ["lab.ship", "w.pt", "--to", "mine.pt"]),
     ["--to .: would replace mine.pt, which Fenestra did not write"]),
    ("ship-weights --to the weights it reads", _case((), (_copied(WEIGHTS, "w.pt"),), ["lab.ship", "w.pt", "--to", "w.pt"]),
     ["--to w.pt is an input of this command"]),
    ("ship-weights --to weights no manifest lists", _case((), (_copied(WEIGHTS, "w.pt"), _copied(WEIGHTS, "old.pt")),
                                                          ["lab.ship", "w.pt", "--to", "old.pt"]),
     ["--to old.pt is a weights file that Fenestra did not list", "pass --force"]),
    ("train --out over a user's file", _then_call(_train("mine.pt"), _user_file("mine.pt")),
     ["--out .: would replace mine.pt, which Fenestra did not write"]),
    ("train --out over its --init-weights", _then_call(_train("init.pt", "configs/init.toml"), _init_config),
     ["--out init.pt is an input of this command"]),
    ("train --out into its dataset", _train("{ds}/w.pt"),
     ["lies inside the input folder"]),
    ("report --markdown over a user's page", _case(("run",), (_user_file("mine.md"),), ["lab.docs", "run", "--markdown", "mine.md"]),
     ["--markdown .: would replace mine.md, which Fenestra did not write"]),
    ("report --markdown over a user's summary", _case(("run",), (_user_file("docs/results/summary.json"),),
                                                      ["lab.docs", "run", "--markdown", "docs/results.md"]),
     ["would replace summary.json, which Fenestra did not write"]),
    ("report --markdown into the run", _case(("run",), (), ["lab.docs", "run", "--markdown", "run/results.md"]),
     ["--markdown run/results.md lies inside the input folder run"]),
    ("report --markdown over the run's results", _case(("run",), (), ["lab.docs", "run", "--markdown", "run/results.parquet"]),
     ["--markdown run/results.parquet", "a .md file"]),
    ("render --out into a bench run", _case(("run",), (), [*RENDER_ARGS, "--out", "run"]),
     ["--out run holds a benchmark run, not a rendered dataset"]),
    ("render --out into a reconstruction's folder", _case(("rec",), (), [*RENDER_ARGS, "--out", "rec/renders"]),
     ["--out rec/renders lies inside", "one photo's reconstruction"]),
    ("render --out a file", _case((), (_user_file("renders"),), [*RENDER_ARGS, "--out", "renders"]),
     ["--out renders is an existing file"]),
    ("render over a dataset's file the user changed", _case((), (_rendered,), [*RENDER_ARGS, "--out", "renders"]),
     ["would replace coco.json, which Fenestra did not write (or which changed since)"]),
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


def _listed(folder: Path, *names: str) -> bool:
    """True if ``folder``'s manifest lists each of ``names`` with the file's current digest."""
    owned = outputs.read_manifest(folder) or {}
    return all(owned.get(n) == outputs.file_sha256(folder / n) for n in names)


def test_ship_weights_lists_what_it_ships_and_force_replaces_only_weights(tmp_path):
    """ship-weights lists its copy; shipping again replaces it; --force replaces a weights file
    no manifest lists (refused without it, above), never a user's file; the checkout's shipped
    weights are listed, so `python -m lab.ship out/train/default.pt` replaces them."""
    shutil.copy(WEIGHTS, tmp_path / "w.pt")
    shutil.copy(WEIGHTS.with_name("refine.pt"), tmp_path / "old.pt")
    (tmp_path / "mine.pt").write_text("the user's")
    r = fenestra("lab.ship", "w.pt", "--to", "old.pt", "--force", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / "old.pt").read_bytes() == WEIGHTS.read_bytes() and _listed(tmp_path, "old.pt")
    assert fenestra("lab.ship", "w.pt", "--to", "old.pt", cwd=tmp_path).returncode == 0  # its own file now
    one_line_error(fenestra("lab.ship", "w.pt", "--to", "mine.pt", "--force", cwd=tmp_path), "would replace mine.pt")
    assert (tmp_path / "mine.pt").read_text() == "the user's"
    shipped = sorted(p.name for p in WEIGHTS.parent.glob("*.pt"))
    assert _listed(WEIGHTS.parent, *shipped) and len(shipped) == 5


def test_train_writes_its_files_atomically_and_lists_them(tmp_path):
    """A tiny WinNet run: the weights, the training state and the loss log are listed with their
    digests (no temporary file left); the run again replaces them; a weights file the user
    changed since is refused before any data is read."""
    from fenestra.files import TEMP_NAME
    from fenestra.training.train import load_config, train
    from toy_data import write_toy_dataset

    ds = write_toy_dataset(tmp_path / "toy", n_views=3, seed=4)
    out = tmp_path / "train"
    cfg = load_config(CONFIGS / "winnet.toml", data=(str(ds),), out=str(out / "w.pt"), state_dir=str(out),
                      iterations=2, batch_size=2, crop_hw=(64, 64), log_every=1, save_every=1, warmup=1, threads=1)
    for _ in range(2):
        assert train(cfg, log=lambda *_: None) == out / "w.pt"
        assert _listed(out, "w.pt", "w.state.pt", "w.loss.csv")
        assert not [p for p in out.iterdir() if TEMP_NAME.fullmatch(p.name)]
    (out / "w.pt").write_bytes(b"the user's")
    with pytest.raises(outputs.OwnershipError, match="would replace w.pt, which Fenestra did not write"):
        train(dataclasses.replace(cfg, data=(str(tmp_path / "missing"),)), log=lambda *_: None)
    assert (out / "w.pt").read_bytes() == b"the user's"


def test_report_markdown_lists_its_pages_and_force_replaces_only_generated_ones(made, tmp_path):
    """lab.docs (the results docs) lists the results page and its summary; a second run replaces them; a
    generated page that no manifest lists (a checkout's committed docs) needs --force."""
    _copy(made, tmp_path, "run")
    docs = tmp_path / "docs"
    for _ in range(2):
        r = fenestra("lab.docs", "run", "--markdown", "docs/results.md", cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-2000:]
    assert _listed(docs, "results.md") and _listed(docs / "results", "summary.json")
    (docs / outputs.MANIFEST).unlink()
    one_line_error(fenestra("lab.docs", "run", "--markdown", "docs/results.md", cwd=tmp_path),
                   "docs/results.md is a generated results page that Fenestra did not list", "--force")
    r = fenestra("lab.docs", "run", "--markdown", "docs/results.md", "--force", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert _listed(docs, "results.md")


def test_render_lists_its_dataset_and_recognises_an_older_one(tmp_path):
    """render lists every file of the dataset it writes (kind: a rendered dataset); rendering it
    again reuses it; a dataset without manifest (an older Fenestra's) whose config.json is this
    config's is recognised and listed; one whose config.json is another's is refused."""
    for _ in range(2):
        r = fenestra(*RENDER_ARGS, "--out", "renders", cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-2000:]
    ds = next((tmp_path / "renders").iterdir())
    assert outputs.read_kind(ds) == "dataset" and outputs.foreign_files(ds) == []
    assert "views/000002/image.png" in outputs.read_manifest(ds)
    (ds / outputs.MANIFEST).unlink()
    assert fenestra(*RENDER_ARGS, "--out", "renders", cwd=tmp_path).returncode == 0
    assert outputs.foreign_files(ds) == [] and outputs.read_kind(ds) == "dataset"
    (ds / outputs.MANIFEST).unlink()
    doc = json.loads((ds / "config.json").read_text())
    (ds / "config.json").write_text(json.dumps({**doc, "scene_sha256": "0" * 64}))
    before = snapshot(tmp_path)
    one_line_error(fenestra(*RENDER_ARGS, "--out", "renders", cwd=tmp_path),
                   f"{ds.name} holds files Fenestra did not render for this config")
    assert snapshot(tmp_path) == before


def test_evaluate_detector_json_replaces_its_own_metrics(made, tmp_path):
    """evaluate-detector --json lists its metrics file; a second run replaces it; --force replaces
    a metrics file no manifest lists (refused without it, above)."""
    args = _evaluate("m.json")(made, tmp_path)
    (tmp_path / "m.json").write_text(METRICS)
    for extra in (["--force"], []):
        r = fenestra(*args, *extra, cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-2000:]
        assert _listed(tmp_path, "m.json") and json.loads((tmp_path / "m.json").read_text())["n_images"] == 3


def test_gate_fails_a_run_whose_listed_run_json_is_gone(tmp_path):
    args = run_with_status("complete")(tmp_path)
    assert fenestra(*args, cwd=tmp_path).returncode == 0  # the sealed run passes as it is
    outputs.record(tmp_path / "run", ["run.json"])  # as bench lists it
    (tmp_path / "run" / "run.json").unlink()
    one_line_error(fenestra(*args, cwd=tmp_path), "run/run.json is missing", "lists it")


# ---------------------------------------------------------------- one reconstruct at a time

def test_a_second_reconstruct_into_a_folder_is_refused_up_front(tmp_path):
    """While a process holds the folder, a reconstruct into it stops at once (before its pipeline),
    naming the command and the process that hold it, and changes nothing. The holder is a process
    whose command line reads as the CLI's (`fenestra reconstruct ...`), holding the lock as
    reconstruct does."""
    assert reconstruct("o", cwd=tmp_path).returncode == 0
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from fenestra import outputs\n"
                               "out = sys.argv[1]; sys.argv = ['/usr/bin/fenestra', 'reconstruct', 'p.jpg', '--out', out]\n"
                               "with outputs.locked(out, 'reconstruct'):\n print('held', flush=True); time.sleep(60)",
                               str(tmp_path / "o")], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])})
    try:
        assert holder.stdout.readline().strip() == "held"
        before = snapshot(tmp_path)
        r = reconstruct("o", cwd=tmp_path)
        one_line_error(r, f"o is in use by `fenestra reconstruct` (process {holder.pid})")
        assert "intrinsics:" not in r.stdout  # refused before the pipeline ran
        assert snapshot(tmp_path) == before
    finally:
        holder.kill()
        holder.wait()


def test_a_lock_names_its_holder_in_one_bounded_line():
    """What a lock file records, as the refusal names it: the CLI's command, another program's
    name, an older Fenestra's bare process id; a long or multi-line command stays one short line."""
    assert outputs.running_command(["/venv/bin/fenestra", "bench", "--out", "x"]) == "fenestra bench"
    assert outputs.running_command([".../fenestra/__main__.py", "reconstruct", "a.jpg"]) == "fenestra reconstruct"
    assert outputs.running_command(["/usr/bin/my-script", "--out", "o"]) == "my-script"
    assert outputs.lock_holder("1234 fenestra batch\n") == "`fenestra batch` (process 1234)"
    assert outputs.lock_holder("1234\n") == "process 1234"
    long = outputs.lock_holder("7 " + "x\n`y" * 5000)
    assert "\n" not in long and len(long) < 200 and long.count("`") == 2


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
