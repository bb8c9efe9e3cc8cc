"""The failure catalogue (fenestra.pipeline.messages) speaks the user's words: every failure code
the pipeline can give has its sentence, and no sentence or flag a person reads carries "nan", an
exponent, an internal parameter name or a comparison of raw numbers, whatever the numbers are."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from fenestra.pipeline.facade_model import Known, facade_model
from fenestra.pipeline.messages import FAILURES, degrees, edges_words, failure_message, metres, ratio
from fenestra.pipeline.types import STAGES, Failure

PACKAGE = Path(__file__).resolve().parents[2] / "fenestra"
# what a sentence for a person never holds: NaN/inf, an exponent, an identifier_with_underscores,
# a "name=value" or "x < y" of raw numbers, a px count
BAD = re.compile(r"nan|inf\b|\d[eE][+-]?\d|\b[a-z]+_[a-z_]+\b|=|\s<\s|\d\s*px\b", re.I)
HOSTILE = "four lines explain nan% of the outline < min_explained=60%; width 1.52e+06 m; a corner 2692.6 px away"


def codes_in_the_package() -> set[tuple[str, str]]:
    """(stage, code) of every coded failure the package's source creates, read from the source
    (independently of the catalogue): Failure("stage", "code", ...) and the quad stage's _fail("code", ...)."""
    found = set()
    for p in PACKAGE.rglob("*.py"):
        text = p.read_text()
        found |= set(re.findall(r'Failure\("(\w+)",\s*"(\w+)"', text))
        if p.name == "quad.py":
            found |= {("quad", c) for c in re.findall(r'_fail\("(\w+)"', text)}
    return found


def test_every_failure_code_of_the_package_has_its_sentence():
    codes = codes_in_the_package()
    assert {("quad", "not_quadrilateral"), ("quad", "touches_border"), ("wall", "not_completed")} <= codes
    assert codes <= set(FAILURES), sorted(codes - set(FAILURES))
    assert all((s, None) in FAILURES for s in STAGES)  # every stage says something for an uncoded failure


@pytest.mark.parametrize("key", sorted(FAILURES, key=str))
@pytest.mark.parametrize("cut", [(), ("left",), ("top", "left")])
def test_each_sentence_is_short_and_clean_whatever_the_detail(key, cut):
    stage, code = key
    if code == "not_completed":  # its detail is already a sentence (pipeline.facade_model.complete_partial)
        detail = f"cut by {edges_words(cut)}, with no whole window in its row to complete it from"
    else:
        detail = HOSTILE
    text = failure_message(Failure(stage, code, detail), cut)
    assert text and "\n" not in text and len(text) <= 120, text
    assert not BAD.search(text), text
    if cut:
        assert edges_words(cut) in text


def test_a_cut_window_names_its_edges():
    f = Failure("quad", "touches_border", "mask reaches the image top, left edge")
    assert failure_message(f, ("top", "left")) == "cut by the photo's top and left edges"
    assert failure_message(f, ("right",)) == "cut by the photo's right edge"
    assert failure_message(Failure("quad", "not_quadrilateral", "x"), ("left",)) == \
        "cut by the photo's left edge, and the window's outline is not four-sided"


@pytest.mark.parametrize("x, words", [(1.52e6, "1520 km"), (0.35, "35 cm"), (1.524, "1.5 m"), (250.0, "250 m"),
                                      (float("nan"), "an unknown size"), (float("inf"), "an unknown size")])
def test_lengths_read_well(x, words):
    assert metres(x) == words


def test_ratios_and_angles_read_well():
    assert ratio(0.754) == "0.75" and ratio(1e9) == "over 100" and ratio(float("nan")) == "unknown"
    assert degrees(35.4) == "35°" and degrees(float("nan")) == "an unknown angle"


def test_flags_of_absurd_windows_are_clean_sentences():
    """A façade of plausible windows plus a 1500 km wide one, a 0.001 x 9 m pole and a lone window
    off the façade's plane: each is flagged, and every flag reads cleanly."""
    from test_pipeline_facade_model import TRUE, _scrambled

    true = TRUE + [(-3.0, 0.2, 1.5e6, 0.8), (0.0, 7.0, 0.001, 9.0)]
    _, model = facade_model(_scrambled(true), Known(window_height_m=1.6))
    assert {6, 7} <= set(model.flags)
    flags = [f for v in model.flags.values() for f in v]
    assert any("km" in f for f in flags)
    for f in flags:
        assert not BAD.search(f) and "\n" not in f, f
