"""The learned corner refinement (snapper ``refine``, fenestra/pipeline/snappers/refine.py): on a fresh render
of a house the detector and the refinement trained on (niedriha) (new cameras and look: seed 7777, not one of
lab/scripts/refine_data.sh's), perturbed exact corners move closer to the render's exact
corners_px; patches are sampled where they say; and a weights file it cannot use is refused in one line."""
import numpy as np
import pytest

from fenestra.errors import FenestraError, one_line
from fenestra.pipeline.snappers import snap
from fenestra.pipeline.snappers.refine import (FLIPS, PATCH, SHIPPED, RefineParams, build_net, from_patch, load_refiner,
                                      sample_patches, to_patch)


def test_patches_are_sampled_where_the_map_says():
    """A linear ramp image: every patch pixel holds the ramp's value at the image point that
    from_patch gives for it, for every mirror, at sub-pixel centres and a scale step."""
    ys, xs = np.mgrid[0:120, 0:140].astype(np.float32)
    g = xs + 200.0 * ys
    centres = np.array([[60.3, 50.7], [61.25, 49.5], [70.9, 55.1], [58.0, 62.6]])
    for step in (1.0, 1.2):
        patches = sample_patches(g, centres, FLIPS, step)
        uv = np.array([[3.0, 7.0], [20.0, 11.0], [PATCH - 1.0, 0.0], [19.0, PATCH - 1.0]])
        for k in range(4):
            for p in uv:
                x, y = from_patch(centres[k:k + 1], FLIPS[k:k + 1], p[None], step)[0]
                assert patches[k, int(p[1]), int(p[0])] == pytest.approx(x + 200.0 * y, abs=0.1)
                assert to_patch(centres[k:k + 1], FLIPS[k:k + 1], np.array([[x, y]]), step)[0] == pytest.approx(p)


def test_refinement_moves_perturbed_corners_of_a_fresh_render_closer(tmp_path):
    from fenestra.rendered_view import read_view
    from fenestra.pipeline.reconstruct import to_gray
    from fenestra.renders.dataset import DatasetConfig, render_dataset

    root = render_dataset(DatasetConfig(scene="niedriha", n_views=10, seed=7777, out_root=str(tmp_path)), progress=False)
    rng = np.random.default_rng(0)
    before, after = [], []
    for d in sorted((root / "views").iterdir()):
        view = read_view(d)
        gray = to_gray(view.image)
        H, W = gray.shape
        for w in view.windows:
            truth = np.asarray(w["corners_px"], float)
            if (w["visible_fraction"] < 0.9 or not all(w["corner_visible"])
                    or not ((truth >= 4).all() and (truth[:, 0] <= W - 5).all() and (truth[:, 1] <= H - 5).all())
                    or min(np.linalg.norm(truth - np.roll(truth, 1, 0), axis=1)) < 15):
                continue
            start = truth + rng.normal(0, 1.5, (4, 2))  # like a detector's mask-fit corners
            q, info = snap("refine", gray, start)
            assert len(info["moved"]) == 4 and np.isfinite(q).all()
            before.append(np.linalg.norm(start - truth, axis=1))
            after.append(np.linalg.norm(q - truth, axis=1))
    before, after = np.concatenate(before), np.concatenate(after)
    assert len(before) >= 30, "the views show too few whole windows"
    print(f"refine on {len(before)} corners: median {np.median(before):.2f} -> {np.median(after):.2f} px")
    assert np.median(after) < 0.7 * np.median(before)
    assert np.mean(after < 1.5) > np.mean(before < 1.5) + 0.15


def test_corrupt_or_mismatched_weights_are_refused_in_one_line(tmp_path):
    import torch

    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a torch file")
    with pytest.raises(FenestraError, match="junk.pt is not a model checkpoint") as e:
        load_refiner(str(junk))
    assert "\n" not in one_line(e.value)

    good = torch.load(SHIPPED, weights_only=True)
    other = {**good, "patch": PATCH + 8}
    torch.save(other, tmp_path / "patch.pt")
    with pytest.raises(FenestraError, match=f"weights for {PATCH + 8} px patches"):
        load_refiner(str(tmp_path / "patch.pt"))

    wider = {**good, "state_dict": build_net((16, 24, 48)).state_dict()}
    torch.save(wider, tmp_path / "shape.pt")
    with pytest.raises(FenestraError, match="do not fit the net of widths") as e:
        load_refiner(str(tmp_path / "shape.pt"))
    assert "\n" not in one_line(e.value)

    torch.save({**good, "arch": "winnet"}, tmp_path / "arch.pt")
    with pytest.raises(FenestraError, match="holds a 'winnet' model"):
        load_refiner(str(tmp_path / "arch.pt"))
    with pytest.raises(FenestraError, match="not found"):
        snap("refine", np.zeros((50, 50), np.uint8), np.array([[10.0, 10], [40, 10], [40, 40], [10, 40]]),
             RefineParams(weights=str(tmp_path / "missing.pt")))
