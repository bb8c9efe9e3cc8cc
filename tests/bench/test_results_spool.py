"""A run's rows streamed to Parquet by view shard (bench.results.RowSpool) give the table that
concatenating every view's rows in memory gives: same rows, columns, order, dtypes, Parquet schema
and CSV bytes, wherever the shards are cut; and the summary read from it is the in-memory one."""
from __future__ import annotations

import json
import math

import pandas as pd
import pyarrow.parquet as pq
import pytest

from fenestra.bench import results as res
from fenestra.bench.results import REQUIRED_COLUMNS, RowSpool


def _view(i: int) -> pd.DataFrame:
    """One view's rows as bench.evaluate makes them (a DataFrame of row dicts); the views differ in
    what pandas infers: a column all None in one view (object), strings with None in another
    (str), ints in one and floats in the next."""
    rows = []
    for w in range(3 + i % 2):
        for m in ("oracle/none/lm", "oracle/hough/wall"):
            missed = (i + w) % 3 == 0
            rows.append({
                "house": "h", "view": f"{i:06d}", "window_id": f"w{w}", "method": m,
                "detector": "oracle", "snapper": m.split("/")[1], "pose": m.split("/")[2],
                "evaluable": w != 2, "status": "missed" if missed else ("failed" if w == 1 and i == 2 else "ok"),
                **{c: (math.nan if missed else 0.1 * (i + w) + len(m)) for c in REQUIRED_COLUMNS
                   if c.startswith(("corner", "aspect", "rot", "normal", "trans", "iou"))},
                "aspect_case": None if i % 3 == 0 or missed else "general",
                "wall_id": None if i == 1 else (w if i % 2 else float(w)),
                "instance_id": w,
            })
    return pd.DataFrame(rows)


def _json(summary: dict) -> str:
    return json.dumps(res._jsonable(summary))


VIEWS = [_view(i) for i in range(7)] + [pd.DataFrame()]  # the last view has no labelled window


def _in_memory(tmp_path) -> tuple[pd.DataFrame, object]:
    df = pd.concat([v for v in VIEWS if len(v)], ignore_index=True)
    df.insert(0, "profile", "p")
    out = tmp_path / "memory"
    out.mkdir()
    df.to_parquet(out / "results.parquet", index=False)
    df.to_csv(out / "results.csv", index=False)
    return df, out


@pytest.mark.parametrize("per_shard", [1, 3, 100])
def test_spooled_table_is_the_concatenated_one(tmp_path, per_shard):
    want, mem = _in_memory(tmp_path)
    assert want["aspect_case"].dtype == object and want["wall_id"].dtype == object  # the cases that matter
    run = tmp_path / "run"
    spool = RowSpool(run / res.SPOOL_DIR, views_per_shard=per_shard)
    for v in VIEWS:
        spool.add(v)
    assert spool.n_rows == len(want) and spool.n_views == len(VIEWS)
    written = spool.finish(run, "p", csv=True)
    assert [p.name for p in written] == ["results.parquet", "results.csv"]
    assert not (run / res.SPOOL_DIR).exists() and sorted(p.name for p in run.iterdir()) == ["results.csv", "results.parquet"]
    got, ref = pq.read_table(run / "results.parquet"), pq.read_table(mem / "results.parquet")
    assert got.schema.equals(ref.schema, check_metadata=True)
    assert got.equals(ref)
    pd.testing.assert_frame_equal(pd.read_parquet(run / "results.parquet"), pd.read_parquet(mem / "results.parquet"))
    # the CSV holds the same values (an integer in a column whose views mix ints, floats and None
    # prints as 1.0 when the shard that holds it also holds floats: RowSpool's docstring)
    pd.testing.assert_frame_equal(pd.read_csv(run / "results.csv"), pd.read_csv(mem / "results.csv"))
    if per_shard == 1:
        assert (run / "results.csv").read_bytes() == (mem / "results.csv").read_bytes()
    assert _json(res.summarize(pd.read_parquet(run / "results.parquet"))) == _json(res.summarize(want))


def test_spool_without_rows_writes_nothing(tmp_path):
    spool = RowSpool(tmp_path / res.SPOOL_DIR, views_per_shard=2)
    spool.add(pd.DataFrame())
    with pytest.raises(ValueError, match="no view has a row"):
        spool.finish(tmp_path, "p")
    assert not (tmp_path / res.RESULTS_PARQUET).exists()


def test_summary_reads_only_its_columns():
    want = pd.concat([v for v in VIEWS if len(v)], ignore_index=True)
    some = want[res.summary_columns(want.columns)]  # what a run reads back from its Parquet table
    assert _json(res.summarize(some)) == _json(res.summarize(want))
    assert set(res.summary_columns(want.columns)) < set(want.columns)


# ---------------------------------------------------------------- the manifest's check of a million rows

def _table_and_manifest(tmp_path):
    from fenestra.bench import manifest

    views = [_view(i) for i in range(5)]
    df = pd.concat(views, ignore_index=True)
    df.insert(0, "profile", "p")
    res.write_results(df, tmp_path)
    methods = list(dict.fromkeys(df["method"]))
    expected = {"methods": methods, "views": [["h", f"{i:06d}", [f"w{w}" for w in range(3 + i % 2)]] for i in range(5)]}
    manifest.write_manifest(tmp_path, expected, "p", "0")
    return df, manifest


def test_expected_frame_is_the_expanded_rows(tmp_path):
    _, manifest = _table_and_manifest(tmp_path)
    doc = manifest.load_manifest(tmp_path, expand=False)
    frame = manifest.expected_frame(doc)
    assert [tuple(r) for r in frame.astype(str).itertuples(index=False)] == manifest.expand_rows(doc)
    assert doc["n_rows"] == len(frame) == 34


def test_verify_table_names_a_changed_row_and_passes_a_reordered_table(tmp_path):
    df, manifest = _table_and_manifest(tmp_path)
    doc = manifest.load_manifest(tmp_path, expand=False)
    manifest.verify_table(tmp_path, df.iloc[::-1], doc)  # same rows, any order
    bad = df.copy()
    bad.loc[7, "window_id"] = "w9"  # as many rows, one of them not expected
    with pytest.raises(manifest.RunIntegrityError, match=r"lacks 1 of 34 expected rows.*has unexpected 1 of 34.*h/000001/w9"):
        manifest.verify_table(tmp_path, bad, doc)
    with pytest.raises(manifest.RunIntegrityError, match="lacks 1 of 34"):
        manifest.verify_table(tmp_path, df.drop(index=3), doc)


@pytest.mark.parametrize("owned", [True, False])
def test_a_run_killed_while_spooling_can_be_run_again(tmp_path, owned):
    """Issue 51, item 7: a run killed after some shards (no run_status, no finish: kill -9) leaves
    shards that its manifest lists, so the next run of the same profile in that folder claims it and
    clears the spool; unlisted shards (a spool without its owner) are refused as foreign."""
    from fenestra.bench.manifest import RunIntegrityError, claim_run_dir

    run = claim_run_dir(tmp_path / "run", "p", "abcd1234")
    spool = RowSpool(run / res.SPOOL_DIR, views_per_shard=2, owner=run if owned else None)
    for v in VIEWS[:5]:
        spool.add(v)
    assert len(list((run / res.SPOOL_DIR).glob("*.parquet"))) == 2  # killed here
    if not owned:
        with pytest.raises(RunIntegrityError, match="did not write"):
            claim_run_dir(run, "p", "abcd1234")
        return
    claim_run_dir(run, "p", "abcd1234")
    assert not (run / res.SPOOL_DIR).exists()  # the interrupted spool is cleared (STALE)
    claim_run_dir(run, "other", "ffff0000", force=True)  # and --force replaces it for another profile
