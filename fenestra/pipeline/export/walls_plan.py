"""The exported walls: one per façade plane, as far as the photo shows it, trimmed at the corners.

    walls = facade_walls(placed, {window index: wall id}, K, (W, H))
    walls[0].frame      # PlacedWindow: the wall's rectangle [0, w] x [0, h] in its own frame
    walls[0].members    # its windows, turned into the wall's axes (an opening square to its wall)
    walls[0].holes      # their voids in the wall's frame, (x0, y0, x1, y1) m each

What a wall is. The façade model's walls (``walls``: the façade model's wall ids) are merged only
when they are one plane: normals within TOL.facade_plane_deg and distances from the camera within
TOL.facade_plane_offset_rel (:func:`one_plane`); the merged wall keeps the plane of its largest
part. A window without a wall id stays a fragment of its own (its void plus ``margin_m``).

A wall's extent (:func:`visible_extent`): the photo's frame projected onto the wall's plane (the
half-planes where the rays through the frame's edges meet it, in front of the camera and at most
VISIBLE_FAR_FACTOR times its farthest window's depth), its bounding rectangle, grown to hold every
window's void; its bottom is the ground (the export world's z = 0: :func:`ground_y`), whether the
photo shows the foot of the wall or cuts it off (a wall stands on the ground).

Corners (:func:`corner_x`). Two walls that are not one plane meet where their planes intersect
(a vertical line for two upright walls) when the photo shows that line (its point at the walls'
mid-height projects inside the frame, in front of the camera) and it separates them: each wall's
voids lie on one side of it in its own plane, and the two walls' windows on opposite sides in the
photo. Each wall is then cut (or extended) to end on that line: a corner building is two walls
meeting at the corner.

Windows in their wall (:func:`aligned`). A window keeps its measured width and height and its
centre (moved onto the wall's plane along the wall's normal), and takes the wall's axes: its
opening is perpendicular to its wall, and the wall's hole, the opening and the window body are one
rectangle.

Frames: as fenestra/pipeline/export/geometry.py (window frame x along, y up, z outward; ``placed``
in the export world, grounded: z = 0 is the ground).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fenestra.pipeline.export.geometry import WALL_MARGIN_M, PlacedWindow, void_hole
from fenestra.tolerances import TOL

VISIBLE_FAR_FACTOR = 3.0  # a wall seen at a grazing angle ends this many times its farthest window's depth away
NEAR_M = 1e-3  # the visible part of a plane starts this far in front of the camera


@dataclass(frozen=True)
class FacadeWall:
    """One exported wall. id: its façade model wall id (a window's index for a fragment of its
    own); frame: the wall rectangle [0, width_m] x [0, height_m] in the frame's plane (z = 0 the
    photographed plane); members: its windows (in the wall's axes when ``own`` is False); holes:
    their voids in ``frame``'s coordinates, (x0, y0, x1, y1) m; margin_m: how far the wall's
    outline reaches beyond [0, w] x [0, h] (0 for a façade plane); own: a window's fragment;
    merged_from: the wall ids it joins (one plane); corners: ((the id of a wall it meets at a corner,
    which end of this wall is there: "ATSTART" x = 0 or "ATEND" x = width_m), ...)."""

    id: int
    frame: PlacedWindow
    members: tuple
    holes: tuple
    margin_m: float
    own: bool
    merged_from: tuple = ()
    corners: tuple = ()


def plane(pw: PlacedWindow) -> tuple[np.ndarray, float]:
    """The plane z = 0 of ``pw``'s frame in the camera frame: (unit outward normal (3,), its
    distance d m: n . X = d)."""
    n = np.asarray(pw.R, dtype=np.float64)[:, 2]
    return n, float(n @ pw.t)


def one_plane(a: PlacedWindow, b: PlacedWindow, max_deg: float = TOL.facade_plane_deg,
              max_offset_rel: float = TOL.facade_plane_offset_rel) -> bool:
    """Whether the planes of ``a`` and ``b`` are one façade plane: normals within ``max_deg`` and
    distances from the camera within ``max_offset_rel`` of the nearer one."""
    (na, da), (nb, db) = plane(a), plane(b)
    angle = np.degrees(np.arccos(np.clip(float(na @ nb), -1.0, 1.0)))
    return bool(angle <= max_deg and abs(da - db) <= max_offset_rel * min(abs(da), abs(db)))


def in_frame(frame: PlacedWindow, X_cam: np.ndarray) -> np.ndarray:
    """Camera-frame points (N, 3) m in ``frame``'s coordinates (N, 3) m (z: off its plane)."""
    return (np.asarray(X_cam, dtype=np.float64).reshape(-1, 3) - frame.t) @ frame.R


def centre_xy(frame: PlacedWindow, pw: PlacedWindow) -> np.ndarray:
    """The centre of ``pw``'s void on ``frame``'s plane, (2,) m (moved along the plane's normal)."""
    return in_frame(frame, pw.to_camera([[pw.width_m / 2, pw.height_m / 2, 0.0]]))[0, :2]


def _clip(poly: np.ndarray, a: np.ndarray, b: float) -> np.ndarray:
    """Sutherland-Hodgman: the part of convex polygon ``poly`` (N, 2) where a . p + b >= 0."""
    out = []
    for i in range(len(poly)):
        p, q = poly[i], poly[(i + 1) % len(poly)]
        fp, fq = float(a @ p + b), float(a @ q + b)
        if fp >= 0:
            out.append(p)
        if (fp >= 0) != (fq >= 0):
            out.append(p + (q - p) * (fp / (fp - fq)))
    return np.array(out, dtype=np.float64).reshape(-1, 2)


def visible_polygon(frame: PlacedWindow, K: np.ndarray, image_size: tuple[int, int], far_m: float) -> np.ndarray:
    """The part of ``frame``'s plane that the photo shows, as a convex polygon (N, 2) m in its
    coordinates (N = 0: none): where the rays through the photo's frame (pixel edges at -0.5 and
    W - 0.5, H - 0.5) meet the plane at depths in [NEAR_M, far_m]."""
    W, H = image_size
    K = np.asarray(K, dtype=np.float64)
    spaces = [(K.T @ np.array(l, dtype=np.float64), 0.0)
              for l in ((1, 0, 0.5), (-1, 0, W - 0.5), (0, 1, 0.5), (0, -1, H - 0.5))]
    spaces += [(np.array([0.0, 0.0, 1.0]), -NEAR_M), (np.array([0.0, 0.0, -1.0]), float(far_m))]
    L = 10.0 * float(far_m)
    poly = np.array([[-L, -L], [L, -L], [L, L], [-L, L]], dtype=np.float64)
    r1, r2 = frame.R[:, 0], frame.R[:, 1]
    for g, h in spaces:  # g . X + h >= 0 with X = t + x r1 + y r2
        poly = _clip(poly, np.array([g @ r1, g @ r2]), float(g @ frame.t + h))
        if len(poly) == 0:
            break
    return poly


def ground_y(frame: PlacedWindow, x_m: float) -> float | None:
    """The height y (m, ``frame``'s coordinates) where the export world's ground (z = 0) crosses
    the vertical x = ``x_m`` of the frame's plane; None for a plane whose y axis is not upright."""
    T = frame.export_matrix()
    if T[2, 1] < 0.5:
        return None
    return float(-(T[2, 3] + T[2, 0] * x_m) / T[2, 1])


def visible_extent(frame: PlacedWindow, members: list[PlacedWindow], K: np.ndarray,
                   image_size: tuple[int, int]) -> np.ndarray:
    """The wall's rectangle (x0, y0, x1, y1) m in ``frame``'s coordinates (see the module
    docstring): the bounding box of the photo's view of the plane and of the members' voids (their
    measured size about their centre), its bottom on the ground."""
    rects = np.array([member_rect(frame, pw) for pw in members])
    lo, hi = rects[:, :2].min(axis=0), rects[:, 2:].max(axis=0)
    far = VISIBLE_FAR_FACTOR * max(float(pw.to_camera(pw.void_corners())[:, 2].max()) for pw in members)
    poly = visible_polygon(frame, K, image_size, far)
    if len(poly):
        lo, hi = np.minimum(lo, poly.min(axis=0)), np.maximum(hi, poly.max(axis=0))
    y_ground = ground_y(frame, 0.5 * float(lo[0] + hi[0]))
    if y_ground is not None and y_ground < rects[:, 1].min():
        lo[1] = y_ground
    return np.array([lo[0], lo[1], hi[0], hi[1]])


def member_rect(frame: PlacedWindow, pw: PlacedWindow) -> tuple[float, float, float, float]:
    """``pw``'s void as the wall holds it: its measured width x height about its centre on
    ``frame``'s plane, (x0, y0, x1, y1) m in ``frame``'s coordinates."""
    cx, cy = centre_xy(frame, pw)
    return (float(cx - pw.width_m / 2), float(cy - pw.height_m / 2),
            float(cx + pw.width_m / 2), float(cy + pw.height_m / 2))


def aligned(frame: PlacedWindow, pw: PlacedWindow) -> PlacedWindow:
    """``pw`` in the wall's axes: ``frame``'s rotation, its void :func:`member_rect` on the plane."""
    x0, y0, _, _ = member_rect(frame, pw)
    return replace(pw, R=frame.R, t=frame.t + frame.R @ np.array([x0, y0, 0.0]))


def corner_x(a: PlacedWindow, b: PlacedWindow, y_m: float, max_deg: float = TOL.facade_plane_deg) -> float | None:
    """Where ``b``'s plane crosses ``a``'s at height ``y_m`` of ``a``'s frame: x (m, ``a``'s
    coordinates), or None when the planes are parallel within ``max_deg``."""
    nb, db = plane(b)
    ca, cb = float(nb @ a.R[:, 0]), float(nb @ a.R[:, 1])
    if abs(ca) < np.sin(np.radians(max_deg)):
        return None
    return (db - float(nb @ a.t) - cb * y_m) / ca


def _side(rects: np.ndarray, x: float) -> int:
    """-1 when every rectangle (N, 4) lies left of x, +1 when right, 0 when they straddle it."""
    if np.all(rects[:, 2] <= x):
        return -1
    if np.all(rects[:, 0] >= x):
        return 1
    return 0


def _u(K: np.ndarray, X_cam: np.ndarray) -> float:
    p = np.asarray(K, dtype=np.float64) @ X_cam
    return float(p[0] / p[2])


def corner(a: PlacedWindow, ma: list[PlacedWindow], b: PlacedWindow, mb: list[PlacedWindow], K: np.ndarray,
           image_size: tuple[int, int]) -> tuple[float, int, float, int] | None:
    """The corner of walls ``a`` and ``b`` (frames; ``ma``, ``mb`` their windows) when the photo
    shows it and it separates them (module docstring): (x in a's frame, the side of it a's windows
    are on (-1 left, +1 right), x in b's frame, b's side); else None."""
    ra = np.array([member_rect(a, pw) for pw in ma])
    rb = np.array([member_rect(b, pw) for pw in mb])
    ya = 0.5 * float(ra[:, 1].min() + ra[:, 3].max())
    xa = corner_x(a, b, ya)
    if xa is None:
        return None
    P = a.t + a.R @ np.array([xa, ya, 0.0])  # the corner line's point at a's mid-height, camera frame
    if P[2] <= NEAR_M or not -0.5 <= _u(K, P) <= image_size[0] - 0.5:
        return None
    xb = float(in_frame(b, P[None])[0, 0])
    sa, sb = _side(ra, xa), _side(rb, xb)
    if sa == 0 or sb == 0:
        return None
    ua = [_u(K, pw.to_camera([[pw.width_m / 2, pw.height_m / 2, 0.0]])[0]) for pw in ma]
    ub = [_u(K, pw.to_camera([[pw.width_m / 2, pw.height_m / 2, 0.0]])[0]) for pw in mb]
    uc = _u(K, P)
    if not ((max(ua) <= uc <= min(ub)) or (max(ub) <= uc <= min(ua))):
        return None
    return xa, sa, xb, sb


def _planes(placed: list[PlacedWindow], walls: dict[int, int] | None) -> tuple[list, list]:
    """([(wall id, merged ids, frame, members)] of the façade planes, [own windows]): the windows
    grouped by ``walls``, groups on one plane (:func:`one_plane`) merged into their largest."""
    groups: dict[int, list[PlacedWindow]] = {}
    own = []
    for pw in placed:
        wid = None if walls is None else walls.get(pw.index)
        if wid is None:
            own.append(pw)
        else:
            groups.setdefault(int(wid), []).append(pw)
    planes: list = []
    for wid, members in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        host = next((p for p in planes if one_plane(p[2], members[0])), None)
        if host is None:
            planes.append((wid, [wid], members[0], list(members)))
        else:
            host[1].append(wid)
            host[3].extend(members)
    return planes, own


def facade_walls(placed: list[PlacedWindow], walls: dict[int, int] | None, K: np.ndarray,
                 image_size: tuple[int, int], margin_m: float = WALL_MARGIN_M) -> list[FacadeWall]:
    """The exported walls of ``placed`` (module docstring): one per façade plane of ``walls``
    ({window index: wall id}), in the order of their first window, then a fragment (its void plus
    ``margin_m``) per window without a wall id. K (3, 3) and image_size (W, H) px: the photo's,
    at the size the texture's photo region has."""
    planes, own = _planes(placed, walls)
    extents = [visible_extent(frame, members, K, image_size) for _, _, frame, members in planes]
    corners: list[list[tuple[int, str]]] = [[] for _ in planes]
    for i in range(len(planes)):
        for j in range(i + 1, len(planes)):
            c = corner(planes[i][2], planes[i][3], planes[j][2], planes[j][3], K, image_size)
            if c is None:
                continue
            for k, other, x, side in ((i, j, c[0], c[1]), (j, i, c[2], c[3])):
                extents[k][2 if side < 0 else 0] = x  # the wall ends on the corner line
                corners[k].append((planes[other][0], "ATEND" if side < 0 else "ATSTART"))
    out = []
    for (wid, merged, ref, members), (x0, y0, x1, y1), met in zip(planes, extents, corners):
        frame = replace(ref, index=wid, width_m=float(x1 - x0), height_m=float(y1 - y0),
                        t=ref.t + ref.R @ np.array([x0, y0, 0.0]))
        inside = [aligned(frame, pw) for pw in members]
        out.append(FacadeWall(wid, frame, tuple(inside), tuple(member_rect(frame, pw) for pw in inside), 0.0,
                              False, tuple(merged), tuple(met)))
    out += [FacadeWall(pw.index, pw, (pw,), (void_hole(pw),), float(margin_m), True) for pw in own]
    first = {pw.index: n for n, pw in enumerate(placed)}
    return sorted(out, key=lambda w: min(first[pw.index] for pw in w.members))
