"""Doors and signboards: the detections the box verifier calls no window, after the façade model.

    openings = place_openings(dets, fits, visible, results, model, exported, K, (W, H))
    openings[d].kind      # "door" or "signboard" (pipeline.types.Detection.kind)
    openings[d].placed    # a door on its wall: a WindowResult in the camera frame, as a window's
    openings[d].reason    # None when it goes into the model, else why not (a signboard: always)

A door never takes part in the geometry: no wall fit, focal length, scale or statistic sees it
(as for a window cut by the photo's border). Its quad is the mask fit's (the photo's bottom edge may
cut it: a door runs down to the ground, so its visible part stands in, and the export puts its foot
on its floor: pipeline.export.floors.on_floor). It goes on the wall of exported windows whose
vanishing points its own sides point at (pipeline.facade_model.partial_wall), else on the one
nearest it in the photo (a door's outline is often a frame in a dark recess, its sides less sure
than a window's), and gets its extent on that wall's plane at that wall's scale
(pipeline.facade_model.on_wall). A signboard is left out of the model, with its reason.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fenestra.pipeline.facade_model import FacadeModel, on_wall, partial_wall
from fenestra.pipeline.types import Detection, Failure, Partial, Unavailable, WindowResult

# A door is at least DOOR_MIN_WINDOW_SHARE of its wall's median window height tall (lower: a vent, a
# panel of a door's leaf, a letter box) and its foot at most DOOR_FOOT_ABOVE median window heights
# above its wall's lowest window sill (a door stands on the ground floor; higher: a dark window, a
# balcony's recess). Chosen on the spb validation photos' door labels (tools/door_recall.py).
DOOR_MIN_WINDOW_SHARE = 0.5
DOOR_FOOT_ABOVE = 0.35
SIGNBOARD_REASON = "a signboard (the detector's box verifier), not an opening of the wall"


@dataclass(frozen=True)
class Opening:
    """One detection the box verifier calls no window: ``index`` (in Reconstruction.openings),
    ``kind`` ("door" or "signboard"), the detection's ``score`` and ``box`` (4,) x0 y0 x1 y1 px;
    ``placed``: a door on its wall (a WindowResult: quads, R, t, aspect ratio and height on the
    wall's plane, ``partial`` when the photo's bottom edge cuts it), else None; ``wall``: its wall
    id, or None; ``reason``: None when it goes into the model, else why not (one line)."""

    index: int
    kind: str
    score: float
    box: np.ndarray
    placed: WindowResult | None = None
    wall: int | None = None
    reason: str | None = None
    outline: str | None = None  # a placed door's quad: "mask" (the mask fit) or "box" (the detection's box)
    window_share: float | None = None  # a placed door's height over its wall's median window height
    foot_share: float | None = None  # its foot's height above its wall's lowest window sill, over that median

    @property
    def exported(self) -> bool:
        return self.reason is None

    def to_json(self) -> dict:
        """windows.json's entry: index, kind, score, box, wall, exported, not_exported, and a
        placed door's quad, width_m, height_m, partial and cut."""
        p = self.placed
        out = {"index": self.index, "kind": self.kind, "score": float(self.score),
               "box": np.asarray(self.box, dtype=np.float64).tolist(), "wall": self.wall,
               "exported": self.exported, "not_exported": self.reason}
        if p is not None and p.R is not None:
            out.update(outline=self.outline, window_share=self.window_share, foot_share=self.foot_share, quad=np.asarray(p.quad_snapped).tolist(), width_m=float(p.aspect_ratio) * float(p.height_m),
                       height_m=float(p.height_m), partial=p.partial is not None,
                       cut=[] if p.partial is None else list(p.partial.cut))
        return out


def box_quad(box: np.ndarray) -> np.ndarray:
    """The corners (4, 2) px TL TR BR BL of a box (4,) x0 y0 x1 y1 on the pixel-edge outline, at
    pixel centres (the outermost pixels' centres)."""
    x0, y0, x1, y1 = np.asarray(box, dtype=np.float64).reshape(4)
    return np.array([[x0 + 0.5, y0 + 0.5], [x1 - 0.5, y0 + 0.5], [x1 - 0.5, y1 - 0.5], [x0 + 0.5, y1 - 0.5]])


def door_quad(det: Detection, fit, visible) -> tuple[np.ndarray | None, tuple[str, ...], str, str | None]:
    """(quad (4, 2) px, the photo edges cutting it, its source, reason) of a door from its mask fit
    (a pipeline.reconstruct.QuadFit) and, when that touches the border, its visible part's
    QuadResult: the mask fit's quad ("mask"); cut by the photo's bottom edge only, the visible
    part's; where the mask's outline is not four-sided (a door's mask is often ragged: a frame in a
    dark recess), the detection's box ("box"); cut by another edge, no quad and why."""
    qr = None if fit is None else fit.result
    if qr is not None and qr.quad is not None:
        return np.asarray(qr.quad, dtype=np.float64), (), "mask", None
    cut = () if visible is None else tuple(visible.cut)
    if cut and cut != ("bottom",):
        return None, cut, "", f"the door is cut by the photo's {', '.join(cut)} edge"
    if visible is not None and visible.quad is not None:
        return np.asarray(visible.quad, dtype=np.float64), cut, "mask", None
    return box_quad(det.box), cut, "box", None


def door_wall(quad: np.ndarray, cut: tuple[str, ...], image_size: tuple[int, int], results: list[WindowResult],
              walls: list, K: np.ndarray):
    """The wall a door's quad (4, 2) px belongs on: the one whose vanishing points its sides point
    at (pipeline.facade_model.partial_wall), else the one whose windows' snapped quads lie nearest
    it in the photo; Unavailable without a wall."""
    from fenestra.pipeline.walls.lines import hull_distance  # noqa: PLC0415 (fenestra.pipeline.walls.lines loads SciPy: imported when first used)

    if not walls:
        return Unavailable("no wall with an exported window to put the door in")
    wall = partial_wall(quad, cut, image_size, results, walls, K)
    if not isinstance(wall, Unavailable):
        return wall
    centre = np.asarray(quad, dtype=np.float64).mean(axis=0)[None]
    near = [float(hull_distance(centre, np.array([results[k].quad_snapped for k in w.members]))[0]) for w in walls]
    return walls[int(np.argmax(near))]


def place_door(index: int, det: Detection, fit, visible, results: list[WindowResult], walls: list, exported: set,
               K: np.ndarray, image_size: tuple[int, int]) -> Opening:
    """A door detection as an :class:`Opening`: placed on its wall (:func:`door_quad`,
    :func:`door_wall`, pipeline.facade_model.on_wall), at least DOOR_MIN_WINDOW_SHARE of the
    wall's median window height tall and its foot at most DOOR_FOOT_ABOVE of it above the wall's
    lowest window sill; or with the reason it is not."""
    opening = Opening(index, det.kind, float(det.score), np.asarray(det.box, dtype=np.float64))
    quad, cut, source, why = door_quad(det, fit, visible)
    if quad is None:
        return replace(opening, reason=why)
    opening = replace(opening, outline=source)
    wall = door_wall(quad, cut, image_size, results, walls, K)
    if isinstance(wall, Unavailable):
        return replace(opening, reason=wall.reason)
    base = WindowResult(index, float(det.score), quad, quad, None, None, None, None, None, 1.0, None, None,
                        partial=None if not cut else Partial(cut, Failure("quad", "touches_border",
                                                                          "the door reaches the photo's bottom edge")))
    placed = on_wall(base, quad, wall, results[wall.members[0]].R, K)
    if placed is None:
        return replace(opening, wall=wall.id, reason=f"a corner's ray misses wall {wall.id}'s plane")
    voters = [k for k in wall.members if k in exported] or list(wall.members)  # its windows in the model
    typical = float(np.median([float(results[k].height_m) for k in voters]))
    up = np.asarray(results[wall.members[0]].R, dtype=np.float64)[:, 1]
    lowest = min(float(up @ np.asarray(results[k].t, dtype=np.float64)) for k in voters)
    above = float(up @ np.asarray(placed.t, dtype=np.float64)) - lowest
    opening = replace(opening, placed=placed, wall=wall.id, window_share=float(placed.height_m) / typical,
                      foot_share=above / typical)
    if float(placed.height_m) < DOOR_MIN_WINDOW_SHARE * typical:
        return replace(opening, reason=f"{placed.height_m:.2f} m tall, too low for a door beside its wall's "
                                       f"{typical:.2f} m windows (a door is at least {DOOR_MIN_WINDOW_SHARE:g} of them)")
    if above > DOOR_FOOT_ABOVE * typical:
        return replace(opening, reason=f"its foot is {above:.2f} m above its wall's lowest window sill: a door stands "
                                       f"lower (at most {DOOR_FOOT_ABOVE:g} of a {typical:.2f} m window above it)")
    return opening


def inside_doors(openings: list[Opening]) -> list[Opening]:
    """The openings with every door whose box lies mostly (over half its area) inside a larger
    modelled door's box left out: a part of that door (a leaf, a transom)."""
    out = list(openings)
    doors = sorted((o for o in out if o.kind == "door" and o.exported), key=lambda o: -box_area(o.box))
    kept: list[Opening] = []
    for o in doors:
        host = next((k for k in kept if overlap(o.box, k.box) > 0.5 * box_area(o.box)), None)
        if host is None:
            kept.append(o)
        else:
            out[o.index] = replace(o, reason=f"a part of door {host.index} (its box lies inside that door's)")
    return out


def box_area(b: np.ndarray) -> float:
    x0, y0, x1, y1 = np.asarray(b, dtype=np.float64).reshape(4)
    return max(0.0, x1 - x0) * max(0.0, y1 - y0)


def overlap(a: np.ndarray, b: np.ndarray) -> float:
    """The area (px²) two boxes (4,) x0 y0 x1 y1 share."""
    a, b = np.asarray(a, dtype=np.float64).reshape(4), np.asarray(b, dtype=np.float64).reshape(4)
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def place_openings(dets: list[Detection], fits: list, visible: dict, results: list[WindowResult], model: FacadeModel,
                   exported: set, K: np.ndarray, image_size: tuple[int, int]) -> tuple[Opening, ...]:
    """Every no-window detection ``dets`` (with their quad fits ``fits`` and {index: visible
    part's QuadResult} ``visible``) as an :class:`Opening`: doors placed on the walls holding an
    ``exported`` window (detection indices; ``results`` the windows as the model holds them,
    ``model`` the façade model), signboards left out with their reason, and a
    door inside a larger one left out as its part (:func:`inside_doors`)."""
    walls = [w for w in model.walls if set(w.members) & set(exported)]
    return tuple(inside_doors([place_door(k, d, fits[k], visible.get(k), results, walls, set(exported), K, image_size)
                               if d.kind == "door" else
                               Opening(k, d.kind, float(d.score), np.asarray(d.box, dtype=np.float64),
                                       reason=SIGNBOARD_REASON) for k, d in enumerate(dets)]))
