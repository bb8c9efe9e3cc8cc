"""Every user error is one line with exit 2 naming the file or field, never echoing an unbounded
value: a dataset's symlink loop, an adapter option it does not take, a WebP header of a huge
size, K.json nested deeply or holding a 5000-digit number, a long distortion list, a malformed
summary.json, a file name that is not UTF-8 in a benchmark's dataset; a CSV-only run read as
written; the Python API's Known; Ctrl-C while the command line loads.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fault_helpers import (EXAMPLE, env, fenestra, one_line_error, run_with_status, yolo_case)

K = [[1000.0, 0, 383.5], [0, 1000.0, 511.5], [0, 0, 1]]


def with_K(text: str):
    """A builder: K.json holding ``text``, reconstructing the example photo with it."""
    def build(d: Path) -> list:
        (d / "K.json").write_text(text)
        return ["reconstruct", EXAMPLE / "img017.jpg", "--K", "K.json", "--masks", EXAMPLE / "panes017.png", "--out", "o"]
    return build


def webp_of(w: int, h: int):
    """A builder: a WebP file whose VP8X chunk states a w x h canvas (and a few bytes of nothing else)."""
    def build(d: Path) -> list:
        vp8x = b"VP8X" + struct.pack("<I", 10) + bytes(4) + (w - 1).to_bytes(3, "little") + (h - 1).to_bytes(3, "little")
        body = b"WEBP" + vp8x + b"VP8L" + struct.pack("<I", 8) + bytes(8)
        (d / "big.webp").write_bytes(b"RIFF" + struct.pack("<I", len(body)) + body)
        return ["reconstruct", "big.webp", "--fx", "1000", "--out", "o"]
    return build


def looping_data(d: Path) -> list:
    os.symlink("b", d / "a")
    os.symlink("a", d / "b")
    return ["bench", "--profile", "real", "--data", "a", "--format", "yolo", "--out", "run"]


def summary_of(text: str, command: str):
    """A builder: a complete run folder whose summary.json holds ``text``, read by ``command``
    (gate, report, or compare with a good copy of the run)."""
    def build(d: Path) -> list:
        gate = run_with_status("complete")(d)
        shutil.copytree(d / "run", d / "good")
        (d / "run" / "summary.json").write_text(text)
        return {"gate": gate, "report": ["report", "run"], "compare": ["compare", "good", "run"]}[command]
    return build


NOT_UTF8 = os.fsdecode(b"fa\xe7ade-\xff")


def non_utf8_photo(d: Path) -> list:
    """A YOLO dataset of two photos, the second named in bytes that are not UTF-8."""
    yolo_case("0 0.5 0.5 0.2 0.2\n")(d)
    shutil.copy(d / "ds" / "images" / "a.png", d / "ds" / "images" / f"{NOT_UTF8}.png")  # (cv2.imwrite of such a name crashes)
    (d / "ds" / "labels" / f"{NOT_UTF8}.txt").write_text("0 0.5 0.5 0.2 0.2\n")
    return ["bench", "--profile", "real", "--data", "ds", "--format", "yolo", "--out", "run", "--no-report"]


# (case, builder of the input in a fresh folder -> command line, the one error line's needles)
FAULTS = [
    ("--data a symlink loop", looping_data, ["--data 'a' is a symlink loop"]),
    ("check-data --option bogus=1", lambda d: [*yolo_case("")(d), "--option", "bogus=1"],
     ["dataset format 'yolo' has no option 'bogus'; its options: images, labels, classes, dataset, every"]),
    ("photo a WebP stating 16383 x 16383 px", webp_of(16383, 16383),
     ["big.webp is 16383x16383 = 268 Mpx, over the limit of 150 Mpx"]),
    ("K.json nested 100000 deep", with_K('{"K": ' + "[" * 100000 + "]" * 100000 + "}"),
     ["cannot read intrinsics JSON K.json: nested too deeply"]),
    ("K.json with a 5000-digit number", with_K(json.dumps({"K": K}).replace("1000.0", "1" + "0" * 5000, 1)),
     ["cannot read intrinsics JSON K.json:", "4300 digits"]),
    ("K.json with 50000 distortion coefficients", with_K(json.dumps({"K": K, "distortion": [0.1] * 50000})),
     ["K.json: bad distortion", "got [0.1, 0.1,", "... (250000 characters)"]),
    *[(f"{cmd} on a summary.json {what}", summary_of(text, cmd), [f"run summary {Path('run', 'summary.json')}", why])
      for cmd in ("gate", "report", "compare")
      for what, text, why in (("that is a list", "[]", "must be a JSON object with 'metadata' and 'results', got list"),
                              ("whose metadata is a number", '{"metadata": 3, "results": {}}',
                               "'metadata' must be a JSON object, got 3"),
                              ("that is not JSON", "not json", "is not valid JSON"))],
    ("bench --data with a photo name that is not UTF-8", non_utf8_photo,
     ["ds: photo 'fa\\udce7ade-\\udcff': the name is not valid UTF-8, which a results table cannot hold; rename it"]),
]


@pytest.mark.parametrize("case, build, needles", FAULTS, ids=[c for c, _, _ in FAULTS])
def test_a_user_error_is_one_bounded_line(case, build, needles, tmp_path):
    from fenestra.errors import MAX_LINE_CHARS

    args = build(tmp_path)
    line = one_line_error(fenestra(*args, cwd=tmp_path, timeout=180), *needles)
    assert len(line) <= len("error: ") + MAX_LINE_CHARS, len(line)


def test_a_photo_that_is_a_symlink_loop_is_left_out_with_its_reason(tmp_path):
    yolo_case("0 0.5 0.5 0.2 0.2\n")(tmp_path)
    os.symlink("c.png", tmp_path / "ds" / "images" / "b.png")
    os.symlink("b.png", tmp_path / "ds" / "images" / "c.png")
    r = fenestra("check-data", "ds", "--format", "yolo", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "1 photo(s), 1 window(s), 2 refused" in r.stdout, r.stdout
    assert "ds/images/b.png: ds/images: 'b.png' is a symlink loop (it cannot be resolved); skipped" in r.stdout, r.stdout


def test_a_csv_only_run_keeps_its_view_ids(tmp_path):
    """A run whose results.parquet is gone is read from its results.csv with its view ids as
    written ("000000", which CSV would turn into the integer 0), so the manifest's rows match."""
    from fenestra.bench import results

    args = run_with_status("complete")(tmp_path)
    df = results.load_results(tmp_path / "run")
    results.write_results(df, tmp_path / "run", csv=True)
    (tmp_path / "run" / "results.parquet").unlink()
    views = results.load_results(tmp_path / "run")["view"]
    assert views.tolist() == df["view"].tolist() and views.iloc[0] == "000000"
    r = fenestra(*args, cwd=tmp_path)
    assert r.returncode == 0 and "all gates passed" in r.stdout, r.stderr[-2000:]


@pytest.mark.parametrize("field, value", [("window_height_m", 1e300), ("window_width_m", float("nan")),
                                          ("storey_m", 0.5), ("window_height_m", "1.5"), ("storey_m", True)])
def test_known_from_python_names_the_field_out_of_range(field, value):
    from fenestra import Known

    with pytest.raises(ValueError, match=rf"Known\.{field} must be a length in m within the physical range"):
        Known(**{field: value})


@pytest.mark.parametrize("delay_s", [0.02, 0.1, 0.3])
def test_ctrl_c_while_the_command_line_loads_is_one_line(delay_s, tmp_path):
    """Ctrl-C while Fenestra's stages load (the first half second): exit 130 and one line, no
    traceback. It is sent ``delay_s`` after the interpreter reports the ``fenestra`` package imported
    (``-X importtime``; before, Python's own start-up is not Fenestra's to handle). The child gets
    SIGINT's default disposition (see test_cli_faults.test_ctrl_c_prints_interrupted)."""
    p = subprocess.Popen([sys.executable, "-X", "importtime", "-m", "fenestra", "scenes", "list"], cwd=tmp_path,
                         env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    seen = []
    while not seen or not seen[-1].rstrip().endswith("| fenestra"):
        seen.append(p.stderr.readline())
        assert seen[-1], "the child ended before importing fenestra: " + "".join(seen[-20:])
    time.sleep(delay_s)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert "Traceback" not in err, err[-2000:]
    assert p.returncode == 130, (p.returncode, err[-2000:])
    assert [ln for ln in err.splitlines() if ln.startswith("error: ")] in (
        ["error: interrupted; nothing was written"], ["error: interrupted; partial outputs removed"]), err[-2000:]
