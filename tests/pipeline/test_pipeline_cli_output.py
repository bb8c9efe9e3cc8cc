"""What `fenestra reconstruct` says and writes for a user (issue 35 item 5): help that names every
option in full with examples, a one-line note when the output holds no window, and a batch summary
with each photo's time and sizes, also as summary.csv."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import typer
from typer.testing import CliRunner

from fenestra.pipeline import cli as pipeline_cli


def _app() -> typer.Typer:
    app = typer.Typer()
    pipeline_cli.register(app)
    return app


def test_help_names_every_option_in_full_and_shows_examples():
    """At 80 columns rich's table cut names short (``--known-height,--heig…``)."""
    out = CliRunner().invoke(_app(), ["reconstruct", "--help"], env={"COLUMNS": "80"}).output
    assert "…" not in out
    for name in ("--known-height, --height", "--known-width, --width", "--known-storey", "--export-all",
                 "--max-pixels", "--quad-source", "--substitute"):
        assert name in out, name
    assert "Examples:" in out and "fenestra reconstruct street.jpg --out out/street" in out
    assert max(len(line) for line in out.splitlines()) <= 80


def _blank_with_blob(tmp_path: Path) -> tuple[Path, Path]:
    photo, masks = tmp_path / "blank.png", tmp_path / "masks.png"
    cv2.imwrite(str(photo), np.full((240, 320, 3), 128, np.uint8))
    inst = np.zeros((240, 320), np.uint16)
    inst[100:102, 100:102] = 1  # a 2 x 2 px blob: detected, no quad
    cv2.imwrite(str(masks), inst)
    return photo, masks


def test_an_empty_output_says_so_in_one_line(tmp_path):
    """img_552 wrote an empty model.ifc and model.obj with nothing said (issue 35)."""
    photo, masks = _blank_with_blob(tmp_path)
    res = CliRunner().invoke(_app(), ["reconstruct", str(photo), "--masks", str(masks), "--snapper", "none",
                                      "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    notes = [line for line in res.output.splitlines() if line.startswith("empty output")]
    assert notes == ["empty output: none of the 1 detected windows exported (0 flagged implausible, 1 failed; "
                     "--export-all exports the flagged); model.ifc and model.obj hold no window, no model.glb"]
    assert (tmp_path / "out" / "model.ifc").is_file() and not (tmp_path / "out" / "model.glb").exists()
    # a photo whose windows are exported says nothing of the kind
    img, inst = np.full((480, 640, 3), 200, np.uint8), np.zeros((480, 640), np.uint16)
    for i, (x, y) in enumerate([(x, y) for y in (100, 260) for x in (100, 250, 400)], 1):
        img[y:y + 90, x:x + 60], inst[y:y + 90, x:x + 60] = 40, i
    cv2.imwrite(str(tmp_path / "p.png"), img)
    cv2.imwrite(str(tmp_path / "m.png"), inst)
    res = CliRunner().invoke(_app(), ["reconstruct", str(tmp_path / "p.png"), "--masks", str(tmp_path / "m.png"),
                                      "--snapper", "none", "--out", str(tmp_path / "six")])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "six" / "windows.json").read_text())
    assert sum(w["exported"] for w in doc["windows"]) == 6 and "empty output" not in res.output


def test_batch_summary_has_time_and_sizes_and_a_csv(tmp_path):
    folder = tmp_path / "photos"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for name, (h, w) in (("one.png", (160, 200)), ("two.png", (120, 240))):
        cv2.imwrite(str(folder / name), rng.integers(0, 255, (h, w, 3), dtype=np.uint8))
    (folder / "broken.jpg").write_bytes(b"not a photo")
    out = tmp_path / "out"
    res = CliRunner().invoke(_app(), ["reconstruct", str(folder), "--out", str(out)])
    assert res.exit_code == 1, res.output  # the broken photo
    with open(out / "summary.csv", newline="") as f:
        rows = {Path(r["photo"]).name: r for r in csv.DictReader(f)}
    assert list(next(iter(rows.values()))) == list(pipeline_cli.SUMMARY_CSV_COLUMNS)
    assert set(rows) == {"one.png", "two.png", "broken.jpg"} and rows["broken.jpg"]["error"]
    for name, (h, w) in (("one.png", (160, 200)), ("two.png", (120, 240))):
        r = rows[name]
        assert (int(r["width_px"]), int(r["height_px"])) == (w, h) and r["error"] == ""
        assert int(r["photo_bytes"]) == (folder / name).stat().st_size
        stem = Path(name).stem
        assert int(r["output_bytes"]) == sum(p.stat().st_size for p in (out / stem).rglob("*") if p.is_file())
        assert 0 < float(r["seconds"]) < 600 and float(r["cpu_s"]) > 0
    js = {Path(r["photo"]).name: r for r in json.loads((out / "summary.json").read_text())}
    assert js["one.png"]["seconds"] == float(rows["one.png"]["seconds"])
    header = next(line for line in res.output.splitlines() if line.startswith("photo"))
    assert "time_s" in header and "size_px" in header and "out_MB" in header
    assert any(line.startswith("one.png") and " 200x160 " in line for line in res.output.splitlines())
    assert "summary.csv" in res.output
