"""What a person is told about a window, in their words: one short sentence per failure (the
failure catalogue, by stage and code) and the numbers in units that read well. The numbers
themselves stay in windows.json (``failure``: stage, code and detail).

    failure_message(Failure("quad", "not_quadrilateral", "four lines explain 56% ..."))
        -> "the window's outline is not four-sided"
    metres(1.52e6) -> "1520 km"; metres(0.35) -> "35 cm"; metres(float("nan")) -> "an unknown size"
"""
from __future__ import annotations

import math

from fenestra.pipeline.types import Failure

# (stage, code) -> the sentence; (stage, None) -> the stage's sentence for a failure it gives no code
FAILURES: dict[tuple[str, str | None], str] = {
    ("quad", "empty_mask"): "the detection holds no pixel",
    ("quad", "multiple_blobs"): "the detection is in several pieces, so it is not one window",
    ("quad", "too_small"): "the window is too small in the photo to measure",
    ("quad", "touches_border"): "cut by {edges}",
    ("quad", "not_quadrilateral"): "the window's outline is not four-sided",
    ("quad", "no_corners"): "the detector gave no corners for it",
    ("quad", None): "its outline could not be read as a window",
    ("snap", None): "its corners could not be placed",
    ("aspect", None): "its shape cannot be measured in this view (the outline is degenerate)",
    ("pose", None): "its position in 3D could not be computed",
    ("wall", "not_completed"): "{detail}",
    ("wall", None): "no wall of the façade could hold it",
    ("geometry", None): "the façade's geometry could not be fitted",
}
PARTIAL_PREFIX = "cut by {edges}, and "


def edges_words(cut: tuple[str, ...]) -> str:
    """() -> "the photo's edge"; ("left",) -> "the photo's left edge"; ("top", "left") -> "the
    photo's top and left edges"."""
    if not cut:
        return "the photo's edge"
    names = cut[0] if len(cut) == 1 else ", ".join(cut[:-1]) + " and " + cut[-1]
    return f"the photo's {names} edge" + ("s" if len(cut) > 1 else "")


def failure_message(f: Failure, cut: tuple[str, ...] = ()) -> str:
    """The sentence for failure ``f`` of a window cut by the photo's edges ``cut`` (none: whole).

    Args:
        f: the window's Failure (stage, code, detail).
        cut: the photo's edges that cut the window (pipeline.types.CUT_SIDES), () when whole.
    Returns:
        one short sentence without a trailing full stop: the catalogue's for (stage, code), else
        the stage's; a cut window's sentence says the cut first.
    """
    words = FAILURES.get((f.stage, f.code)) or FAILURES[(f.stage, None)]
    edges = edges_words(cut)
    text = words.format(edges=edges, detail=f.detail)
    if cut and not text.startswith("cut by"):
        text = PARTIAL_PREFIX.format(edges=edges) + text
    return text


def metres(x: float) -> str:
    """A length (m) as a person reads it: cm under 1 m, m up to 1 km, km beyond; "an unknown size"
    when not finite."""
    x = float(x)
    if not math.isfinite(x):
        return "an unknown size"
    if abs(x) < 1.0:
        return f"{100 * x:.0f} cm"
    if abs(x) < 1000.0:
        return f"{x:.1f} m" if abs(x) < 100 else f"{x:.0f} m"
    return f"{x / 1000:.0f} km"


def ratio(x: float) -> str:
    """A width/height ratio: two decimals, "over 100" beyond, "unknown" when not finite."""
    x = float(x)
    if not math.isfinite(x):
        return "unknown"
    return "over 100" if x > 100 else f"{x:.2f}"


def degrees(x: float) -> str:
    """An angle in whole degrees ("35°"); "an unknown angle" when not finite."""
    x = float(x)
    return f"{x:.0f}°" if math.isfinite(x) else "an unknown angle"
