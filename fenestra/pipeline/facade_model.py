"""From per-window results to a façade model: one wall per façade plane, one scale per wall, and
the windows a BIM should not get.

    results, model = facade_model(results, Known(window_height_m=1.4))
    model.walls      # WallModel per wall: members, normal, scale and where it came from
    model.flags      # {window index: [reasons]}: implausible windows (not exported by default)

Scale. A single photo fixes a window only up to a factor along its viewing ray; the wall fit gives
every window the same height (the scale parameter), so the windows of one flat façade end up at
different depths. Here every window of a wall is moved along its ray onto the wall's one plane
(the plane of the wall's rotation through the windows' centres, which is a similarity about the
camera centre: the reprojection does not change), and the plane's distance is set once per wall
from what the user knows (:class:`Known`), else from DEFAULT_WINDOW_HEIGHT_M, flagged "assumed".

Walls. Walls whose rotations agree within MERGE_DEG (the same vanishing points; LONE_TOL_DEG for a
one-window wall) are merged into one wall: one façade plane. So are walls that both stand within
UPRIGHT_DEG of the façade's vertical (the up axis most walls agree with) and whose headings about
it agree within those tolerances: walls are vertical, and a wall's own vertical vanishing point is
noisy (on street photos two fits of one façade differ by 5-13 deg of tilt, under 2 deg of heading).

Robust statistics. A wall's scale and the medians its windows are compared with come
from its *typical* windows (:func:`typical_members`): those of a plausible window shape
(TYPICAL_ASPECT) that agree with each other in height and shape (within AGREE_RATIO, the largest
such set), so boxes over shop fronts or two windows at once cannot set the scale and flag the
clean windows; a wall without one typical window falls back to all its windows.

Plausibility. A window is flagged (with a reason) when its aspect ratio is outside ASPECT_RANGE,
when its shape or size disagrees with its wall's typical windows (ratio to their median beyond
WALL_RATIO), when it is taller or wider than MAX_WINDOW_M at an assumed scale (or, with a known
window size, WALL_RATIO times it), when it is taller than a known storey, when it is behind the
wall's plane, or when it stands alone in a plane of its own while the façade has a wall of several
windows (a right-angled side wall shows several). Flagged windows keep their geometry; their
intervals widen by FLAG_WIDEN.

Partial windows. A window cut by the photo's border takes no part in the above: after
the walls are set, :func:`place_partials` puts its visible part on the wall whose vanishing points
its own sides point at (PARTIAL_VP_DEG; the nearest such wall in the image), with that wall's pose
and scale, as the rectangle around its visible part on the wall's plane (:func:`visible_extent`),
then completed beyond the photo's edge to the size of the whole windows of its row or column
(:func:`complete_partial`); it is flagged only by the absolute size limits. Without such a wall,
or without a row or column to complete it from, it stays a failure: no window is ever exported at
its visible size.

Rows. Last, pipeline.row_lines.regularize_rows gives the windows of each storey row of
a wall that agree with the row's median sill and head lines exactly those lines (pipeline.session
runs it after :func:`place_partials`; partial and flagged windows keep their own).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fenestra.conventions import heading_difference_deg, project, rotation_error_deg, vote_axis
from fenestra.errors import bounded
from fenestra.pipeline.messages import degrees, edges_words, metres, ratio
from fenestra.pipeline.types import Failure, Partial, Uncertainty, Unavailable, WindowResult

DEFAULT_WINDOW_HEIGHT_M = 1.5  # a typical window's height, used (and flagged "assumed") without --known-*
MERGE_DEG = 5.0  # walls whose rotations differ by less are one façade plane
ASPECT_RANGE = (0.2, 4.0)  # w/h of any window: 99.8 % of the 4552 labelled window boxes of spb_facades/train
WALL_RATIO = 2.5  # a window's w/h or height more than this factor off its wall's median
LONE_TOL_DEG = 10.0  # a one-window wall within this of a larger wall joins it (one quad's rotation is noisier)
UP_AGREE_DEG = 5.0  # walls' up axes within this vote for one façade vertical (as export.geometry's gravity)
UPRIGHT_DEG = 15.0  # a wall whose up axis is within this of the façade's vertical is compared by heading only
FLAG_WIDEN = 3.0  # a flagged window's 90 % intervals are this many times wider
# a window's height as a share of the storey's: rows whose pitch implies more or less are not storeys
# (two rows of one storey, a basement row, dormers), and the known storey height is not used on them
STOREY_WINDOW_SHARE = (0.2, 0.75)
TYPICAL_ASPECT = (0.35, 1.5)  # w/h of a typical window: 2.5-97.5 % (0.38-1.49) of the 3606 window boxes of spb_facades/train
AGREE_RATIO = 1.5  # typical windows of a wall agree within this factor in height (per unit distance) and w/h
MAX_WINDOW_M = 4.0  # a window taller or wider than this is flagged unless a known size says otherwise


# the physical range of each known size, m: a value outside is a typo or a unit mistake (1 cm: a
# curtain-wall pane is 9.3 cm, examples/)
KNOWN_RANGE_M = {"window_width_m": (0.01, 30.0), "window_height_m": (0.01, 30.0), "storey_m": (1.0, 50.0)}


@dataclass(frozen=True)
class Known:
    """What the user knows that sets the scale (at most one): window_width_m / window_height_m of a
    typical window (each wall's median window gets it), storey_m (floor-to-floor height: each
    wall's median vertical pitch between window rows)."""

    window_width_m: float | None = None
    window_height_m: float | None = None
    storey_m: float | None = None

    def __post_init__(self) -> None:
        given = {k: v for k, v in vars(self).items() if v is not None}
        if len(given) > 1:
            raise ValueError(f"give at most one known size, got {given}")
        for k, v in given.items():
            lo, hi = KNOWN_RANGE_M[k]
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not lo <= v <= hi:
                raise ValueError(f"Known.{k} must be a length in m within the physical range [{lo:g}, {hi:g}], "
                                 f"got {bounded(repr(v))}")


@dataclass(frozen=True)
class WallModel:
    """One façade plane: id, members (window indices), normal (3,) camera frame (the window z axis,
    outward), distance_m (of the plane from the camera), scale_source (how its size was set),
    assumed (True when from the default), merged_from (the wall fit's wall ids it joins),
    partial (the windows cut by the photo's border placed on it afterwards: :func:`place_partials`;
    they set none of the above)."""

    id: int
    members: tuple[int, ...]
    normal: np.ndarray
    distance_m: float
    scale_source: str
    assumed: bool
    merged_from: tuple[int, ...]
    partial: tuple[int, ...] = ()

    @property
    def windows(self) -> tuple[int, ...]:
        """Every window on the wall: its members, then its partial windows."""
        return (*self.members, *self.partial)

    def to_json(self) -> dict:
        return {"id": self.id, "members": list(self.members), "normal": self.normal.tolist(),
                "distance_m": self.distance_m, "scale_source": self.scale_source, "assumed": self.assumed,
                "merged_from": list(self.merged_from), "partial": list(self.partial)}


@dataclass(frozen=True)
class FacadeModel:
    """walls: list of WallModel; flags: {window index: [reasons]} (implausible windows)."""

    walls: list
    flags: dict

    def wall_of(self, index: int) -> WallModel | None:
        """The wall window ``index`` is on (a member or a partial window), or None."""
        return next((w for w in self.walls if index in w.windows), None)


def _posed(r: WindowResult) -> bool:
    return r.failure is None and r.R is not None and r.t is not None and r.aspect_ratio is not None


def _centre(r: WindowResult) -> np.ndarray:
    """The window's centre (3,) in the camera frame, m."""
    h = float(r.height_m)
    return np.asarray(r.t, dtype=np.float64).reshape(3) + np.asarray(r.R) @ np.array([r.aspect_ratio * h / 2, h / 2, 0.0])


def facade_up(starts: list[list[int]], results: list[WindowResult]) -> np.ndarray | None:
    """The façade's vertical (3,) camera frame: the up axis (R[:, 1]) most windows' walls agree
    with within UP_AGREE_DEG (conventions.vote_axis; each start group votes with its first
    member's axis, weighted by its windows); None without a posed window."""
    if not starts:
        return None
    ups = np.array([np.asarray(results[m[0]].R, dtype=np.float64)[:, 1] for m in starts])
    return vote_axis(ups, np.array([len(m) for m in starts], dtype=np.float64), UP_AGREE_DEG)[0]


def same_plane(R_a: np.ndarray, R_b: np.ndarray, up: np.ndarray | None, tol_deg: float,
               upright_deg: float = UPRIGHT_DEG) -> bool:
    """Two walls' rotations (3, 3) face one façade plane: they agree within tol_deg, or both stand
    within upright_deg of the façade's vertical ``up`` (3,) and their normals' headings about it
    (conventions.heading_difference_deg) agree within tol_deg. Walls are vertical, so a difference
    in tilt alone is the noise of each wall's own vertical vanishing point, not two planes."""
    if rotation_error_deg(R_a, R_b) <= tol_deg:
        return True
    if up is None:
        return False
    upright = all(np.degrees(np.arccos(np.clip(np.asarray(R)[:, 1] @ up, -1.0, 1.0))) <= upright_deg
                  for R in (R_a, R_b))
    return upright and heading_difference_deg(np.asarray(R_a)[:, 2], np.asarray(R_b)[:, 2], up) <= tol_deg


def merge_groups(results: list[WindowResult], tol_deg: float = MERGE_DEG,
                 lone_tol_deg: float = LONE_TOL_DEG) -> list[tuple[tuple[int, ...], tuple]]:
    """Posed windows grouped into façade planes: [(members, merged wall-fit ids)], largest first.

    Windows of one wall fit start together; a window without a wall (a per-window strategy) is its
    own start. Groups that face one plane (:func:`same_plane`: rotations, or headings about the
    façade's vertical, :func:`facade_up`, of their largest member) within tol_deg merge; a
    one-window group (its rotation from one quad: noisier) within lone_tol_deg.
    """
    starts: dict = {}
    for k, r in enumerate(results):
        if _posed(r):
            starts.setdefault(("wall", r.group) if r.group is not None else ("window", k), []).append(k)
    ordered = sorted(starts.items(), key=lambda kv: -len(kv[1]))
    up = facade_up([m for _, m in ordered], results)
    groups: list[tuple[list[int], list, np.ndarray]] = []
    for key, members in ordered:
        R = np.asarray(results[members[0]].R)
        tol = lone_tol_deg if len(members) == 1 else tol_deg
        for g in groups:
            if same_plane(g[2], R, up, tol):
                g[0].extend(members)
                g[1].append(key[1] if key[0] == "wall" else None)
                break
        else:
            groups.append((list(members), [key[1] if key[0] == "wall" else None], R))
    return [(tuple(sorted(m)), tuple(x for x in ids if x is not None)) for m, ids, _ in groups]


def _rows_pitch(heights_up: np.ndarray, window_h: np.ndarray) -> float | None:
    """Median vertical pitch between window rows (same unit as the inputs), or None with < 2 rows.
    heights_up: the windows' bottom edges along the wall's up axis; rows split at gaps above half
    the median window height."""
    y = np.sort(heights_up)
    if len(y) < 2:
        return None
    cut = np.flatnonzero(np.diff(y) > 0.5 * float(np.median(window_h))) + 1
    rows = [float(np.mean(part)) for part in np.split(y, cut)]
    return float(np.median(np.diff(rows))) if len(rows) >= 2 else None


def typical_members(aspects: np.ndarray, heights: np.ndarray, ratio: float = AGREE_RATIO,
                    aspect_range: tuple[float, float] = TYPICAL_ASPECT) -> np.ndarray:
    """Indices of a wall's typical windows: of a plausible window shape (w/h within
    ``aspect_range``), the largest set that agrees within ``ratio`` with one of them in height
    (``heights``: per unit distance, or m at one scale) and in w/h (ties: the set with the smaller
    spread of heights); all windows when none has a plausible shape."""
    a, h = np.asarray(aspects, dtype=np.float64), np.asarray(heights, dtype=np.float64)
    shaped = np.flatnonzero((a >= aspect_range[0]) & (a <= aspect_range[1]) & (h > 0))
    if not len(shaped):
        return np.arange(len(a))
    best, best_key = shaped[:1], None
    for c in shaped:
        near = shaped[(np.maximum(h[shaped] / h[c], h[c] / h[shaped]) <= ratio)
                      & (np.maximum(a[shaped] / a[c], a[c] / a[shaped]) <= ratio)]
        k = (len(near), -float(np.ptp(np.log(h[near]))))
        if best_key is None or k > best_key:
            best, best_key = near, k
    return np.sort(best)


def wall_scale(results: list[WindowResult], members: tuple[int, ...], offsets: np.ndarray, up: np.ndarray,
               known: Known) -> tuple[float, str, bool]:
    """(distance of the plane from the camera in m, scale source, assumed) for one wall whose
    members sit at plane offsets ``offsets`` (their |n . centre|, m at the fit's scale); up (3,): the
    wall's up axis in the camera frame. Every median is over the wall's typical windows
    (:func:`typical_members`), so implausible boxes do not set the scale."""
    h = np.array([float(results[k].height_m) for k in members]) / offsets  # height per unit distance
    a = np.array([float(results[k].aspect_ratio) for k in members])
    typ = typical_members(a, h)
    w = h * a
    if known.window_width_m is not None:
        return known.window_width_m / float(np.median(w[typ])), f"known window width {known.window_width_m:g} m", False
    if known.window_height_m is not None:
        return known.window_height_m / float(np.median(h[typ])), f"known window height {known.window_height_m:g} m", False
    why = ""
    if known.storey_m is not None:
        bottoms = np.array([float(up @ np.asarray(results[k].t).reshape(3)) for k in members]) / offsets
        pitch = _rows_pitch(bottoms[typ], h[typ])
        implied = None if not pitch else known.storey_m * float(np.median(h[typ])) / pitch  # the windows' height, m
        if implied is not None and STOREY_WINDOW_SHARE[0] <= implied / known.storey_m <= STOREY_WINDOW_SHARE[1]:
            return known.storey_m / pitch, f"known storey height {known.storey_m:g} m", False
        why = (" (storey height given but the wall shows < 2 window rows)" if implied is None else
               f" (storey height given but the wall's window rows are not a storey apart: they would make its "
               f"windows {implied:.2f} m tall, outside {STOREY_WINDOW_SHARE[0]:g}-{STOREY_WINDOW_SHARE[1]:g} of the storey)")
    return (DEFAULT_WINDOW_HEIGHT_M / float(np.median(h[typ])),
            f"assumed: median window height {DEFAULT_WINDOW_HEIGHT_M:g} m{why}", True)


def _rescaled(r: WindowResult, s: float) -> WindowResult:
    """The window scaled by s about the camera centre (same image, s times the size and distance)."""
    return replace(r, t=np.asarray(r.t, dtype=np.float64) * s, height_m=float(r.height_m) * s)


def _widened(unc: Uncertainty | None, factor: float = FLAG_WIDEN) -> Uncertainty | None:
    """The intervals ``factor`` times wider about their centres (``widened`` = factor)."""
    if unc is None:
        return None
    a = 0.5 * (unc.aspect_lo + unc.aspect_hi)
    half = 0.5 * (unc.aspect_hi - unc.aspect_lo) * factor
    return replace(unc, aspect_sd=unc.aspect_sd * factor, aspect_lo=a - half, aspect_hi=a + half,
                   rot_deg=unc.rot_deg * factor, trans_rel=unc.trans_rel * factor, widened=factor)


def size_limits(known: Known, assumed: bool) -> tuple[float, float, str]:
    """(largest plausible window height, width, in m, and why) for a wall whose scale is
    ``assumed`` or set by ``known``: MAX_WINDOW_M, or WALL_RATIO x a known window size when larger;
    a known storey caps the height (a window is not taller than its storey)."""
    if not assumed and known.window_height_m is not None:
        m = max(MAX_WINDOW_M, WALL_RATIO * known.window_height_m)
        return m, m, f"{WALL_RATIO:g} times the known window height"
    if not assumed and known.window_width_m is not None:
        m = max(MAX_WINDOW_M, WALL_RATIO * known.window_width_m)
        return m, m, f"{WALL_RATIO:g} times the known window width"
    if known.storey_m is not None:
        return min(MAX_WINDOW_M, known.storey_m) if assumed else known.storey_m, MAX_WINDOW_M, \
            f"the known storey, {metres(known.storey_m)}"
    return MAX_WINDOW_M, MAX_WINDOW_M, "the largest plausible window"


def plausibility(results: list[WindowResult], walls: list[WallModel], known: Known = Known()) -> dict[int, list[str]]:
    """{window index: reasons} for the posed windows that should not become BIM windows; medians
    over each wall's typical windows (:func:`typical_members`), sizes against :func:`size_limits`."""
    flags: dict[int, list[str]] = {}
    main = walls[0] if walls else None
    for wall in walls:
        a = np.array([float(results[k].aspect_ratio) for k in wall.members])
        h = np.array([float(results[k].height_m) for k in wall.members])
        typ = typical_members(a, h)
        ma, mh = float(np.median(a[typ])), float(np.median(h[typ]))
        max_h, max_w, why_max = size_limits(known, wall.assumed)
        for k, ak, hk in zip(wall.members, a, h):
            why = []
            if not ASPECT_RANGE[0] <= ak <= ASPECT_RANGE[1]:
                why.append(f"its shape is no window's (width/height {ratio(ak)}; windows are "
                           f"{ASPECT_RANGE[0]:g} to {ASPECT_RANGE[1]:g})")
            if len(wall.members) >= 3:
                if max(ak / ma, ma / ak) > WALL_RATIO:
                    why.append(f"its shape is unlike its wall's other windows (width/height {ratio(ak)} "
                               f"against {ratio(ma)})")
                if max(hk / mh, mh / hk) > WALL_RATIO:
                    why.append(f"its height is unlike its wall's other windows ({metres(hk)} against {metres(mh)})")
            if hk > max_h:
                why.append(f"too tall for a window ({metres(hk)}, more than {metres(max_h)}: {why_max})")
            if ak * hk > max_w:
                why.append(f"too wide for a window ({metres(ak * hk)}, more than {metres(max_w)}: {why_max})")
            if len(wall.members) == 1 and main is not None and wall is not main and len(main.members) >= 2:
                ang = float(np.degrees(np.arccos(np.clip(abs(wall.normal @ main.normal), 0.0, 1.0))))
                why.append(f"it stands alone in a plane at {degrees(ang)} to the façade")
            if why:
                flags[k] = why
    return flags


def facade_model(results: list[WindowResult], known: Known = Known()) -> tuple[list[WindowResult], FacadeModel]:
    """One plane and one scale per wall, then the plausibility flags (see the module docstring).

    Returns the results moved onto their walls' planes and scaled (the wall each is on:
    ``FacadeModel.wall_of``; flagged windows' ``uncertainty`` widened by FLAG_WIDEN) and the FacadeModel. Failed windows pass
    unchanged.
    """
    out = list(results)
    walls = []
    for wid, (members, merged) in enumerate(merge_groups(results)):
        R = np.asarray(results[members[0]].R, dtype=np.float64)
        n = R[:, 2]
        offsets = np.abs([float(n @ _centre(results[k])) for k in members])  # facing: n . centre < 0
        dist, source, assumed = wall_scale(results, members, np.maximum(offsets, 1e-9), R[:, 1], known)
        for k, off in zip(members, offsets):
            out[k] = _rescaled(results[k], dist / max(off, 1e-9))
        walls.append(WallModel(wid, members, n, dist, source, assumed, merged))
    flags = plausibility(out, walls, known)
    for wall in walls:
        R = np.asarray(out[wall.members[0]].R)
        for k in wall.members:
            if float(R[:, 2] @ _centre(out[k])) >= 0:
                flags.setdefault(k, []).append("it lies behind its wall, on the camera's side")
    for k in flags:
        out[k] = replace(out[k], uncertainty=_widened(out[k].uncertainty))
    return out, FacadeModel(walls, flags)


# ---------------------------------------------------------------- windows cut by the photo's border
#
# A window whose mask reaches the photo's edge has no corners of its own there: its quad, pose and
# size as a whole window are unknown (the quad stage's ``touches_border``). Its visible part is
# still a window of the model: the quad of the visible part (pipeline.reconstruct.visible_quads)
# is placed on a wall the whole windows made, after that wall's pose, scale and statistics are
# set, so it never biases them. Its corners' rays meet the wall's plane; the rectangle around
# those points in the wall's axes is its visible extent.

PARTIAL_VP_DEG = 5.0  # a partial window's own sides point at its wall's vanishing points within this (not snapped)


def own_sides(quad: np.ndarray, cut: tuple[str, ...], image_size: tuple[int, int]) -> tuple[int, ...]:
    """The sides of a visible quad (4, 2) px (TL TR BR BL; side k runs from corner k to corner
    k + 1: 0 top, 1 right, 2 bottom, 3 left) that are the window's own: all but, for each image
    edge in ``cut`` (pipeline.types.CUT_SIDES names), the side whose ends lie nearest that edge's
    line (x = -0.5, x = W - 0.5, y = -0.5 or y = H - 0.5 of a (W, H) image; a learned mask's fit
    may tilt it a pixel or two off the edge)."""
    W, H = image_size
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    off = {"top": np.abs(q[:, 1] + 0.5), "bottom": np.abs(q[:, 1] - (H - 0.5)),
           "left": np.abs(q[:, 0] + 0.5), "right": np.abs(q[:, 0] - (W - 0.5))}  # (4,) per corner
    edge = {int(np.argmin(np.maximum(off[c], np.roll(off[c], -1)))) for c in cut}
    return tuple(k for k in range(4) if k not in edge)


def side_misfit_deg(quad: np.ndarray, sides: tuple[int, ...], R: np.ndarray, K: np.ndarray,
                    noise_px: float | None = None) -> float:
    """How far (deg) the quad's (4, 2) px sides ``sides`` (:func:`own_sides` numbering) miss the
    vanishing points of a wall with axes R (3, 3) (camera frame: the top and bottom sides run along
    R[:, 0], the left and right ones along R[:, 1]) beyond the angle ``noise_px`` (default: the
    wall fit's corner noise) makes on each side's length: the largest over the sides, -inf for none."""
    from fenestra.pipeline.walls.settings import WALL_FIT  # noqa: PLC0415 (fenestra.pipeline.walls.settings loads SciPy: imported when first used)
    from fenestra.pipeline.walls.vanishing import side_angles_to_vp  # noqa: PLC0415 (fenestra.pipeline.walls.vanishing loads SciPy: imported when first used)

    noise = WALL_FIT.corner_noise_px if noise_px is None else noise_px
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    worst = -np.inf
    for k in sides:
        seg = np.array([[q[k], q[(k + 1) % 4]]])
        vp = np.asarray(K, dtype=np.float64) @ np.asarray(R, dtype=np.float64)[:, 0 if k in (0, 2) else 1]
        allow = np.degrees(np.arctan2(2.0 * noise, max(float(np.linalg.norm(seg[0, 1] - seg[0, 0])), 1e-9)))
        worst = max(worst, float(side_angles_to_vp(seg, vp)[0]) - allow)
    return worst


def plane_points(px: np.ndarray, K: np.ndarray, normal: np.ndarray, distance_m: float) -> np.ndarray | None:
    """Where the rays of pixels px (N, 2) meet the plane normal . X = -distance_m (camera frame;
    normal (3,) unit, pointing to the camera's side): (N, 3) m, or None when a ray misses it in
    front of the camera (parallel to it, or meeting it behind)."""
    p = np.asarray(px, dtype=np.float64).reshape(-1, 2)
    rays = np.column_stack([p, np.ones(len(p))]) @ np.linalg.inv(np.asarray(K, dtype=np.float64)).T
    den = rays @ np.asarray(normal, dtype=np.float64)
    if np.any(den >= -1e-12):
        return None
    return rays * (-float(distance_m) / den)[:, None]


def visible_extent(quad: np.ndarray, K: np.ndarray, R: np.ndarray, distance_m: float
                   ) -> tuple[np.ndarray, float, float] | None:
    """The visible extent of a quad (4, 2) px on the wall plane R[:, 2] . X = -distance_m (camera
    frame, m): the rectangle, in the wall's axes (R[:, 0] along, R[:, 1] up), around the points
    where the corners' rays meet the plane. Returns (t (3,): its bottom-left corner, camera frame
    m; width m; height m), or None when a ray misses the plane (:func:`plane_points`)."""
    R = np.asarray(R, dtype=np.float64)
    X = plane_points(quad, K, R[:, 2], distance_m)
    if X is None:
        return None
    a, b = X @ R[:, 0], X @ R[:, 1]  # coordinates along and up the wall (its foot -distance_m R[:, 2] is at 0, 0)
    t = -float(distance_m) * R[:, 2] + a.min() * R[:, 0] + b.min() * R[:, 1]
    return t, float(np.ptp(a)), float(np.ptp(b))


def partial_wall(quad: np.ndarray, cut: tuple[str, ...], image_size: tuple[int, int], results: list[WindowResult],
                 walls: list[WallModel], K: np.ndarray) -> WallModel | Unavailable:
    """The wall a visible quad (4, 2) px cut by the image edges ``cut`` belongs on, or why none
    (Unavailable, one line): of the walls whose vanishing points its own sides (:func:`own_sides`) point at
    within PARTIAL_VP_DEG (:func:`side_misfit_deg`; a wall's axes: its first member's R), the
    nearest in the image (to the convex hull of its members' snapped quads)."""
    from fenestra.pipeline.walls.lines import hull_distance  # noqa: PLC0415 (fenestra.pipeline.walls.lines loads SciPy: imported when first used)

    if not walls:
        return Unavailable("no wall of whole windows in the photo to place it on")
    sides = own_sides(quad, cut, image_size)
    if not sides:
        return Unavailable("none of its sides is its own (all along the photo's edges)")
    misfit = [side_misfit_deg(quad, sides, results[w.members[0]].R, K) for w in walls]
    fits = [w for w, m in zip(walls, misfit) if m <= PARTIAL_VP_DEG]
    if not fits:
        best = int(np.argmin(misfit))
        return Unavailable(f"its sides point at no wall's vanishing points (nearest: wall {walls[best].id}, "
                           f"{misfit[best]:.1f} deg beyond the noise > {PARTIAL_VP_DEG:g} deg)")
    centre = np.asarray(quad, dtype=np.float64).reshape(4, 2).mean(axis=0)[None]
    near = [float(hull_distance(centre, np.array([results[k].quad_snapped for k in w.members]))[0]) for w in fits]
    return fits[int(np.argmax(near))]


def place_partial(r: WindowResult, quad: np.ndarray, cut: tuple[str, ...], wall: WallModel | Unavailable,
                  R_wall: np.ndarray | None, K: np.ndarray) -> WindowResult:
    """Window ``r`` (its whole-window failure in ``r.failure``) as a partial window with visible
    quad (4, 2) px and ``cut`` sides: on ``wall`` (with axes R_wall (3, 3)), its visible extent
    (:func:`visible_extent`) as its pose and size, its reprojected quad that rectangle's; or, for a
    reason (an Unavailable) instead of a wall or a ray that misses the wall's plane, failed at stage
    ``wall`` with that reason."""
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    part = Partial(tuple(cut), r.failure)
    on = None if isinstance(wall, Unavailable) else on_wall(r, q, wall, R_wall, K)
    if on is None:
        why = wall.reason if isinstance(wall, Unavailable) else f"a corner's ray misses wall {wall.id}'s plane"
        return replace(r, quad_mask=q, quad_snapped=q, partial=part,
                       failure=Failure("wall", None, f"partial window (cut by the photo's {', '.join(cut)} edge): {why}"))
    return replace(on, partial=part)


def on_wall(r: WindowResult, quad: np.ndarray, wall: WallModel, R_wall: np.ndarray, K: np.ndarray) -> WindowResult | None:
    """``r`` with the extent of quad (4, 2) px on ``wall``'s plane (axes R_wall (3, 3), camera
    frame; :func:`visible_extent`) as its pose and size, its quads ``quad``, its reprojected quad
    that rectangle's, no failure; None when a corner's ray misses the plane."""
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    extent = visible_extent(q, K, R_wall, wall.distance_m)
    if extent is None:
        return None
    t, w, h = extent
    R = np.asarray(R_wall, dtype=np.float64)
    rect = np.array([[0.0, h, 0.0], [w, h, 0.0], [w, 0.0, 0.0], [0.0, 0.0, 0.0]])  # TL TR BR BL, window frame
    return replace(r, quad_mask=q, quad_snapped=q, aspect_ratio=w / h, aspect_case=None, focal_estimate_px=None,
                   R=R, t=t, height_m=h, quad_reprojected=project(K, R, t, rect), failure=None, uncertainty=None)


COMPLETE_SLACK = 1.15  # a visible part may exceed its row's (column's) typical whole window by this factor
ROW_OVERLAP = 0.5  # a whole window is in a partial one's row (column) when they overlap by this share of the smaller
ALIGN_FRAC = 0.1  # a whole window is in a top- (bottom-) cut one's row when their sills (heads) agree within this share of its height


def _overlap(lo_a: float, hi_a: float, lo_b: float, hi_b: float) -> float:
    """The share of the shorter of two intervals (m) that the other covers, 0-1."""
    return max(0.0, min(hi_a, hi_b) - max(lo_a, lo_b)) / max(min(hi_a - lo_a, hi_b - lo_b), 1e-12)


def _on_wall(r: WindowResult, R: np.ndarray) -> tuple[float, float, float, float]:
    """(along m, up m, width m, height m) of a posed window in its wall's axes R (3, 3): its
    bottom-left corner's coordinates and its size."""
    t = np.asarray(r.t, dtype=np.float64).reshape(3)
    h = float(r.height_m)
    return float(t @ R[:, 0]), float(t @ R[:, 1]), float(r.aspect_ratio) * h, h


def _completed(visible_m: float, whole_m: list[float], cut_words: str, where: str, more: str) -> float | Unavailable:
    """A cut window's size along one axis, m: the median of the whole windows' sizes ``whole_m``
    it lines up with (at least its visible size ``visible_m``), or why not (no such window, or a
    visible part more than COMPLETE_SLACK larger: ``more`` than them)."""
    if not whole_m:
        return Unavailable(f"{cut_words}, with no whole window in its {where} to complete it from")
    typical = float(np.median(whole_m))
    if visible_m > COMPLETE_SLACK * typical:
        return Unavailable(f"{cut_words}, yet {more} than the whole windows of its {where}")
    return max(typical, visible_m)


def complete_partial(r: WindowResult, wall: WallModel, results: list[WindowResult], R: np.ndarray,
                     K: np.ndarray) -> WindowResult | Unavailable:
    """A placed partial window (its visible extent on ``wall``) completed to the size of the whole
    windows it lines up with, extended beyond the photo's edges that cut it.

    Cut by the left or right edge: its width becomes the median width of the whole windows of its
    row (the wall's members whose vertical extent overlaps its own by ROW_OVERLAP), its side on the
    photo kept; cut by the top or bottom edge: its height becomes the median height of its
    column's (horizontal overlap), else of its row's (the whole windows whose sill, for a top cut,
    or head, for a bottom cut, is level with its own within ALIGN_FRAC of their height). Args: r, the partial window (R, t, height_m, aspect_ratio: its
    visible extent); wall, its wall; results, every window (the members' poses); R (3, 3), the
    wall's axes; K (3, 3) px. Returns the completed WindowResult (pose, size and reprojected quad
    of the whole window; ``partial.visible_fraction``: the share of its area in the photo), or why
    it cannot be completed (Unavailable, one sentence): no whole window in its row or column, cut
    on two opposite edges, or a visible part larger than the windows it would match.
    """
    R = np.asarray(R, dtype=np.float64)
    a, b, w, h = _on_wall(r, R)
    cut = set(r.partial.cut)
    edges = edges_words(r.partial.cut)
    members = [_on_wall(results[k], R) for k in wall.members]
    if {"left", "right"} <= cut or {"top", "bottom"} <= cut:
        return Unavailable(f"cut by {edges}: too little of it is seen to complete it")
    a1, b1, w1, h1 = a, b, w, h
    if cut & {"left", "right"}:
        row = [m[2] for m in members if _overlap(m[1], m[1] + m[3], b, b + h) >= ROW_OVERLAP]
        w1 = _completed(w, row, f"cut by {edges}", "row", "wider")
        if isinstance(w1, Unavailable):
            return w1
        a1 = a + w - w1 if "left" in cut else a
    if cut & {"top", "bottom"}:
        col = [m[3] for m in members if _overlap(m[0], m[0] + m[2], a1, a1 + w1) >= ROW_OVERLAP]
        if not col:  # its row: the whole windows whose edge on its uncut side (sill or head) is level with its own
            col = [m[3] for m in members if abs((m[1] if "top" in cut else m[1] + m[3]) - (b if "top" in cut else b + h))
                   <= ALIGN_FRAC * m[3]]
        h1 = _completed(h, col, f"cut by {edges}", "column or row", "taller")
        if isinstance(h1, Unavailable):
            return h1
        b1 = b + h - h1 if "bottom" in cut else b
    t = np.asarray(r.t, dtype=np.float64).reshape(3) + (a1 - a) * R[:, 0] + (b1 - b) * R[:, 1]
    rect = np.array([[0.0, h1, 0.0], [w1, h1, 0.0], [w1, 0.0, 0.0], [0.0, 0.0, 0.0]])
    part = replace(r.partial, visible_fraction=float(min(1.0, (w * h) / (w1 * h1))))
    return replace(r, t=t, height_m=h1, aspect_ratio=w1 / h1, quad_reprojected=project(K, R, t, rect), partial=part)


def partial_flags(r: WindowResult, wall: WallModel, known: Known) -> list[str]:
    """Why a completed partial window should not become a BIM window: only the absolute size limits
    of its wall (:func:`size_limits`) (its size is its row's or column's, compared with no median)."""
    max_h, max_w, why_max = size_limits(known, wall.assumed)
    h, w = float(r.height_m), float(r.aspect_ratio) * float(r.height_m)
    return ([f"too tall for a window ({metres(h)}, more than {metres(max_h)}: {why_max})"] if h > max_h else []) + \
           ([f"too wide for a window ({metres(w)}, more than {metres(max_w)}: {why_max})"] if w > max_w else [])


def place_partials(results: list[WindowResult], model: FacadeModel, visible: dict, K: np.ndarray,
                   image_size: tuple[int, int], known: Known = Known()) -> tuple[list[WindowResult], FacadeModel]:
    """The windows cut by the photo's border placed on the façade model's walls, after them.

    results, model: :func:`facade_model`'s (left as they are: a new list and model are returned);
    visible: {window index: pipeline.quad.QuadResult of its visible part}
    (pipeline.reconstruct.visible_quads); only windows that failed at the quad stage are placed
    (a geometry that failed as a whole keeps its failure). K (3, 3) px: the K used; image_size
    (W, H) px. A window whose visible part is a quadrilateral and has a wall
    (:func:`partial_wall`) gets its visible extent there (:func:`place_partial`) and joins the
    wall's ``partial`` windows, flagged only by :func:`partial_flags`; otherwise it fails with a
    one-line reason (stage ``quad``: its visible part is no quadrilateral; ``wall``: no wall).
    Either way its ``partial`` holds the cut sides. No wall's pose, scale, members or flags change.
    """
    out, flags = list(results), dict(model.flags)
    placed: dict[int, list[int]] = {}
    walls = [w for w in model.walls if w.members]
    for k in sorted(visible):
        r, qr = out[k], visible[k]
        if r.failure is None or r.failure.stage != "quad" or not qr.cut:
            continue
        if qr.quad is None:
            out[k] = replace(r, partial=Partial(tuple(qr.cut), r.failure),
                             failure=Failure("quad", r.failure.code,
                                             f"{r.failure.detail}; its visible part: {qr.failure.reason}"))
            continue
        wall = partial_wall(qr.quad, qr.cut, image_size, out, walls, K)
        R_wall = None if isinstance(wall, Unavailable) else out[wall.members[0]].R
        out[k] = place_partial(r, qr.quad, qr.cut, wall, R_wall, K)
        if out[k].failure is None:
            done = complete_partial(out[k], wall, out, R_wall, K)
            if isinstance(done, Unavailable):
                out[k] = replace(out[k], failure=Failure("wall", "not_completed", done.reason))
                continue
            out[k] = done
            placed.setdefault(wall.id, []).append(k)
            why = partial_flags(out[k], wall, known)
            if why:
                flags[k] = why
    new_walls = [replace(w, partial=tuple(placed.get(w.id, ()))) for w in model.walls]
    return out, FacadeModel(new_walls, flags)
