"""What feeds a figure is covered by a digest: edited shard indexes are recomputed (issue 37: 4).

Part of the fault suite (tests/faults/, README of the suite: tests/faults/conftest.py):
every case runs the CLI as a user meets the fault."""
from __future__ import annotations

import json

import pytest


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
