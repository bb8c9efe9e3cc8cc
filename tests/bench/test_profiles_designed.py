"""The designed default profile (issue 34, item 2): the union of [[methods.grids]] cross products,
each answering one question, with "@cli" / "@paper" standing for fenestra.conventions.DEFAULTS /
PAPER; the full cross product is the `full` profile. Expected method sets are built here from the
registries and the conventions, not by fenestra.bench.profiles."""
from __future__ import annotations

import itertools

import pandas as pd
import pytest

from fenestra.bench.profiles import ProfileError, load_profile, planned_methods, profile_from_dict, selected
from fenestra.conventions import DEFAULTS, PAPER
from fenestra.methods import Method
from fenestra.pipeline.detectors import DETECTORS
from fenestra.pipeline.reconstruct import POSES
from fenestra.pipeline.snappers import SNAPPERS
from fenestra.reports.plots import main_pose

POSE_LIST = ("lm", "ippe", "wall", "building", "wall+lines", "building+lines")  # the bench's K-given poses


def _labels(methods) -> set[str]:
    return {m.label for m in methods}


def test_default_profile_answers_the_four_questions_and_nothing_else():
    dets = DETECTORS.where(in_all=True)
    snappers = SNAPPERS.where(in_all=True)
    expected = ({Method(DEFAULTS.detector, s, DEFAULTS.pose) for s in snappers}           # which snapper
                | {Method(DEFAULTS.detector, DEFAULTS.snapper, p) for p in POSE_LIST}    # which pose
                | {Method(d, DEFAULTS.snapper, DEFAULTS.pose) for d in dets}            # which detector
                | {PAPER} | {Method(d, PAPER.snapper, PAPER.pose) for d in dets}        # the paper's
                | {Method(DEFAULTS.detector, DEFAULTS.snapper, DEFAULTS.pose, withhold_K=True)}  # the CLI without K
                | {Method("oracle", "none", DEFAULTS.pose)})                                      # the exact-mask floor
    got = planned_methods(load_profile("default").methods)
    assert len(got) == len(set(got)) and set(got) == expected
    assert len(expected) < 25 and DEFAULTS in got and PAPER in got
    # a detector that is not available (Mask R-CNN without its weights file) drops only its own methods
    avail = planned_methods(load_profile("default").methods, [d for d in dets if d != PAPER.detector])
    assert set(avail) == {m for m in expected if m.detector != PAPER.detector}


def test_full_profile_is_the_cross_product_on_the_default_renders():
    full, default = load_profile("full"), load_profile("default")
    dets = DETECTORS.where(in_all=True)
    snappers = SNAPPERS.where(in_all=True)
    assert planned_methods(full.methods) == tuple(Method(d, s, p) for d, s, p in itertools.product(dets, snappers, POSE_LIST))
    assert full.source == default.source
    # the designed K-given methods are a subsequence of the full product's order (tables read alike);
    # the default adds the CLI's method with K withheld (the focal chain), which `full` does not run
    it = iter(_labels_ordered := [m.label for m in planned_methods(full.methods)])
    designed = planned_methods(default.methods, dets)
    assert all(m.label in it for m in designed if not m.withhold_K) and _labels_ordered
    assert [m.label for m in designed if m.withhold_K] == ["default/refine/wall+lines+noK"]


@pytest.mark.parametrize("name", ["smoke", "full", "walls"])
def test_planned_methods_is_the_runners_plan_for_a_profile_without_grids(name):
    """The contract for bench.runner.plan_methods to delegate to planned_methods."""
    from fenestra.bench.runner import plan_methods

    p = load_profile(name)
    methods, _ = plan_methods(p)
    assert planned_methods(p.methods, list(dict.fromkeys(m.detector for m in methods))) == methods


def test_grids_tokens_and_their_errors():
    grid = {"detectors": ["@cli"], "snappers": ["@paper", "none"], "pose_solvers": ["@cli"], "withhold_K": [False, True]}
    p = profile_from_dict({"name": "x", "methods": {"grids": [grid]}})
    want = {Method(DEFAULTS.detector, s, DEFAULTS.pose, withhold_K=wk) for s in (PAPER.snapper, "none")
            for wk in (False, True) if not wk or POSES[DEFAULTS.pose].fits_focal}
    assert set(planned_methods(p.methods)) == want
    assert selected(p.methods, "snappers") == [n for n in SNAPPERS if n in {PAPER.snapper, "none"}]
    with pytest.raises(ProfileError, match=r"\[\[methods.grids\]\] and also \['snappers'\]"):
        profile_from_dict({"name": "x", "methods": {"snappers": ["none"], "grids": [grid]}})
    with pytest.raises(ProfileError, match=r"methods.grid\[1\]: methods.snappers: unknown snapper 'sift'"):
        profile_from_dict({"name": "x", "methods": {"grids": [grid, {**grid, "snappers": ["sift"]}]}})
    with pytest.raises(ProfileError, match=r"methods.grid\[0\]: methods.withhold_K must be"):
        profile_from_dict({"name": "x", "methods": {"grids": [{**grid, "withhold_K": []}]}})
    with pytest.raises(ProfileError, match=r"unknown key\(s\) \['snapper'\]"):
        profile_from_dict({"name": "x", "methods": {"grids": [{"snapper": ["none"]}]}})


def test_a_profile_without_grids_hashes_as_before_them():
    """Run folders and render caches of every other profile keep their names."""
    from fenestra.bench.profiles import config_hash

    p = load_profile("smoke")
    d = p.to_dict()
    assert d["methods"]["grids"] == ()
    del d["methods"]["grids"]
    assert p.config_hash() == config_hash(d)
    assert load_profile("default").config_hash() != load_profile("full").config_hash()


def _table(methods) -> pd.DataFrame:
    return pd.DataFrame([m.row() for m in methods])


def test_the_reports_rank_snappers_under_the_pose_that_has_them_all():
    """main_pose: the designed default's snappers run under the CLI's pose; the full product ties
    every pose and keeps the paper's (so its figures are those of the old default)."""
    dets = DETECTORS.where(in_all=True)
    assert main_pose(_table(planned_methods(load_profile("default").methods, dets))) == DEFAULTS.pose
    assert main_pose(_table(planned_methods(load_profile("full").methods, dets))) == PAPER.pose
    assert main_pose(_table([Method("oracle", "none", "wall"), Method("oracle", "none", "ippe")])) == "ippe"
