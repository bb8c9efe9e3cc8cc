"""The Ray executor's shard cache (fenestra/bench/executors.py): Parquet rows + a JSON index with a
digest and row counts; nothing on disk is unpickled, a damaged shard is recomputed, never short."""
from __future__ import annotations

import hashlib
import io
import json
import math
import os
import pickle

import numpy as np
import pandas as pd
import pytest

from fenestra.bench.evaluate import ViewOutcome
from fenestra.bench.executors import _index_digest, _load_shard, read_shard, write_shard


def _outcomes() -> list[ViewOutcome]:
    """Two views as evaluate_view returns them: rows with floats, NaN, None, strings and bools;
    stage seconds; COCO gt (RLE) and dt lists; false-positive and export counts; a third view with
    no row."""
    def row(v, w, err):
        return {"house": "fzk-haus", "view": f"{v:06d}", "window_id": str(w), "method": "oracle/none/lm",
                "detected": err is not None, "corner_err_px_snap": err, "iou": np.float64(0.5 + w / 10),
                "eval_reason": "" if err is not None else "too_small"}
    gt = [{"image": "h/000000", "rle": {"size": [4, 5], "counts": "52"}, "bbox": [1.0, 2.0, 3.0, 1.0],
           "area": 3.0, "iscrowd": 0}]
    dt = {"oracle": [{"image": "h/000000", "bbox": [1.0, 2.0, 3.0, 1.0], "score": np.float32(0.75)}]}
    exported = {"oracle/none/lm": {"n_exported": 3, "n_matched": 1, "n_on_ignore": 1, "n_on_nothing": 1}}
    return [ViewOutcome([row(0, 1, 0.25), row(0, 2, None)], {"detect": 0.5, "snap": 0.125}, gt, dt, {"oracle": 1},
                        exported),
            ViewOutcome([row(1, 3, 1.5)], {"detect": 0.25}, [], {"oracle": []}, {"oracle": 0}),
            ViewOutcome([], {"detect": 0.0})]


def test_shard_round_trip(tmp_path):
    idx = write_shard(tmp_path / "shards" / "k.json", "out/renders/h", _outcomes(), 2.5)
    assert sorted(p.name for p in idx.parent.iterdir()) == ["k.json", "k.parquet"]
    back = read_shard(idx)
    assert back["dataset"] == "out/renders/h" and back["render_s"] == 2.5
    for a, b in zip(_outcomes(), back["outcomes"], strict=True):
        assert len(a.rows) == len(b.rows) and a.stage_s == b.stage_s and a.n_false_positives == b.n_false_positives
        assert a.export_counts == b.export_counts and (a.dataset, a.view, a.size) == (b.dataset, b.view, b.size)
        assert json.loads(json.dumps(a.coco_dt, default=float)) == b.coco_dt and a.coco_gt == b.coco_gt
        for ra, rb in zip(a.rows, b.rows):
            for k, v in ra.items():
                assert rb[k] == v or (v is None and (rb[k] is None or math.isnan(rb[k]))), (k, v, rb[k])
    # the results table built from them is the one built from the originals
    pd.testing.assert_frame_equal(pd.DataFrame([r for o in back["outcomes"] for r in o.rows]),
                                  pd.DataFrame([r for o in _outcomes() for r in o.rows]), check_dtype=False)


class _Exploit:
    """What a crafted pickle does on load: run a command (here: touch a file)."""

    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (os.system, (f"touch {self.path}",))


def test_crafted_shard_executes_nothing_and_is_recomputed(tmp_path, capsys):
    idx = write_shard(tmp_path / "k.json", "d", _outcomes(), 1.0)
    pwned = tmp_path / "pwned"
    idx.with_suffix(".parquet").write_bytes(pickle.dumps(_Exploit(pwned)))
    assert _load_shard(str(idx)) is None  # -> recomputed by run_ray
    assert "rows file does not match the digest" in capsys.readouterr().err
    idx.write_bytes(pickle.dumps(_Exploit(pwned)))  # the index itself replaced by a pickle
    assert _load_shard(str(idx)) is None and "is damaged (index is not valid JSON" in capsys.readouterr().err
    assert not pwned.exists()
    (tmp_path / "old.pkl").write_bytes(pickle.dumps(_Exploit(pwned)))  # an old-format shard is never opened
    assert _load_shard(str(tmp_path / "old.json")) is None and not pwned.exists()


def test_truncated_or_short_shard_is_recomputed(tmp_path, capsys):
    idx = write_shard(tmp_path / "k.json", "d", _outcomes(), 1.0)
    pq = idx.with_suffix(".parquet")
    good = pq.read_bytes()
    pq.write_bytes(good[: len(good) // 2])
    assert _load_shard(str(idx)) is None and "does not match the digest" in capsys.readouterr().err
    # rows dropped and the digest recomputed to match: the row counts still catch it
    df = pd.read_parquet(io.BytesIO(good)).iloc[:-1]
    df.to_parquet(pq, index=False)
    doc = json.loads(idx.read_text())
    doc["rows_sha256"] = hashlib.sha256(pq.read_bytes()).hexdigest()
    doc["index_sha256"] = _index_digest(doc)  # the index's own digest rewritten too
    idx.write_text(json.dumps(doc))
    assert _load_shard(str(idx)) is None and "2 rows, the index says 3" in capsys.readouterr().err
    write_shard(idx, "d", _outcomes(), 1.0)  # recomputed: every row back
    assert sum(len(o.rows) for o in read_shard(idx)["outcomes"]) == 3


def test_an_edited_export_count_makes_the_shard_recomputed(tmp_path, capsys):
    """The export counts feed the export precision: the index's own digest covers them."""
    idx = write_shard(tmp_path / "k.json", "d", _outcomes(), 1.0)
    assert read_shard(idx)["outcomes"][0].export_counts["oracle/none/lm"]["n_on_ignore"] == 1
    doc = json.loads(idx.read_text())
    doc["views"][0]["export_counts"]["oracle/none/lm"]["n_on_ignore"] = 0  # a door export hidden
    idx.write_text(json.dumps(doc))
    assert _load_shard(str(idx)) is None and "does not match its own digest" in capsys.readouterr().err


def test_a_killed_ray_run_resumes_and_force_replaces_it(tmp_path):
    """A run killed after its workers wrote shards that the driver never listed (kill -9 between
    a shard's end and its listing, or mid-shard: rows written, index not): the next run of the
    profile claims the folder and keeps the shards it recognises (name and digest), so it resumes;
    --force for another profile removes them; a stranger's file or a forged index in shards/ is
    still refused."""
    from fenestra import outputs
    from fenestra.bench.executors import recognised_shards
    from fenestra.bench.manifest import RunIntegrityError, claim_run_dir

    run = claim_run_dir(tmp_path / "run", "p", "abcd1234")
    done = write_shard(run / "shards" / "0123456789abcdef.json", "d", _outcomes(), 1.0)  # as the actor does
    half = write_shard(run / "shards" / "fedcba9876543210.json", "d", _outcomes()[:1], 1.0)
    half.unlink()  # killed between the rows and the index
    assert recognised_shards(run) == ["shards/0123456789abcdef.json", "shards/0123456789abcdef.parquet",
                                      "shards/fedcba9876543210.parquet"]
    claim_run_dir(run, "p", "abcd1234")  # the same profile: claimed, the shards kept for the resumed run
    listed = outputs.read_manifest(run)
    assert listed["shards/0123456789abcdef.json"] == hashlib.sha256(done.read_bytes()).hexdigest()
    assert _load_shard(str(done)) is not None and half.with_suffix(".parquet").is_file()
    claim_run_dir(run, "other", "ffff0000", force=True)  # --force: another profile replaces the run
    assert not (run / "shards").exists()

    forged = write_shard(run / "shards" / "00000000000000aa.json", "d", _outcomes(), 1.0)
    index = json.loads(forged.read_text())
    forged.write_text(json.dumps({**index, "render_s": 0.5}))  # its own digest no longer matches
    (run / "shards" / "notes.txt").write_text("the user's")
    assert recognised_shards(run) == []
    with pytest.raises(RunIntegrityError, match="did not write.*00000000000000aa"):
        claim_run_dir(run, "other", "ffff0000")
