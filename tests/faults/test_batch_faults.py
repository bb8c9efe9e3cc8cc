"""A batch of photos (`fenestra reconstruct FOLDER --out DIR`): one folder per photo inside DIR,
always, whatever the photos are named; a photo's failure is recorded and the batch goes on.

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import cv2
import numpy as np

from fenestra import outputs

from fault_helpers import fenestra
from test_ownership import snapshot


def _photo(path: Path) -> None:
    """A 64x48 photo at ``path`` (any name: encoded here, written by Python; cv2.imwrite takes
    no name that is not UTF-8)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    ok, buf = cv2.imencode(".png", np.random.default_rng(0).integers(60, 200, (48, 64, 3), dtype=np.uint8))
    path.write_bytes(buf.tobytes())

# names a careful and a hostile user give photos: dots only, a hidden name, the batch's own
# bookkeeping names, names equal but for case, a byte that is not UTF-8
NAMES = ["...png", "..png", "summary.json.png", "summary.csv.png", ".fenestra-output.json.png", "a.png", "A.png",
         os.fsdecode(b"b\xff.png"), "c d;e.png"]


def _batch_folder(d: Path) -> Path:
    photos = d / "photos"
    for n in NAMES:
        _photo(photos / n)
    (photos / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n not a photo")  # fails: recorded, the batch goes on
    _photo(d / "hidden.png")
    return photos


def test_every_photo_gets_its_own_folder_inside_out(tmp_path):
    photos = _batch_folder(tmp_path)
    (tmp_path / "o").mkdir()
    (tmp_path / "earlier").mkdir()  # a sibling of --out: never written into
    _photo(tmp_path / "earlier" / "x.png")
    before = {k: v for k, v in snapshot(tmp_path).items() if not k.startswith("o/")}
    hidden = shutil.copy(tmp_path / "hidden.png", photos / ".jpg")  # a hidden photo named explicitly
    r = fenestra("reconstruct", photos, hidden, "--fx", "60", "--out", "o", cwd=tmp_path)
    assert r.returncode == 1, r.stderr[-3000:]  # one photo failed: exit 1, the others done
    assert "Traceback" not in r.stderr
    rows = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert len(rows) == len(NAMES) + 2
    failed = [row for row in rows if row["error"]]
    assert [Path(row["photo"]).name for row in failed] == ["broken.png"]
    # nothing outside --out changed (the parent, the sibling, the photos); summary.json is the batch's
    after = {k: v for k, v in snapshot(tmp_path).items() if not k.startswith("o/")}
    assert after == {**before, "photos/.jpg": after["photos/.jpg"]}
    assert outputs.read_kind(tmp_path / "o") == "batch"
    subs = [p for p in (tmp_path / "o").iterdir() if p.is_dir()]
    results = [p for p in subs if (p / "windows.json").is_file()]
    assert len(results) == len(NAMES) + 1  # one folder per photo reconstructed, each a direct child of o
    for p in results:
        assert not p.name.startswith(".") and p.name.isprintable()
        os.fsencode(p.name).decode("utf-8")  # every folder name is valid UTF-8
        assert outputs.read_kind(p) == "reconstruction"
    assert len({p.name.lower() for p in results}) == len(results)
    photos_of = {json.loads((p / "windows.json").read_text())["photo"] for p in results}
    assert photos_of == {row["photo"] for row in rows if not row["error"]}
    assert sorted(p.name for p in (tmp_path / "o").iterdir() if p.is_file()) == [".fenestra-output.json",
                                                                                  "summary.csv", "summary.json"]
    again = fenestra("reconstruct", photos, hidden, "--fx", "60", "--out", "o", cwd=tmp_path)  # its own output: replaced
    assert again.returncode == 1, again.stderr[-3000:]
    assert [(row["photo"], row["error"]) for row in json.loads((tmp_path / "o" / "summary.json").read_text())] == [
        (row["photo"], row["error"]) for row in rows]


def test_an_out_folder_not_utf8(tmp_path):
    """--out whose name is not UTF-8: the batch and the single photo write their IFC files there."""
    for i in range(2):
        _photo(tmp_path / "photos" / f"p{i}.png")
    out = os.fsdecode(b"o\xff")
    r = fenestra("reconstruct", "photos", "--fx", "60", "--out", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert [row["error"] for row in json.loads((tmp_path / out / "summary.json").read_text())] == [None, None]
    assert (tmp_path / out / "p0" / "model.ifc").read_bytes().startswith(b"ISO-10303-21;")
    single = os.fsdecode(b"s\xfe")
    r = fenestra("reconstruct", "photos/p0.png", "--fx", "60", "--out", single, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / single / "model.ifc").is_file()
