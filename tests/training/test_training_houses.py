"""fenestra.training.houses: the procedural training houses every data script shares."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from fenestra.training import houses

ROOT = Path(__file__).resolve().parents[2]


def test_train_validation_and_bench_seeds_are_disjoint():
    bench_seeds = {0, 1, 2}  # the bench's procedural houses (never trained on)
    train = [s for f in houses.TRAIN_SEEDS.values() for s in f]
    val = [s for f in houses.VALIDATION_SEEDS.values() for s in f]
    assert not set(train) & set(val) and not (set(train) | set(val)) & bench_seeds
    assert len(train) == len(set(train)) == 16 + 16 + 20


def test_recessed_houses_have_reveals():
    """The families the corner refinement trains on put the glass behind the wall face."""
    reveals = {houses.varied_spec(s).reveal_depth for s in houses.TRAIN_SEEDS["varied"]}
    assert reveals == {0.05, 0.1, 0.15, 0.3}
    assert {houses.street_spec(s).reveal_depth for s in houses.TRAIN_SEEDS["street"]} == {0.1, 0.15, 0.25}


def test_variants_end_with_the_plainest_house():
    facade = houses.variants("facade", 131)
    assert (facade[0].glazed_doors, facade[0].curtain_walls) == (2, 0)
    assert (facade[-1].glazed_doors, facade[-1].curtain_walls) == (0, 0)
    assert [v.glazed_doors for v in houses.variants("street", 152)] == [1, 0]
    assert [v.glazed_doors for v in houses.variants("street", 151)] == [0]


def test_unknown_family_is_named():
    with pytest.raises(ValueError, match="'villas'"):
        houses.variants("villas", 1)
    r = subprocess.run([sys.executable, "-m", "fenestra.training.houses", "villas", "x"], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.returncode == 2 and "usage:" in r.stderr


def test_existing_files_are_kept(tmp_path):
    """A rerun reuses what is there: no house is rewritten."""
    seeds = list(houses.TRAIN_SEEDS["varied"]) + list(houses.VALIDATION_SEEDS["varied"])
    for s in seeds:
        (tmp_path / f"varied-{s}.ifc").write_text(f"kept {s}")
    paths = houses.write_family("varied", tmp_path)
    assert [p.name for p in paths] == [f"varied-{s}.ifc" for s in seeds]
    assert all(p.read_text() == f"kept {s}" for p, s in zip(paths, seeds))


def test_data_scripts_write_the_houses_through_the_module():
    """One definition of each family: the scripts call the module, none embeds house specs."""
    scripts = ROOT / "lab" / "scripts"
    for name, families in (("make_data.sh", ("varied", "facade")), ("make_data_street.sh", ("street",))):
        text = (scripts / name).read_text()
        assert "HouseSpec(" not in text, name
        for f in families:
            assert f"-m fenestra.training.houses {f} " in text, (name, f)


def test_a_missing_house_is_written_whole(tmp_path):
    """The one missing house is generated (an IFC ifcopenshell opens, each window in an opening) and
    no ``.part`` file is left beside it."""
    import ifcopenshell

    seeds = list(houses.TRAIN_SEEDS["varied"]) + list(houses.VALIDATION_SEEDS["varied"])
    for s in seeds[1:]:
        (tmp_path / f"varied-{s}.ifc").write_text("kept")
    houses.write_family("varied", tmp_path)
    f = ifcopenshell.open(str(tmp_path / f"varied-{seeds[0]}.ifc"))
    assert len(f.by_type("IfcWindow")) > 0 and len(f.by_type("IfcOpeningElement")) >= len(f.by_type("IfcWindow"))
    assert not list(tmp_path.glob("*.part"))
