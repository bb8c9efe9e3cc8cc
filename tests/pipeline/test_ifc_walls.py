"""model.ifc's walls and window bodies on a corner building: one IfcWall per façade plane, as far
as the photo shows it, the two walls meeting at their corner; windows and openings square to their
wall; parametric window bodies mapped from their type's.

Two scenes. A render of a corner of a bundled house (FZK-Haus), through reconstruct_photo with
exact masks and K: two walls, each window in its own, meeting at the true corner. And an exact
construction: a building occupying x > 0, y > 0 (world z up, metres), its façade
A the plane y = 0 (outward -y, x to the right seen from outside), its façade B the plane x = 0
(outward -x, -y to the right), so the corner line is x = y = 0. A camera at EYE looks at the
corner; every window's reconstruction is exact (its pose from the construction). Expected extents
come from this file's own ray casting, never from the exporter's helpers.
"""
from __future__ import annotations

import json

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.element
import ifcopenshell.util.placement
import ifcopenshell.validate
import numpy as np
import pytest

from fenestra.conventions import K_from_fov, look_at
from fenestra.pipeline.export import write_outputs
from fenestra.pipeline.export.geometry import COVERING_THICKNESS_M, PlacedWindow
from fenestra.pipeline.export.ifc_window import TYPE_SIZE_REL, type_sizes
from fenestra.pipeline.export.walls_plan import one_plane
from fenestra.pipeline.types import WindowResult
from fenestra.tolerances import TOL

IMG_W, IMG_H = 1280, 720
K = K_from_fov(IMG_W, IMG_H, 45.0)
EYE = np.array([-11.0, -9.0, 1.7])
R_W, T_W = look_at(EYE, [0.0, 0.0, 4.0])  # world -> camera
# each façade's frame in the world: columns x (along, to the right seen from outside), y (up), z (outward)
FRAME = {k: np.column_stack([v[0], v[1], v[2]]) for k, v in
         {"A": ([1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]), "B": ([0, -1.0, 0], [0, 0, 1.0], [-1.0, 0, 0])}.items()}
# (façade, x0 along its frame's x from the corner, sill z, w, h) m; B's x runs towards the corner
VOIDS = [("A", 1.5, 1.0, 1.20, 1.5), ("A", 4.0, 1.0, 1.20 * (1 + 0.6 * TYPE_SIZE_REL), 1.5),
         ("A", 1.5, 4.2, 1.20, 1.5), ("B", -3.0, 1.0, 0.9, 1.2), ("B", -6.5, 1.0, 0.9, 1.2),
         ("B", -3.0, 4.2, 0.9, 1.2)]
WALLS = {0: 0, 1: 2, 2: 0, 3: 1, 4: 1, 5: 1}  # façade A fitted as two walls (0 and 2) of one plane
SKEW_DEG = 4.0  # window 2's own rotation is off its wall's by this (about its vertical), as fits are
SKEWED = 2


def _rot_z(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def window_results() -> list[WindowResult]:
    """Each void's exact reconstruction (window SKEWED's rotation turned SKEW_DEG about the vertical
    through its centre, its centre kept)."""
    out = []
    for i, (side, x0, z0, w, h) in enumerate(VOIDS):
        F = FRAME[side]
        R = F if i != SKEWED else _rot_z(SKEW_DEG) @ F
        centre = F @ np.array([x0 + w / 2, z0 + h / 2, 0.0])  # world (both frames' origin is the corner's foot)
        origin = centre - R @ np.array([w / 2, h / 2, 0.0])
        X = np.array([[0, h, 0], [w, h, 0], [w, 0, 0], [0, 0, 0]], dtype=np.float64) @ R.T + origin
        Xc = X @ R_W.T + T_W
        q = (Xc @ K.T)[:, :2] / (Xc @ K.T)[:, 2:]
        out.append(WindowResult(i, 0.9, q, q, w / h, "general", None, R_W @ R, R_W @ origin + T_W, h, q, None))
    return out


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    out = tmp_path_factory.mktemp("corner")
    photo = np.random.default_rng(1).integers(60, 200, (IMG_H, IMG_W, 3), dtype=np.uint8)
    paths = write_outputs(out, photo, K, window_results(), walls=WALLS)
    return paths, json.loads(paths["manifest"].read_text()), ifcopenshell.open(str(paths["ifc"]))


def world(manifest: dict, X: np.ndarray) -> np.ndarray:
    """Export-world points (N, 3) -> the scene's world, through export.json's world_frame."""
    M = np.asarray(manifest["world_frame"]["camera_to_export"])
    cam = (np.asarray(X, dtype=np.float64).reshape(-1, 3) - manifest["world_frame"]["offset_m"]) @ M
    return (cam - T_W) @ R_W


def _placement(product) -> np.ndarray:
    return np.asarray(ifcopenshell.util.placement.get_local_placement(product.ObjectPlacement))


def _walls(ifc) -> dict:
    """{façade letter: IfcWall}, by the façade its first opening's window is on."""
    out = {}
    for wall in ifc.by_type("IfcWall"):
        i = int(wall.HasOpenings[0].RelatedOpeningElement.HasFillings[0].RelatedBuildingElement.Name.split()[1])
        out[VOIDS[i][0]] = wall
    return out


def _qto(product) -> dict:
    return ifcopenshell.util.element.get_psets(product)["Qto_WallBaseQuantities"]


def photo_edge_on_plane(u: float, normal_axis: int) -> float:
    """The farthest point along its façade where the rays through the photo's column ``u`` (its top
    and bottom pixel edges) meet the façade plane {world[normal_axis] = 0}: the largest |coordinate|
    along the façade, m (this file's own ray casting)."""
    hits = []
    for v in (-0.5, IMG_H - 0.5):
        d = R_W.T @ np.linalg.solve(K, [u, v, 1.0])
        s = -EYE[normal_axis] / d[normal_axis]
        assert s > 0
        hits.append(EYE + s * d)
    along = 1 - normal_axis  # A (y = 0) runs along x, B (x = 0) along y
    return max(abs(p[along]) for p in hits)


def test_the_model_is_valid(model):
    logger = ifcopenshell.validate.json_logger()
    ifcopenshell.validate.validate(model[2], logger, express_rules=True)
    assert logger.statements == []


def test_two_walls_one_per_facade_plane_each_window_in_its_own(model):
    _, _, ifc = model
    walls = _walls(ifc)
    assert len(ifc.by_type("IfcWall")) == 2 and set(walls) == {"A", "B"}
    for side, wall in walls.items():
        filled = sorted(int(rel.RelatedOpeningElement.HasFillings[0].RelatedBuildingElement.Name.split()[1])
                        for rel in wall.HasOpenings)
        assert filled == [i for i, v in enumerate(VOIDS) if v[0] == side]
    psets = ifcopenshell.util.element.get_psets(walls["A"])["Fenestra_Wall"]
    assert psets["MergedWalls"] == "0, 2" and psets["CornerWith"] == walls["B"].Name
    (joint,) = ifc.by_type("IfcRelConnectsPathElements")  # A starts at the corner (x from it), B ends there
    ends = {joint.RelatingElement.id(): joint.RelatingConnectionType, joint.RelatedElement.id(): joint.RelatedConnectionType}
    assert ends == {walls["A"].id(): "ATSTART", walls["B"].id(): "ATEND"}


def test_the_walls_meet_at_the_corner_and_end_where_the_photo_does(model):
    """Each wall's photographed face (COVERING_THICKNESS_M in front of its solid) starts or ends on
    the corner line x = y = 0 within TOL.corner_meet_m; its other end is where the photo's edge
    (A: the right column, B: the left one) meets its plane."""
    _, manifest, ifc = model
    for side, wall in _walls(ifc).items():
        M = _placement(wall)
        length = _qto(wall)["Length"]
        ends = (M @ np.array([[0, -COVERING_THICKNESS_M, 0, 1], [length, -COVERING_THICKNESS_M, 0, 1]]).T).T[:, :3]
        ends = world(manifest, ends)
        near, far = sorted(ends, key=lambda p: np.hypot(p[0], p[1]))
        assert np.hypot(near[0], near[1]) < TOL.corner_meet_m, (side, near)
        axis = 1 if side == "A" else 0
        assert abs(near[axis]) < 1e-6 and abs(far[axis]) < 1e-6  # on the façade's plane
        expected = photo_edge_on_plane(IMG_W - 0.5 if side == "A" else -0.5, axis)
        assert abs(far[1 - axis]) == pytest.approx(expected, abs=1e-6), side


def test_walls_stand_on_the_ground_and_reach_the_photos_top(model):
    """The walls' bottom is the export world's ground (z = 0); their top the highest point where
    the photo's top edge meets their plane (the far end of it: this file's ray casting)."""
    _, manifest, ifc = model
    ground = world(manifest, np.array([[0.0, 0.0, 0.0]]))[0, 2]
    for side, wall in _walls(ifc).items():
        assert _placement(wall)[2, 3] == pytest.approx(0.0, abs=1e-9)
        axis = 1 if side == "A" else 0
        u = IMG_W - 0.5 if side == "A" else -0.5
        d = R_W.T @ np.linalg.solve(K, [u, -0.5, 1.0])
        top = EYE + (-EYE[axis] / d[axis]) * d
        assert _qto(wall)["Height"] == pytest.approx(top[2] - ground, abs=1e-6), side


def test_openings_and_windows_are_square_to_their_wall(model):
    """Every opening's extrusion and every window's y axis run along its wall's y (the layer
    direction), the skewed window's too; its opening keeps its measured size about its centre."""
    _, manifest, ifc = model
    for wall in ifc.by_type("IfcWall"):
        n = _placement(wall)[:3, 1]
        for rel in wall.HasOpenings:
            opening = rel.RelatedOpeningElement
            (solid,) = opening.Representation.Representations[0].Items
            d = _placement(opening)[:3, :3] @ np.asarray(solid.ExtrudedDirection.DirectionRatios)
            assert abs(d @ n) == pytest.approx(1.0, abs=1e-12)
            window = opening.HasFillings[0].RelatedBuildingElement
            Mw = _placement(window)
            assert np.allclose(Mw[:3, :3], _placement(wall)[:3, :3], atol=1e-12)
            i = int(window.Name.split()[1])
            side, x0, z0, w, h = VOIDS[i]
            assert (solid.SweptArea.XDim, solid.SweptArea.YDim) == pytest.approx((w, h), abs=1e-9)
            centre = world(manifest, (Mw @ np.array([w / 2, 0, h / 2, 1.0]))[:3])[0]
            assert centre == pytest.approx(FRAME[side] @ np.array([x0 + w / 2, z0 + h / 2, 0.0]), abs=1e-6), i


def test_window_bodies_are_their_types_parametric_body_mapped_to_each_size(model):
    """Types carry the SweptSolid body (RepresentationMaps); windows map it (MappedRepresentation);
    the two sizes of façade A within TYPE_SIZE_REL share a type; each window's built body spans its
    measured width and height in its wall's axes (x, z), inside the wall (y > 0)."""
    _, _, ifc = model
    settings = ifcopenshell.geom.settings()
    types = {}
    for window in ifc.by_type("IfcWindow"):
        i = int(window.Name.split()[1])
        wtype = ifcopenshell.util.element.get_type(window)
        types.setdefault(VOIDS[i][0], set()).add(wtype.id())
        assert wtype.PredefinedType == "WINDOW" and window.PredefinedType == "WINDOW"
        (body_map,) = wtype.RepresentationMaps
        assert body_map.MappedRepresentation.RepresentationType == "SweptSolid"
        assert all(it.is_a("IfcExtrudedAreaSolid") for it in body_map.MappedRepresentation.Items)
        assert {a.Name for a in body_map.HasShapeAspects} == {"Lining", "Framing", "Glazing"}
        (rep,) = window.Representation.Representations
        assert rep.RepresentationType == "MappedRepresentation" and rep.Items[0].MappingSource == body_map
        V = np.asarray(ifcopenshell.geom.create_shape(settings, window).geometry.verts).reshape(-1, 3)
        _, _, _, w, h = VOIDS[i]
        assert (np.ptp(V[:, 0]), np.ptp(V[:, 2])) == pytest.approx((w, h), abs=1e-6), i
        assert V[:, 0].min() == pytest.approx(0.0, abs=1e-6) and V[:, 1].min() > 0
        q = ifcopenshell.util.element.get_psets(window)["Qto_WindowBaseQuantities"]
        assert (q["Width"], q["Height"], q["Area"], q["Perimeter"]) == pytest.approx((w, h, w * h, 2 * (w + h)))
    assert {k: len(v) for k, v in types.items()} == {"A": 1, "B": 1}


def test_type_sizes_groups_within_the_share_only():
    """Sizes within TYPE_SIZE_REL of the most shared one form its type; one 30 % wider does not."""
    pw = [PlacedWindow(i, w, h, np.eye(3), np.array([0, 0, 10.0]))
          for i, (w, h) in enumerate([(1.0, 1.5), (1.05, 1.5), (0.97, 1.46), (1.3, 1.5)])]
    t = type_sizes(pw)
    assert t[0] == t[1] == t[2] != t[3]
    assert (t[0].width_m, t[0].height_m) == (1.0, 1.5) and (t[3].width_m, t[3].height_m) == (1.3, 1.5)


def test_one_plane_needs_both_the_normal_and_the_distance():
    """A plane turned by more than TOL.facade_plane_deg, or set back by more than
    TOL.facade_plane_offset_rel of its distance, is another plane."""
    base = PlacedWindow(0, 1.0, 1.0, np.eye(3), np.array([0.0, 0.0, 20.0]))
    moved = PlacedWindow(1, 1.0, 1.0, np.eye(3), np.array([3.0, 1.0, 20.0 * (1 + 0.5 * TOL.facade_plane_offset_rel)]))
    setback = PlacedWindow(2, 1.0, 1.0, np.eye(3), np.array([0.0, 0.0, 20.0 * (1 + 2 * TOL.facade_plane_offset_rel)]))
    c, s = np.cos(np.radians(2 * TOL.facade_plane_deg)), np.sin(np.radians(2 * TOL.facade_plane_deg))
    turned = PlacedWindow(3, 1.0, 1.0, np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]), np.array([0.0, 0.0, 20.0]))
    assert one_plane(base, moved) and not one_plane(base, setback) and not one_plane(base, turned)


# --- a render of a corner of a bundled house, through `fenestra reconstruct` ---------------------

@pytest.fixture(scope="module")
def rendered_corner(tmp_path_factory):
    """FZK-Haus's south-west corner (the façades x = 0 and y = 0 meet on the line x = y = 0) seen
    diagonally, rendered (pyrender), reconstructed with the render's K, the exact masks of its four
    ground-floor windows (1.2 m tall: the gable's 1 m window, the façade model's only window of a
    typical shape, would set its wall's scale alone) and that known height; returns (camera,
    {window index: its façade's normal axis, from the true window nearest its quad}, output folder)."""
    import cv2

    from fenestra import PhotoOptions, reconstruct_photo
    from fenestra.pipeline.facade_model import Known
    from fenestra.renders.camera import Camera
    from fenestra.renders.raster import RasterRenderer
    from fenestra.scenes import load_scene

    scene = load_scene("fzk-haus")
    R, t = look_at([-10.0, -10.0, 1.7], [1.5, 1.5, 2.2])
    cam = Camera.from_fov(1280, 720, 60, R, t)
    with RasterRenderer(scene) as r:
        view = r.render(cam)
    gt = [w for w in view.windows if w.visible_fraction > 0.9 and w.corners_world[:, 2].max() < 3.0]
    assert len(gt) == 4
    masks = np.where(np.isin(view.instances, [w.instance_id for w in gt]), view.instances, 0)
    folder = tmp_path_factory.mktemp("fzk-corner")
    cv2.imwrite(str(folder / "image.png"), cv2.cvtColor(view.rgb, cv2.COLOR_RGB2BGR))
    cv2.imwrite(str(folder / "instances.png"), masks.astype(np.uint16))
    (folder / "K.json").write_text(json.dumps({"K": cam.K.tolist()}))
    reconstruct_photo(folder / "image.png", folder / "out", K_json=folder / "K.json", masks=folder / "instances.png",
                      options=PhotoOptions(known=Known(window_height_m=1.2)))
    doc = json.loads((folder / "out" / "windows.json").read_text())
    axis = {}
    for w in doc["windows"]:
        c = np.asarray(w["quad_snapped"]).mean(axis=0)
        g = min(gt, key=lambda g: np.linalg.norm(g.corners_px.mean(axis=0) - c))
        n = np.cross(g.corners_world[1] - g.corners_world[0], g.corners_world[3] - g.corners_world[0])
        axis[w["index"]] = int(np.argmax(np.abs(n)))
    return cam, axis, folder / "out"


# the rendered corner's reconstruction places its windows 0.1-0.2 m from the truth (pose and scale
# from four quads); the corner, the intersection of the two fitted planes, is held to about that
CORNER_TRUTH_M = 0.3


def test_a_rendered_corner_gives_two_walls_meeting_on_the_true_corner(rendered_corner):
    """Two IfcWalls, each holding the windows of one façade; their photographed faces' corner
    edges touch (within TOL.corner_meet_m: each ends on the fitted planes' intersection), and that
    corner stands within CORNER_TRUTH_M of the true one (x = y = 0) at its foot and 3 m up."""
    cam, axis, out = rendered_corner
    manifest = json.loads((out / "export.json").read_text())
    ifc = ifcopenshell.open(str(out / "model.ifc"))
    walls = ifc.by_type("IfcWall")
    assert len(walls) == 2 and sorted(axis.values()) == [0, 0, 1, 1]
    M_ce = np.asarray(manifest["world_frame"]["camera_to_export"])

    def to_world(X):  # export world -> camera (export.json) -> the house's world (the render's camera)
        return ((np.asarray(X) - manifest["world_frame"]["offset_m"]) @ M_ce - cam.t) @ cam.R

    ends = []
    for wall in walls:
        held = {int(rel.RelatedOpeningElement.HasFillings[0].RelatedBuildingElement.Name.split()[1])
                for rel in wall.HasOpenings}
        assert held == {i for i, a in axis.items() if a == axis[next(iter(held))]}  # one whole façade
        assert ifcopenshell.util.element.get_psets(wall)["Fenestra_Wall"]["CornerWith"]
        M = _placement(wall)
        q = ifcopenshell.util.element.get_psets(wall)["Qto_WallBaseQuantities"]
        local = np.array([[x, -COVERING_THICKNESS_M, z, 1.0] for x in (0.0, q["Length"]) for z in (0.0, q["Height"])])
        ends.append(to_world((local @ M.T)[:, :3]).reshape(2, 2, 3))  # [start, end] x [foot, head]
    (a, b) = ends
    gap, ia, ib = min((_edge_gap(a[i], b[j]), i, j) for i in range(2) for j in range(2))
    assert gap < TOL.corner_meet_m
    for e in (a[ia], b[ib]):
        for z in (0.0, 3.0):  # the corner edge's point at height z, off the true corner line
            p = e[0] + (z - e[0, 2]) / (e[1, 2] - e[0, 2]) * (e[1] - e[0])
            assert np.hypot(p[0], p[1]) < CORNER_TRUTH_M, p


def _edge_gap(e: np.ndarray, f: np.ndarray) -> float:
    """The closest approach (m) of segments e and f ((2, 3) each): e sampled every 1/2000 of its
    length, each sample's distance to segment f."""
    P = e[0] + np.linspace(0.0, 1.0, 2001)[:, None] * (e[1] - e[0])
    d = f[1] - f[0]
    s = np.clip((P - f[0]) @ d / (d @ d), 0.0, 1.0)
    return float(np.linalg.norm(P - (f[0] + s[:, None] * d), axis=1).min())
