"""Procedural window styles (scenes.generate.window_parts; issue #23 item 3): a frame ring, mullions
and transoms round glass panes, all inside the void, so the ground truth is the plain house's and the
renderers find the panes as glass."""
import numpy as np
import pytest

from fenestra.scenes.generate import WINDOW_STYLES, HouseSpec, make_house, window_parts


def _area(b):
    return (b[3] - b[0]) * (b[5] - b[2])


def _overlap(a, b):
    return max(0.0, min(a[3], b[3]) - max(a[0], b[0])) * max(0.0, min(a[5], b[5]) - max(a[2], b[2]))


@pytest.mark.parametrize("style", WINDOW_STYLES[1:])
@pytest.mark.parametrize("size", [(0.5, 0.5), (1.2, 1.5), (2.4, 1.1), (0.7, 2.2)])
def test_parts_tile_the_void_inside_it(style, size):
    """Façade-plane check: every box lies inside the w x h void, panes never overlap bars or each
    other, and frame + bars + panes cover the void exactly once (areas add up to w * h)."""
    w, h = size
    for seed in range(5):
        solid, panes = window_parts(w, h, 0.08, style, np.random.default_rng(seed))
        boxes = solid + panes
        assert panes and all(0 <= b[0] < b[3] <= w + 1e-9 and 0 <= b[2] < b[5] <= h + 1e-9 for b in boxes)
        assert all(b[4] - b[1] < 0.04 for b in panes)  # thin: the renderers' glass_faces threshold
        for i, p in enumerate(panes):
            assert all(_overlap(p, q) < 1e-12 for q in solid + panes[i + 1:])
        frame_ring = solid[:4]
        bars = solid[4:]
        ring_area = sum(_area(b) for b in frame_ring) - 0.0  # the ring's four boxes do not overlap
        bar_area = sum(_area(b) for b in bars) - sum(_overlap(a, b) for i, a in enumerate(bars) for b in bars[i + 1:])
        assert abs(ring_area + bar_area + sum(_area(p) for p in panes) - w * h) < 1e-9


def test_style_names_are_checked():
    with pytest.raises(ValueError, match="window style"):
        window_parts(1.0, 1.0, 0.08, "gothic", np.random.default_rng(0))
    with pytest.raises(ValueError, match="window_styles"):
        make_house(HouseSpec(window_styles=("gothic",)), "unused.ifc")


def test_styled_house_keeps_the_ground_truth_and_renders_glass(tmp_path):
    """Read back through the loader (ifcopenshell geometry): the window voids equal the plain
    house's, and the renderers' glass_faces finds one pane component per generated pane."""
    from fenestra.renders.materials import glass_faces
    from fenestra.scenes.loader import load_scene

    base = dict(seed=7, storeys=2, windows_per_wall=2, width_range=(0.8, 1.8), height_range=(1.0, 1.6))
    styled = make_house(HouseSpec(**base, window_styles=WINDOW_STYLES[1:]), tmp_path / "styled.ifc")
    plain = make_house(HouseSpec(**base), tmp_path / "plain.ifc")
    a, b = load_scene(styled.path), load_scene(plain.path)
    assert [w.id for w in a.windows] == [w.id for w in b.windows] and a.windows
    for wa, wb in zip(a.windows, b.windows):
        assert np.allclose(wa.corners_world, wb.corners_world, atol=1e-6)
    normals = {w.id: w.normal for w in a.windows}
    meshes = {m.global_id: m for m in a.meshes if m.ifc_class == "IfcWindow"}
    rng = np.random.default_rng([7, 13])
    n_glass_windows = 0
    for w in styled.windows:  # the same draws as make_house, in its order
        style = WINDOW_STYLES[1:][int(rng.integers(len(WINDOW_STYLES) - 1))]
        _, panes = window_parts(w.width, w.height, 0.08, style, rng)
        m = meshes[w.element_id]
        glass = glass_faces(m.vertices, m.faces, normals[w.element_id])
        big = [p for p in panes if _area(p) >= 0.03]  # glass_faces' minimum pane area
        assert glass.any() == bool(big)
        n_glass_windows += bool(big)
        assert (~glass).any()  # the frame stays frame
    assert n_glass_windows >= len(styled.windows) // 2
