"""EffWin, the pretrained-backbone detector (fenestra/pipeline/detectors/effwin.py) and its training pieces:
offline ImageNet weights, corner targets and their sub-pixel read-out, corner quads, the crop
geometry that moves corners with the pixels, real box photos, and a tiny training run."""
import csv
import socket
from pathlib import Path

import numpy as np
import pytest
import torch

from fenestra.pipeline.detectors.effwin import (MIRRORED_CHANNELS, EffWin, EffWinConfig, corner_heatmaps, efficientnet_lite,
                                       instance_corners, mirror_mean, predict_maps, pretrained_backbone_path)
from fenestra.pipeline.quad import corners_to_quad
from toy_data import write_toy_dataset
from fenestra.training.augment import AugmentConfig, random_scale_crop
from fenestra.training.train import load_config, train


@pytest.mark.parametrize("backbone", ["efficientnet-lite0", "efficientnet-lite2"])
def test_pretrained_backbone_loads_from_the_installed_wheel_without_network(monkeypatch, backbone):
    """Every ImageNet tensor comes from the wheel's file, with sockets disabled."""
    def no_network(*a, **k):
        raise OSError("network access attempted")
    monkeypatch.setattr(socket.socket, "connect", no_network)
    monkeypatch.setattr(socket, "create_connection", no_network)
    path = Path(pretrained_backbone_path(backbone))
    assert path.is_file() and path.stat().st_size > 10_000_000 and path.name.startswith(backbone)
    state = torch.load(path, map_location="cpu", weights_only=True)
    net = efficientnet_lite(backbone, pretrained=True)
    own = net.state_dict()
    assert set(own) == set(state)
    assert all(torch.equal(own[k], state[k]) for k in state)
    # The detector's encoder holds the same tensors; its classifier head is gone.
    model = EffWin(EffWinConfig(backbone), pretrained=True)
    assert torch.equal(model.stem[0].weight, state["_conv_stem.weight"])
    assert torch.equal(model.blocks[15]._project_conv.weight, state["_blocks.15._project_conv.weight"])
    assert not any(k.startswith("_fc") for k in model.state_dict())
    out = model.eval()(torch.zeros(1, 3, 128, 192))
    assert out.shape == (1, 6, 128, 192) and torch.isfinite(out).all()


def test_unknown_backbone_is_named():
    with pytest.raises(ValueError, match="efficientnet-lite7"):
        efficientnet_lite("efficientnet-lite7")


def test_corner_heatmaps_peak_at_the_corners_and_read_back_subpixel():
    quad = np.array([[20.3, 15.6], [60.8, 17.2], [58.4, 50.7], [22.1, 48.5]])  # TL TR BR BL
    heat = corner_heatmaps(quad[None], (70, 90), sigma=1.5)
    assert heat.shape == (4, 70, 90) and heat.max() <= 1.0
    for c, (x, y) in enumerate(quad):  # the peak pixel is the nearest pixel centre
        iy, ix = np.unravel_index(np.argmax(heat[c]), heat[c].shape)
        assert (ix, iy) == (round(x), round(y))
    mask = np.zeros((70, 90), bool)
    mask[16:49, 21:60] = True
    got = instance_corners(heat, mask)
    # a parabola through the log of a sampled Gaussian: its vertex is the exact centre
    assert np.abs(got - quad).max() < 1e-3, got - quad
    # an unseen corner (NaN) draws nothing and its instance gets no corners
    q2 = quad.copy()
    q2[2] = np.nan
    assert instance_corners(corner_heatmaps(q2[None], (70, 90)), mask) is None


def test_mirror_mean_maps_a_mirrored_window_back_onto_the_window():
    """The maps a network would give for the mirrored image of a window (its void, and its corners:
    the mirror's TL is the window's TR) come back, through mirror_mean, as the window's own maps."""
    H, W = 40, 64
    quad = np.array([[10.0, 8.0], [40.0, 10.0], [38.0, 30.0], [12.0, 29.0]])  # TL TR BR BL
    mirrored = np.stack([W - 1 - quad[:, 0], quad[:, 1]], axis=1)[[1, 0, 3, 2]]  # its TL TR BR BL
    void = np.zeros((H, W), np.float32)
    void[9:30, 11:40] = 1.0

    def maps(q, v):
        return np.concatenate([v[None], 0.5 * v[None], corner_heatmaps(q[None], (H, W))]).astype(np.float32)

    own, of_mirror = maps(quad, void), maps(mirrored, void[:, ::-1])
    got = mirror_mean(torch.from_numpy(np.stack([own, of_mirror])))[0].numpy()
    assert MIRRORED_CHANNELS == (0, 1, 3, 2, 5, 4)
    np.testing.assert_allclose(got, own, atol=1e-3)  # the heatmaps are truncated Gaussians: tails differ by 2e-4


def test_mirror_averaged_maps_of_the_shipped_network_are_mirror_equivariant():
    """With ``mirror`` the maps of a mirrored photo are the mirrored maps of the photo, corners
    swapped left for right (a size the network's stride divides, so no padding moves)."""
    from fenestra.pipeline.detectors import DETECTORS, load_model

    _, net, _ = load_model(DETECTORS["default"].model, None, any_arch=True)
    image = (np.random.default_rng(0).random((96, 128, 3)) * 255).astype(np.uint8)
    a = predict_maps(net, image, mirror=True)
    b = predict_maps(net, np.ascontiguousarray(image[:, ::-1]), mirror=True)
    np.testing.assert_allclose(a, b[list(MIRRORED_CHANNELS)][:, :, ::-1], atol=1e-5)
    assert np.abs(predict_maps(net, image) - a).max() > 1e-3  # without the mirror they differ


def test_corners_to_quad_orders_and_refuses_degenerate_corners():
    quad = np.array([[10.0, 10.0], [50.0, 12.0], [48.0, 40.0], [12.0, 38.0]])
    r = corners_to_quad(quad[[2, 1, 0, 3]])  # walked the other way round from BR: TL TR BR BL out
    np.testing.assert_allclose(r.quad, quad)
    for k in range(4):  # side k passes through corners k, k+1 with an outward normal
        n, c = r.lines[k, :2], r.lines[k, 2]
        assert abs(n @ quad[k] - c) < 1e-9 and abs(n @ quad[(k + 1) % 4] - c) < 1e-9
        assert n @ quad.mean(axis=0) < c
    assert corners_to_quad(None).failure.code == "no_corners"
    assert corners_to_quad(np.array([[0, 0], [10, 0], [10, 0.5], [0, 0.5]])).failure.code == "not_quadrilateral"
    bowtie = np.array([[0, 0], [10, 10], [10, 0], [0, 10]], float)  # TR and BR swapped: crossed sides
    assert corners_to_quad(bowtie).failure.code == "not_quadrilateral"


def test_crop_warp_moves_points_with_the_pixels():
    """A single marked pixel's centre and the warped point land on the same crop pixel."""
    img = np.zeros((120, 160, 3), np.uint8)
    inst = np.zeros((120, 160), np.int32)
    inst[60:64, 100:104] = 1  # a 4x4 block: its centre (101.5, 61.5)
    cfg = AugmentConfig(scale_range=(0.7, 0.7), hflip_prob=1.0)
    for seed in range(5):
        _, ins, warp = random_scale_crop(img, inst, (64, 64), cfg, np.random.default_rng(seed))
        p = warp.points(np.array([101.5, 61.5]))
        ys, xs = np.nonzero(ins)
        if xs.size == 0:
            continue
        assert abs(p[0] - xs.mean()) < 0.6 and abs(p[1] - ys.mean()) < 0.6, (p, xs.mean(), ys.mean())


def test_real_box_photos_split_and_box_instances(tmp_path):
    import cv2

    from fenestra.training.dataset import box_instances, read_box_photo, real_box_photos

    (tmp_path / "images").mkdir()
    (tmp_path / "labels").mkdir()
    for i in range(7):
        cv2.imwrite(str(tmp_path / "images" / f"p{i}.jpg"), np.full((40, 60, 3), 128, np.uint8))
        if i != 3:  # p3 has no label file: left out
            (tmp_path / "labels" / f"p{i}.txt").write_text("0 0.5 0.5 0.5 0.5\n3 0.1 0.1 0.1 0.1\n")
    val = [p.stem for p in real_box_photos(tmp_path, "val", 3)]
    train_ = [p.stem for p in real_box_photos(tmp_path, "train", 3)]
    assert val == ["p0", "p4"] and train_ == ["p1", "p2", "p5", "p6"]
    image, inst, corners = read_box_photo(tmp_path / "images" / "p0.jpg")
    assert corners is None and image.shape == (40, 60, 3)
    # class 0 box: centre (30, 20) px edges, 30 x 20 -> columns 15..44, rows 10..29; class 3 ignored
    ys, xs = np.nonzero(inst)
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (15, 44, 10, 29) and set(np.unique(inst)) == {0, 1}
    # nested boxes: the small one stays on top of the big one
    both = box_instances([np.array([9.5, 9.5, 19.5, 19.5]), np.array([-0.5, -0.5, 29.5, 29.5])], (30, 30))
    assert (both == 1).sum() == 100 and (both == 2).sum() == 800


def test_effwin_tiny_training_loss_decreases_and_detects(tmp_path):
    from fenestra.pipeline.detectors import detect
    from fenestra.images import read_image

    ds = write_toy_dataset(tmp_path / "toy", n_views=6, seed=1)
    cfg = load_config("fenestra/training/configs/default.toml", data=(str(ds),), out=str(tmp_path / "e.pt"),
                      state_dir=str(tmp_path), iterations=30, batch_size=3, crop_hw=(64, 128), log_every=1,
                      warmup=5, lr=3e-3, real_fraction=0.0, threads=1)
    assert cfg.arch == "effwin" and cfg.pretrained
    path = train(cfg, log=lambda *_: None)
    rows = list(csv.DictReader(open(path.with_suffix(".loss.csv"))))
    assert len(rows) == 30 and "corner_focal" in rows[0]
    loss = np.array([float(r["loss"]) for r in rows])
    assert loss[-10:].mean() < 0.85 * loss[:5].mean(), loss
    img = read_image(ds / "views" / "000000" / "image.png")
    dets = detect("default", img, score_threshold=0.0, weights=path)
    assert all(d.mask.shape == img.shape[:2] for d in dets)
    assert all(d.corners is None or d.corners.shape == (4, 2) for d in dets)


def test_occluders_hide_the_void_they_cover_and_are_off_by_default():
    from dataclasses import replace

    from fenestra.training.augment import occluders

    img = np.full((96, 128, 3), 200, np.uint8)
    inst = np.zeros((96, 128), np.int32)
    inst[20:70, 30:90] = 1
    rng = np.random.default_rng(0)
    same, same_inst, occ = occluders(img, inst, AugmentConfig(), rng)
    assert same is img and same_inst is inst and not occ.any()
    assert rng.random() == np.random.default_rng(0).random()  # off: no draw from the stream
    cfg = replace(AugmentConfig(), occluder_prob=1.0, occluder_max=3)
    for seed in range(6):
        out, ins, occ = occluders(img, inst, cfg, np.random.default_rng(seed))
        assert occ.any() and not ins[occ].any()  # occluded pixels are no longer window
        assert (ins[~occ] == inst[~occ]).all() and (out[~occ] == img[~occ]).all()


def test_evaluate_boxes_scores_real_style_photos_through_detect(tmp_path):
    """`evaluate-detector --yolo`: the validation part of a YOLO folder, window boxes (class 0) as
    ground truth, the photos through detect() (resized: 1800x1200 > 1024 px) and COCO bbox AP.
    The shipped default finds the six drawn dark windows in their white frames."""
    import cv2

    from fenestra.training.evaluate import evaluate_boxes, format_table

    (tmp_path / "images").mkdir()
    (tmp_path / "labels").mkdir()
    H, W = 1200, 1800
    img = np.full((H, W, 3), (190, 160, 130), np.uint8)
    lines = []
    for r in range(2):
        for c in range(3):
            x, y = 200 + c * 550, 150 + r * 550
            cv2.rectangle(img, (x - 25, y - 25), (x + 325, y + 425), (245, 245, 240), -1)
            cv2.rectangle(img, (x, y), (x + 300, y + 400), (40, 50, 70), -1)
            lines.append(f"0 {(x + 150.5) / W} {(y + 200.5) / H} {301 / W} {401 / H}")
    lines.append("5 0.5 0.95 0.1 0.1")  # a door: not a window
    lines.append("3" + lines[0][1:])  # a signboard label on the first window's box: a hard negative
    for name in ("a", "b"):  # "a" is the validation photo (index 0), "b" training
        cv2.imwrite(str(tmp_path / "images" / f"{name}.jpg"), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
        (tmp_path / "labels" / f"{name}.txt").write_text("\n".join(lines) + "\n")
    r = evaluate_boxes("default", tmp_path, part="val", holdout_every=2)
    assert (r["n_images"], r["n_gt"]) == (1, 6) and "segm" not in r
    assert r["bbox"]["AP50"] > 0.8, r["bbox"]
    h = r["hard_negatives"]  # detections at 0.5 on a door or signboard label: the first window's
    assert h["n_det_at_threshold"] >= 6 and h["n_hard_negative"] == 1 and h["n_hard_negative_no_window"] == 0
    assert "1 of" in format_table(r) and "door or signboard" in format_table(r)
    with pytest.raises(ValueError, match="instance maps"):
        evaluate_boxes("oracle", tmp_path)


def test_corner_quads_fall_back_to_the_mask_fit_when_they_disagree_with_the_mask():
    from fenestra.pipeline.quad import QuadParams, corners_agree_with_mask
    from fenestra.pipeline.reconstruct import fit_quads
    from fenestra.pipeline.types import Detection

    mask = np.zeros((60, 80), bool)
    mask[10:40, 20:60] = True  # 40 x 30 px: pixel-edge outline x 19.5..59.5, y 9.5..39.5
    good = np.array([[19.6, 9.4], [59.4, 9.6], [59.5, 39.4], [19.5, 39.5]])
    bad = good.copy()
    bad[2] = [79.0, 59.0]  # one corner on another window: area 1.9x, still convex
    far = good + [100, 0]  # the right shape, somewhere else
    assert corners_agree_with_mask(good, mask) and not corners_agree_with_mask(far, mask)
    box = np.array([19.5, 9.5, 59.5, 39.5])
    dets = [Detection(mask, box, 0.9, corners=c) for c in (good, bad, far, None)]
    fits = fit_quads(dets, QuadParams(source="corners"), mask.shape)
    np.testing.assert_allclose(fits[0].result.quad, good)  # the head's corners, as predicted
    mask_fit = fit_quads(dets[:1], QuadParams(source="mask"), mask.shape)[0].result.quad
    np.testing.assert_allclose(mask_fit, [[19.5, 9.5], [59.5, 9.5], [59.5, 39.5], [19.5, 39.5]], atol=0.05)
    assert corners_agree_with_mask(bad, mask)  # within 2x the area: kept (a plausible quad)
    for f in fits[2:]:  # far away, or no corners: the mask fit
        np.testing.assert_allclose(f.result.quad, mask_fit)
