"""EffWin's box verifier (fenestra/pipeline/detectors/verifier.py, fenestra/training/verifier.py; issue #23 item 5):
the logistic fit, the head's checks on load, the safe weights loader, its pure-torch RoIAlign
against torchvision's, and a head trained on a few real train photos telling held-out doors and
signboards from windows.

The street photos are the spb_facades train split in ../shared/real (not shipped: skipped when absent)."""
from __future__ import annotations

import dataclasses
import hashlib
import io
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from fenestra.errors import FenestraError
from fenestra.pipeline.detectors import DEFAULT_WEIGHTS, detect, get_detector, read_weights
from fenestra.pipeline.detectors import verifier
from fenestra.pipeline.detectors.verifier import FeatureSpec, VerifierHead, head_from_dict, head_to_dict, roi_align
from fenestra.training.verifier import Samples, choose_threshold, fit_head, fit_logistic, label_detections

from spb import SPB, needs_spb as spb_mark

ROOT = Path(__file__).resolve().parents[2]
needs_spb = spb_mark(Path("train") / "labels")
CHANNELS = {"bb32": 112, "bb64": 320, "dec32": 96, "dec16": 64, "dec8": 48}  # an EfficientNet-Lite0 EffWin's


def shipped_channels() -> dict[str, int]:
    """The shipped default network's feature channels (its backbone's: Lite2 since detector v6)."""
    from fenestra.pipeline.detectors.effwin import model_from_checkpoint

    return model_from_checkpoint(read_weights(DEFAULT_WEIGHTS)).feature_channels


def test_logistic_fit_is_the_optimum_of_its_loss_and_deterministic():
    """Newton's solution zeroes the gradient of the class-balanced, L2-penalised log loss, computed
    here independently by torch autograd; two fits are bit-identical."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(300, 5))
    y = (X @ np.array([2.0, -1.0, 0.0, 0.5, 0.0]) + rng.normal(size=300) > 1.0).astype(float)  # 1 : 3 classes
    l2 = 3.0
    w, b = fit_logistic(X, y, l2)
    theta = torch.tensor(np.append(w, b), requires_grad=True)
    Xt, yt = torch.tensor(X), torch.tensor(y)
    z = Xt @ theta[:-1] + theta[-1]
    ll = torch.nn.functional.binary_cross_entropy_with_logits(z, yt, reduction="none")
    loss = ll[yt > 0].mean() * 150 + ll[yt == 0].mean() * 150 + 0.5 * l2 * (theta[:-1] ** 2).sum()
    loss.backward()
    assert theta.grad.abs().max() < 1e-6, theta.grad
    w2, b2 = fit_logistic(X, y, l2)
    assert np.array_equal(w, w2) and b == b2
    with pytest.raises(ValueError, match="both classes"):
        fit_logistic(X, np.ones(300))


def test_labels_follow_the_evaluation_rule_for_doors_and_signboards():
    win, door = np.array([0.0, 0, 10, 20]), np.array([50.0, 0, 70, 40])
    boxes = np.array([[0.0, 1, 10, 21],   # the window
                      [52.0, 2, 68, 38],  # inside the door: intersection over the detection 1
                      [40.0, 0, 80, 80],  # over the door, IoU 0.25 and 0.25 of it on the door: neither
                      [200.0, 0, 210, 10]])
    assert label_detections(boxes, [win], [door]).tolist() == [1, 0, -1, -1]
    assert label_detections(boxes, [], []).tolist() == [-1, -1, -1, -1]


def test_threshold_keeps_the_asked_share_of_windows_at_the_shipped_score():
    p = np.linspace(0.01, 1.0, 100)
    y = np.ones(100, int)
    score = np.where(np.arange(100) < 50, 0.2, 0.9)  # only the upper half is at the shipped score 0.5
    t = choose_threshold(p, y, score, keep_windows=0.9)
    kept = (p[score >= 0.5] >= t).mean()
    assert kept == pytest.approx(0.9, abs=0.021) and kept >= 0.9


def _head(dim_layers=("dec16",), context=1.0) -> VerifierHead:
    spec = FeatureSpec(dim_layers, (16,) * len(dim_layers), context)
    d = sum(CHANNELS[n] for n in dim_layers) * 2 + 10
    return VerifierHead(spec, np.zeros(d), np.ones(d), np.full(d, 0.1), -0.5, 0.3)


@pytest.mark.parametrize("change, message", [
    ({"version": 0}, "version 0"),
    ({"std": [0.0] * 138}, "std has values <= 0"),
    ({"weight": [0.1] * 7}, r"weight has shape \(7,\), expected \(138,\)"),
    ({"layers": ["nope"]}, "unknown feature layers"),
    ({"threshold": 2.0}, "threshold"),
    ({"mean": ["x"] * 138}, "could not convert"),
    ({"bias": float("nan")}, "bias"),
])
def test_bad_head_entries_are_refused_in_one_line(change, message):
    d = head_to_dict(_head(), "f" * 64)
    assert head_from_dict(d, "w.pt", CHANNELS).threshold == 0.3
    with pytest.raises(FenestraError, match=message) as e:
        head_from_dict({**d, **change}, "w.pt", CHANNELS)
    assert "\n" not in str(e.value) and str(e.value).startswith("w.pt: its box verifier is unusable")
    with pytest.raises(FenestraError, match="no 'bias'"):
        head_from_dict({k: v for k, v in d.items() if k != "bias"}, "w.pt", CHANNELS)


def test_a_verifier_beside_another_network_is_refused(tmp_path):
    """The head reads one network's features: the shipped file's network fingerprint is recorded in
    its verifier, and the same verifier beside a network with one weight changed is refused."""
    ckpt = read_weights(DEFAULT_WEIGHTS)
    assert ckpt["verifier"]["network_sha256"] == hashlib.sha256(b"".join(
        f"{k}|{t.dtype}|{tuple(t.shape)}|".encode() + t.contiguous().reshape(-1).view(torch.uint8).numpy().tobytes()
        for k, t in sorted(ckpt["state_dict"].items()))).hexdigest()
    state = dict(ckpt["state_dict"])
    name = next(k for k, t in state.items() if t.is_floating_point())
    state[name] = state[name] + 1.0
    other = tmp_path / "other.pt"
    torch.save({**ckpt, "state_dict": state}, other)
    with pytest.raises(FenestraError, match=f"{other}: its box verifier is unusable: it was fitted on network") as e:
        get_detector("default", weights=other)
    assert "\n" not in str(e.value)


def test_shipped_default_has_a_checked_verifier_and_a_broken_one_names_the_file(tmp_path):
    ckpt = read_weights(DEFAULT_WEIGHTS)
    head = head_from_dict(ckpt["verifier"], str(DEFAULT_WEIGHTS), shipped_channels())
    assert 0.0 < head.threshold < 1.0 and ckpt["verifier"]["meta"]["n_doors_signboards"] > 0
    broken = tmp_path / "broken.pt"
    torch.save({**ckpt, "verifier": {**ckpt["verifier"], "std": [-1.0] * len(head.std)}}, broken)
    with pytest.raises(FenestraError, match=f"{broken}: its box verifier is unusable: std") as e:
        get_detector("default", weights=broken)
    assert "\n" not in str(e.value)
    strided = tmp_path / "strided.pt"
    torch.save({**ckpt, "verifier": {**ckpt["verifier"], "strides": [16, 16]}}, strided)
    with pytest.raises(FenestraError, match=f"{strided}: its box verifier is unusable: strides"):
        get_detector("default", weights=strided)
    # without the key: the detector runs unverified (a weights file from before the verifier)
    plain = tmp_path / "plain.pt"
    torch.save({k: v for k, v in ckpt.items() if k != "verifier"}, plain)
    assert isinstance(detect("default", np.zeros((64, 96, 3), np.uint8), weights=plain), list)


def test_weights_that_would_run_code_when_unpickled_are_refused(tmp_path):
    """read_checkpoint uses torch's restricted unpickler: a pickle calling a function is refused
    with one line naming the file, and the function never runs."""
    ran = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (Path.touch, (ran,))

    bad = tmp_path / "evil.pt"
    buf = io.BytesIO()
    torch.save({"arch": "effwin", "x": Payload()}, buf)
    bad.write_bytes(buf.getvalue())
    with pytest.raises(FenestraError, match=f"{bad} is not a model checkpoint") as e:
        read_weights(bad)
    assert not ran.exists() and "\n" not in str(e.value)


@needs_spb
def test_head_trained_on_a_few_train_photos_tells_held_out_doors_from_windows():
    """The shipped network's features on 24 train photos; a head fitted on 18 of them ranks the
    detections on the other 6 photos: windows above doors and signboards (ROC AUC, an independent
    count over all pairs), and the fitted threshold keeps most of those windows. (16 photos, 4 held
    out, as before detector v3: the v3 network kept 74 % there, 93 % with these 6; 4 photos were too
    few to judge a threshold by.) The photos are the first 24 of the training part of the folder as
    it is: since its cleaning (2026-11-28, 559 -> 445 photos, ../shared/real/README.md) they are
    other photos than before, and the test passes on them unchanged (issue #36)."""
    from fenestra.training.verifier import SPEC, collect, out_of_fold, train_head

    s = collect(DEFAULT_WEIGHTS, SPB / "train", max_photos=24)
    ch = shipped_channels()
    assert set(np.unique(s.y)) == {0, 1} and s.X.shape[1] == 2 * (ch["bb32"] + ch["bb64"]) + 10
    held = s.photo >= np.unique(s.photo)[-6]
    fit = Samples(s.X[~held], s.y[~held], s.score[~held], s.photo[~held], 18)
    head = train_head(fit, SPEC, l2=100.0, keep_windows=0.95).head
    p = head.window_probability(s.X[held])
    pos, neg = p[s.y[held] == 1], p[s.y[held] == 0]
    assert len(pos) >= 10 and len(neg) >= 3, (len(pos), len(neg))
    auc = ((pos[:, None] > neg[None, :]).sum() + 0.5 * (pos[:, None] == neg[None, :]).sum()) / (len(pos) * len(neg))
    assert auc > 0.8, auc
    assert (pos >= head.threshold).mean() > 0.8
    # shuffled labels carry no signal: out of fold, the same features rank no better than chance
    y = np.random.default_rng(0).permutation(s.y)
    q = out_of_fold(dataclasses.replace(s, y=y), SPEC, 100.0, folds=4)
    auc0 = ((q[y == 1][:, None] > q[y == 0][None, :]).mean())
    assert auc0 < auc - 0.1, (auc0, auc)


def _torchvision_roi_align(f, boxes, scale):
    """What the verifier pooled with before: torchvision.ops.roi_align (imported here only)."""
    from torchvision.ops import roi_align as tv_roi_align

    b = torch.from_numpy(np.asarray(boxes, np.float64).reshape(-1, 4))
    rois = torch.cat([torch.zeros((len(b), 1), dtype=b.dtype), b], dim=1).to(f.dtype)
    return tv_roi_align(f, rois, output_size=(2, 2), spatial_scale=scale, sampling_ratio=2, aligned=True)


@pytest.mark.parametrize("stride, hw", [(8, (37, 53)), (16, (20, 12)), (32, (9, 14)), (64, (3, 5)), (16, (1, 1))])
def test_roi_align_equals_torchvision_inside_outside_and_below_a_pixel(stride, hw):
    """Random maps and boxes in input pixels: inside the map, partly and wholly outside it (every
    side), smaller than a pixel of the map or of the input, empty, and on its last row/column."""
    rng = np.random.default_rng(stride + hw[0])
    H, W = hw
    f = torch.from_numpy(rng.normal(size=(1, 7, H, W)).astype(np.float32))
    iw, ih = W * stride, H * stride
    x0 = rng.uniform(-0.5 * iw, 1.2 * iw, 300)
    y0 = rng.uniform(-0.5 * ih, 1.2 * ih, 300)
    size = np.exp(rng.uniform(np.log(0.05), np.log(2.0 * max(iw, ih)), (300, 2)))
    boxes = np.stack([x0, y0, x0 + size[:, 0], y0 + size[:, 1]], axis=1)
    special = np.array([[0.0, 0.0, iw, ih], [-3.0 * iw, -3.0 * ih, -2.0 * iw, -2.0 * ih],
                        [2.0 * iw, 2.0 * ih, 3.0 * iw, 3.0 * ih], [iw - 0.3, ih - 0.3, iw, ih],
                        [-stride, -stride, 0.1, 0.1], [5.0, 5.0, 5.0, 5.0], [iw - stride, 0.0, iw + 2 * stride, ih],
                        [0.3, 0.3, 0.7, 0.9], [-1.5 * stride, 0.0, -0.9 * stride, ih]])
    boxes = np.concatenate([boxes, special])
    ours, theirs = roi_align(f, boxes, 1.0 / stride), _torchvision_roi_align(f, boxes, 1.0 / stride)
    assert ours.shape == theirs.shape == (len(boxes), 7, 2, 2) and ours.dtype == theirs.dtype
    err = (ours - theirs).abs().max().item()
    assert err <= 1e-6, err
    assert (theirs[-8] == 0).all() and (theirs[-7] == 0).all()  # the wholly outside boxes do reach the zero case
    assert len(roi_align(f, np.zeros((0, 4)), 1.0 / stride)) == 0


def _real_photos() -> list[Path]:
    photos = [ROOT / "examples" / "curtainwall" / n for n in ("img017.jpg", "img086.jpg")]
    if not (SPB / "train" / "labels").is_dir():
        return photos
    from fenestra.training.dataset import real_box_photos

    return photos + real_box_photos(SPB / "train", "val")[:3]


def test_verifier_decisions_on_real_photos_are_torchvisions(monkeypatch):
    """The shipped detector with its verifier pooling by :func:`roi_align` and by torchvision's keeps
    the same detections (boxes and scores) on the bundled photos (and 3 spb validation-part photos
    when present), with every score kept (threshold 0)."""
    from fenestra.images import read_image

    n_compared = 0
    for path in _real_photos():
        image = read_image(path)
        ours = detect("default", image, score_threshold=0.0)
        with monkeypatch.context() as m:
            m.setattr(verifier, "roi_align", _torchvision_roi_align)
            theirs = detect("default", image, score_threshold=0.0)
        assert [(tuple(d.box), d.score) for d in ours] == [(tuple(d.box), d.score) for d in theirs], path
        n_compared += len(ours)
    assert n_compared > 0


def test_detecting_imports_neither_torchvision_ops_nor_dynamo():
    """torchvision.ops pulls in torch._dynamo (seconds per process): the default detector, verifier
    included, runs without either (a fresh interpreter)."""
    code = ("import sys, numpy as np\n"
            "from fenestra.pipeline.detectors import detect\n"
            "from fenestra.images import read_image\n"
            "img = read_image('examples/curtainwall/img017.jpg')[:320, :480].copy()\n"
            "n = len(detect('default', img, score_threshold=0.0))\n"
            "print(n, sorted(m for m in ('torch._dynamo', 'torchvision.ops') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True,
                         env={**os.environ, "OMP_NUM_THREADS": "1"}).stdout.split("\n")[-2]
    n, loaded = out.split(" ", 1)
    assert int(n) > 0 and loaded == "[]", out
