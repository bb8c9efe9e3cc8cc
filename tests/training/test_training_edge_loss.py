"""EffWin's void loss weighted on the outline band of rendered voids (TrainConfig.edge_weight)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from fenestra.training.recipes.effwin import edge_band
from fenestra.training.recipes.winnet import winnet_loss
from fenestra.training.train import TrainConfig


def test_edge_band_of_a_square_by_hand():
    """A 10 x 10 void in a 32 x 32 map, px = 2: the band is the 14 x 14 square minus the 6 x 6 one."""
    v = torch.zeros(1, 32, 32)
    v[0, 8:18, 8:18] = 1
    band = edge_band(v, 2)[0].numpy()
    expect = np.zeros((32, 32))
    expect[6:20, 6:20] = 1
    expect[10:16, 10:16] = 0
    np.testing.assert_array_equal(band, expect)
    assert edge_band(torch.zeros(2, 8, 8), 3).sum() == 0  # no void: no band


def test_void_weight_scales_only_the_void_bce():
    """BCE with weights w is the mean of w x the per-pixel BCE (computed here by hand); the core
    map's BCE and the Dice terms do not change."""
    g = torch.Generator().manual_seed(0)
    logits = torch.randn(2, 2, 16, 16, generator=g)
    target = (torch.rand(2, 2, 16, 16, generator=g) > 0.5).float()
    w = 1.0 + 4.0 * (torch.rand(2, 16, 16, generator=g) > 0.7).float()
    plain, weighted = winnet_loss(logits, target), winnet_loss(logits, target, w)
    p = torch.sigmoid(logits[:, 0])
    by_hand = -(w * (target[:, 0] * torch.log(p) + (1 - target[:, 0]) * torch.log(1 - p))).mean()
    assert float(weighted["void_bce"]) == pytest.approx(float(by_hand), rel=1e-5)
    assert float(weighted["void_bce"]) > float(plain["void_bce"])
    for k in ("core_bce", "void_dice", "core_dice"):
        assert float(weighted[k]) == float(plain[k])


def test_edge_settings_are_checked():
    with pytest.raises(ValueError, match="edge_weight"):
        TrainConfig(arch="effwin", edge_weight=-1.0)
    with pytest.raises(ValueError, match="edge_px"):
        TrainConfig(arch="effwin", edge_px=0)
