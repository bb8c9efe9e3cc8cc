"""The `wild` bench profile (issue 47, item 7): it names the loadable wild houses by `wild:<key>`,
they resolve in ../shared/ifc/wild (or $FENESTRA_WILD_IFC), and without that folder the run stops
with one plain line naming it. Runs with or without the folder."""
from __future__ import annotations

import pytest

from fenestra.bench.profiles import load_profile
from fenestra.bench.runner import house_list
from fenestra.errors import SceneError
from fenestra.scenes.registry import WILD_ENV, WILD_HOUSES, resolve, scene_name, wild_dir


def test_wild_profile_names_wild_houses_only():
    p = load_profile("wild")
    scenes = p.source.scenes
    assert scenes.procedural == 0 and scenes.houses
    keys = [h.removeprefix("wild:") for h in scenes.houses]
    assert all(h.startswith("wild:") for h in scenes.houses) and set(keys) <= set(WILD_HOUSES)
    # every wild model but the roof-window-only one and the IFC2X_FINAL one
    assert set(WILD_HOUSES) - set(keys) == {"roof-bricscad", "allplan-smiley"}


def test_without_the_folder_the_profile_says_so_in_one_line(tmp_path, monkeypatch):
    monkeypatch.setenv(WILD_ENV, str(tmp_path / "absent"))
    with pytest.raises(SceneError) as e:
        house_list(load_profile("wild"))
    msg = str(e.value)
    assert "\n" not in msg and str(tmp_path / "absent") in msg and WILD_ENV in msg and "is not there" in msg
    with pytest.raises(SceneError, match="unknown wild house 'wild:nope'"):
        resolve("wild:nope")


@pytest.mark.skipif(not wild_dir().is_dir(), reason=f"the wild IFC models are not bundled (GPL, CC BY-SA or no licence: read from ../shared only) and there is no folder at {wild_dir()} (set {WILD_ENV})")
def test_with_the_folder_every_wild_house_resolves_and_keeps_its_name():
    for h in house_list(load_profile("wild")):
        path = resolve(h)
        assert path.parent == wild_dir() and path.name == WILD_HOUSES[h.removeprefix("wild:")]
        assert scene_name(path) == h
