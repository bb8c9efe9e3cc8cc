"""The focal length from the façade's vanishing points, as a chain entry (:func:`vanishing_focal`).

The walls' two orthogonal vanishing directions, refined over all their windows' corners and, with a
``+lines`` strategy, the façade's own line segments (pipeline.walls.focal_from_walls); principal
point at the image centre, square pixels. Where no wall alone shows converging verticals (a level
camera), two walls seen at a right angle (a corner of the building: their two horizontal vanishing
points) give it, the fit then tying them at right angles (pipeline.walls.corner_focals).

Interval (90 %): f +- VP_SD_MULTIPLIER x sd, the multiplier calibrated on renders with known K
(tools/focal_calibration.py). Not used when its field of view is outside PLAUSIBLE_FOV_DEG or that
interval is no narrower than the prior's (:func:`vp_max_sd`). Bounded time: the fit stops as soon as
f runs away, after a capped number of evaluations, or when its first pass is already several times
vaguer than that bound (pipeline.walls.fit_walls_focal). Nor when it is unstable
(:func:`vanishing_stability`): with at least 2 x VP_SPLIT_MIN_QUADS windows, the two halves of the
windows (by position) are fitted alone, and halves whose 90 % intervals are disjoint, or a half
without an answer, send the chain to the prior; ``unavailable`` then says "unstable: halves give A px
and B px ...". Nor when it is not steady (:func:`vanishing_steadiness`): the fit repeated on the
photo at half its size must land inside the interval, and repeated with the window corners moved by
about a pixel must keep an answer (its interval then widened to hold those repeats); ``unavailable``
then says "the vanishing points are not steady: ...".
"""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from fenestra.errors import PipelineError
from fenestra.pipeline.intrinsics.focal import FocalEstimate, fov_from_focal, prior_focal
from fenestra.pipeline.types import Unavailable

if TYPE_CHECKING:  # annotations only; pipeline.walls is imported where a fit runs
    from fenestra.pipeline.segments import SegmentCache
    from fenestra.pipeline.walls import WallParams

PLAUSIBLE_FOV_DEG = (20.0, 100.0)  # a vanishing-point focal length outside is not used (phone: a 3x tele, 26 deg, .. wide)
# The vanishing-point focal length's 90 % interval is f +- VP_SD_MULTIPLIER x sd (the fit's sd): the 90th
# percentile of |f - f_true| / sd over 98 fits on 144 renders with known K (procedural houses 100-105, 24
# views each, dataset seed 1, a 30-95 deg field of view; none of the bench's renders), measured by
#     PYOPENGL_PLATFORM=egl nice .venv/bin/python tools/focal_calibration.py   # -> out/focal-calibration/calibration.csv
# (docs/experiments.md, "Calibrated vanishing-point focal intervals"). The estimate is used when that
# interval is narrower than the prior's (PRIOR_FOV_RANGE_DEG): a measured answer that says more than the
# assumption.
VP_SD_MULTIPLIER = 2.69
# Stability check of the vanishing-point focal length: the windows are split in VP_SPLIT_PARTS disjoint
# halves (:func:`evidence_halves`), each fitted alone with the same façade segments; when every half has at
# least VP_SPLIT_MIN_QUADS windows and the halves' calibrated 90 % intervals are disjoint, or a half gives
# no focal length while the whole does, the answer is called unstable and the prior is used
# (:func:`vanishing_stability`). Measured on renders and on the St Petersburg photos (docs/experiments.md,
# "Vanishing points unstable under re-encoding").
VP_SPLIT_PARTS = 2
# 4 windows a half: with 3 the check called one calibration render unstable whose interval held the truth
# (its focal error 15.9 %, the prior's 45.3 %); with 4 it changes no render answer there
VP_SPLIT_MIN_QUADS = 4
VP_STABILITY_CHECK = True  # the check in the CLI's chain (vanishing_focal's default; False: the chain without it)
# Steadiness check (:func:`vanishing_steadiness`): the fit repeated on the photo at half its size, and
# VP_JITTER_FITS times with every window corner moved by a normal VP_JITTER_PX px (sd per coordinate; a
# re-saved JPEG or a resized copy moves the detector's corners by about that on street photos). An
# answer is used only when the half-size fit gives a focal length inside its 90 % interval and at most
# VP_JITTER_MISSES of the moved ones give none; its interval then holds every moved repeat's focal
# length. Measured by tools/focal_invariance.py (docs/experiments.md, "The vanishing points under
# re-encoding, resizing and mirroring").
VP_JITTER_PX = 1.0
VP_JITTER_FITS = 4
VP_JITTER_MISSES = 1
VP_JITTER_SEED = 0


def vanishing_fit(quads: np.ndarray, image_size: tuple[int, int], wall: WallParams | None = None,
                  segment_cache: SegmentCache | None = None,
                  give_up_rel_sd: float | None = None) -> tuple[float, float] | Unavailable:
    """The façade's vanishing-point focal length and its sd, ungated.

    Args:
        quads: (N, 4, 2) px snapped window quads, TL TR BR BL.
        image_size: (W, H) px.
        wall: the per-wall strategy's parameters (default ``WallParams()``).
        segment_cache: the photo's line segments (pipeline.segments.SegmentCache), for ``+lines``.
        give_up_rel_sd: a relative sd above which the caller will not use the answer (the fit may
            stop early above a multiple of it); None: never.
    Returns:
        (f, sd) px from pipeline.walls.focal_from_walls, or why there is none (Unavailable:
        unobservable, or a field of view outside PLAUSIBLE_FOV_DEG).
    """
    from fenestra.pipeline.walls import WallParams, focal_from_walls  # noqa: PLC0415  (scipy's load waits for a fit)

    W, H = image_size
    if not len(quads):
        return Unavailable("no window quads")
    try:
        f, sd = focal_from_walls(np.asarray(quads, dtype=np.float64), (H, W), wall or WallParams(), segment_cache,
                                 max_rel_sd=give_up_rel_sd)
    except PipelineError as e:
        return Unavailable(str(e))
    if not (np.isfinite(f) and f > 0 and np.isfinite(sd)):
        return Unavailable(f"focal length {f} +- {sd} px")
    fov = fov_from_focal(f, image_size)
    if not PLAUSIBLE_FOV_DEG[0] <= fov <= PLAUSIBLE_FOV_DEG[1]:
        return Unavailable(f"f = {f:.0f} px is a {fov:.0f} deg field of view, outside the plausible "
                           f"{PLAUSIBLE_FOV_DEG[0]:g}-{PLAUSIBLE_FOV_DEG[1]:g} deg")
    return f, sd


def vp_max_sd(image_size: tuple[int, int]) -> float:
    """The largest sd (px) a vanishing-point focal length of a (W, H) px image may have to be used:
    its calibrated 90 % interval (2 x VP_SD_MULTIPLIER x sd wide) narrower than the prior's
    (focal.prior_focal)."""
    lo, hi = prior_focal(image_size).interval_px
    return (hi - lo) / (2.0 * VP_SD_MULTIPLIER)


def vanishing_estimate(f: float, sd: float, image_size: tuple[int, int], how: str = "") -> FocalEstimate | Unavailable:
    """The acceptance rule of a vanishing-point fit.

    Args:
        f, sd: the fit's focal length and sd (px).
        image_size: (W, H) px.
        how: words on where it came from, for the detail.
    Returns:
        The estimate with its calibrated 90 % interval f +- VP_SD_MULTIPLIER x sd (px) when that
        interval is narrower than the prior's, else why it is not used (Unavailable).
    """
    half = VP_SD_MULTIPLIER * sd
    if not sd < vp_max_sd(image_size):
        lo, hi = prior_focal(image_size).interval_px
        return Unavailable(f"f = {f:.0f} +- {half:.0f} px (90 %, calibrated {VP_SD_MULTIPLIER:g} sd) is no narrower "
                           f"than the prior's {lo:.0f}-{hi:.0f} px")
    return FocalEstimate("vanishing points", f, (max(f - half, 1e-6), f + half),
                         f"f = {f:.1f} +- {sd:.1f} px (sd){how}, principal point at the "
                         f"image centre; interval: 90 %, {VP_SD_MULTIPLIER:g} sd (calibrated on renders)")


def evidence_halves(quads: np.ndarray, parts: int = VP_SPLIT_PARTS) -> list[np.ndarray]:
    """Disjoint, deterministic parts of a photo's windows, each spanning the façade.

    Args:
        quads: (N, 4, 2) px window quads.
        parts: how many parts.
    Returns:
        ``parts`` sorted int index arrays covering range(N): the windows ordered by their
        centroid's x, then y (px), dealt out in turn (window k to part k mod parts). The same quads
        in any order give the same windows in each part.
    """
    c = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2).mean(axis=1)
    order = np.lexsort((c[:, 1], c[:, 0])) if len(c) else np.zeros(0, int)
    return [np.sort(order[k::parts]) for k in range(parts)]


def vanishing_stability(quads: np.ndarray, image_size: tuple[int, int], fit: tuple[float, float],
                        wall: WallParams | None = None, segment_cache: SegmentCache | None = None,
                        min_quads: int = VP_SPLIT_MIN_QUADS, parts: int = VP_SPLIT_PARTS) -> tuple[bool, str]:
    """Whether a vanishing-point focal length stands when its evidence is split.

    Each part of :func:`evidence_halves` is fitted alone (:func:`vanishing_fit`, the same façade
    segments, the same early give-up as the whole). Unstable when every part has at least
    ``min_quads`` windows and either two parts' calibrated 90 % intervals (f +- VP_SD_MULTIPLIER sd)
    are disjoint, or a part gives no focal length while the whole does (its answer then rests on
    some of the windows only). Fewer windows: not tested (stable).

    Args:
        quads: (N, 4, 2) px window quads; image_size: (W, H) px.
        fit: (f, sd) px of all the windows.
        wall, segment_cache: as for :func:`vanishing_fit`.
        min_quads: windows a part needs for the test; parts: how many parts.
    Returns:
        (stable, words: the parts' answers, e.g. "unstable: halves give 442 px and no focal length
        (...)"; "" when not tested).
    """
    idx = evidence_halves(quads, parts)
    if min(len(i) for i in idx) < min_quads:
        return True, ""
    give_up = vp_max_sd(image_size) / prior_focal(image_size).focal_px
    fits = [vanishing_fit(np.asarray(quads)[i], image_size, wall, segment_cache, give_up_rel_sd=give_up) for i in idx]
    said = [f"no focal length ({f})" if isinstance(f, Unavailable) else f"{f[0]:.0f} px" for f in fits]
    words = ("halves give " if parts == 2 else f"{parts} parts give ") + " and ".join(said)
    answered = [f for f in fits if not isinstance(f, Unavailable)]
    k = VP_SD_MULTIPLIER
    disjoint = any(abs(a[0] - b[0]) > k * (a[1] + b[1]) for n, a in enumerate(answered) for b in answered[n + 1:])
    if disjoint or len(answered) < len(fits):
        why = "90 % intervals disjoint" if disjoint else "a half has no answer"
        return False, (f"unstable: {words}, f = {fit[0]:.0f} +- {fit[1]:.1f} px from all {len(quads)} windows "
                       f"({why}; split by position); using the prior")
    return True, words


def jittered_quads(quads: np.ndarray, sd_px: float, copies: int, seed: int = VP_JITTER_SEED) -> list[np.ndarray]:
    """Copies of window quads with every corner moved at random, the same for the same windows.

    Args:
        quads: (N, 4, 2) px window quads.
        sd_px: sd (px) of the normal move of each corner coordinate.
        copies: how many copies.
        seed: the moves' random seed.
    Returns:
        ``copies`` arrays (N, 4, 2) px, the windows in :func:`evidence_halves`' order (centroid x,
        then y), so that the same quads in any order get the same moves.
    """
    q = np.asarray(quads, dtype=np.float64).reshape(-1, 4, 2)
    c = q.mean(axis=1)
    q = q[np.lexsort((c[:, 1], c[:, 0]))]
    rng = np.random.default_rng(seed)
    return [q + rng.normal(0.0, sd_px, q.shape) for _ in range(copies)]


def vanishing_steadiness(quads: np.ndarray, image_size: tuple[int, int], est: FocalEstimate,
                         wall: WallParams | None = None, segment_cache: SegmentCache | None = None,
                         sd_px: float = VP_JITTER_PX, fits: int = VP_JITTER_FITS,
                         misses: int = VP_JITTER_MISSES) -> FocalEstimate | Unavailable:
    """A vanishing-point focal length tried against what a re-saved or resized copy changes.

    The fit (:func:`vanishing_fit`, the same early give-up) is repeated on the photo at half its
    size (:func:`halved_fit`) and on :func:`jittered_quads` with the same façade segments. Refused
    when the half-size repeat gives no focal length or one outside ``est``'s interval, or when
    more than ``misses`` of the moved repeats give none; else the estimate, its interval widened
    to hold every moved repeat's focal length, refused when that is no narrower than the prior's.

    Args:
        quads: (N, 4, 2) px window quads; image_size: (W, H) px.
        est: the answer of all the windows as they are (:func:`vanishing_estimate`).
        wall, segment_cache: as for :func:`vanishing_fit`.
        sd_px: sd (px) of the corner moves; fits: how many moved repeats; misses: how many of them
            may give no focal length.
    Returns:
        The estimate with the widened interval (px) and the repeats in its detail, or why it is
        refused (Unavailable, naming the repeats' focal lengths).
    """
    give_up = vp_max_sd(image_size) / prior_focal(image_size).focal_px
    lo, hi = est.interval_px
    moved = [vanishing_fit(q, image_size, wall, segment_cache, give_up_rel_sd=give_up)
             for q in jittered_quads(quads, sd_px, fits)]
    half = halved_fit(quads, image_size, wall, segment_cache, give_up)
    said = ["none" if isinstance(f, Unavailable) else f"{f[0]:.0f} px" for f in moved]
    words = (f"at half the size {'none' if isinstance(half, Unavailable) else f'{half[0]:.0f} px'}; with the "
             f"window corners moved by about {sd_px:g} px "
             + (", ".join(said[:-1]) + " and " + said[-1] if len(said) > 1 else "".join(said)))
    found = [f[0] for f in moved if not isinstance(f, Unavailable)]
    wide = (min([lo, *found]), max([hi, *found]))
    p_lo, p_hi = prior_focal(image_size).interval_px
    if isinstance(half, Unavailable) or not lo <= half[0] <= hi or len(moved) - len(found) > misses \
            or wide[1] - wide[0] >= p_hi - p_lo:
        return Unavailable(f"the vanishing points are not steady: {est.focal_px:.0f} px ({lo:.0f}-{hi:.0f} px) as "
                           f"the photo is, {words}; using the prior")
    return replace(est, interval_px=wide, detail=est.detail + f", widened to {wide[0]:.0f}-{wide[1]:.0f} px by the "
                   f"repeats ({words})")


def halved_fit(quads: np.ndarray, image_size: tuple[int, int], wall: WallParams | None = None,
               segment_cache: SegmentCache | None = None,
               give_up_rel_sd: float | None = None) -> tuple[float, float] | Unavailable:
    """:func:`vanishing_fit` of the photo at half its size (the quads and, with façade lines, the
    segments of the half-size image: SegmentCache.halved), its (f, sd) scaled back to the photo's
    px; (N, 4, 2) px quads of a (W, H) px image."""
    W, H = image_size
    q = (np.asarray(quads, dtype=np.float64) + 0.5) / 2.0 - 0.5  # pixel centres at integers
    fit = vanishing_fit(q, ((W + 1) // 2, (H + 1) // 2), wall, None if segment_cache is None else segment_cache.halved(),
                        give_up_rel_sd=give_up_rel_sd)
    return fit if isinstance(fit, Unavailable) else (2.0 * fit[0], 2.0 * fit[1])


def vanishing_focal(quads: np.ndarray, image_size: tuple[int, int], wall: WallParams | None = None,
                    segment_cache: SegmentCache | None = None,
                    check_stability: bool | None = None) -> FocalEstimate | Unavailable:
    """The façade's vanishing-point focal length as a chain entry.

    Args:
        quads: (N, 4, 2) px snapped window quads; image_size: (W, H) px.
        wall, segment_cache: as for :func:`vanishing_fit`.
        check_stability: test the halves (:func:`vanishing_stability`) and then the steadiness
            (:func:`vanishing_steadiness`); None: the module's VP_STABILITY_CHECK, read at the call.
    Returns:
        The estimate (:func:`vanishing_fit` accepted by :func:`vanishing_estimate`, stable and
        steady, its interval widened by the steadiness repeats), or why there is none (Unavailable).
    """
    fit = vanishing_fit(quads, image_size, wall, segment_cache,
                        give_up_rel_sd=vp_max_sd(image_size) / prior_focal(image_size).focal_px)
    if isinstance(fit, Unavailable):
        return fit
    lines = " and the facade line segments" if wall is not None and wall.lines else ""
    est = vanishing_estimate(*fit, image_size, f" from {len(quads)} window(s){lines}")
    if isinstance(est, Unavailable) or not (VP_STABILITY_CHECK if check_stability is None else check_stability):
        return est
    stable, words = vanishing_stability(quads, image_size, fit, wall, segment_cache)
    if not stable:
        return Unavailable(words)
    return vanishing_steadiness(quads, image_size, replace(est, detail=est.detail + (f"; stable: {words}" if words else "")),
                                wall, segment_cache)
