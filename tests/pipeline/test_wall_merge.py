"""Walls of one façade merge by heading about the façade's vertical (facade_model.same_plane), and
the shared vote that finds that vertical (conventions.vote_axis); rotations built by hand."""
from __future__ import annotations

import numpy as np
import pytest

from fenestra.conventions import heading_difference_deg, vote_axis
from fenestra.pipeline.facade_model import same_plane


def wall_R(heading_deg: float, tilt_deg: float = 0.0) -> np.ndarray:
    """A wall's rotation in the camera frame (x right, y down, z forward): its normal (R[:, 2])
    points towards the camera, turned by heading_deg about the vertical, and the wall leans
    tilt_deg back about its own horizontal axis (R[:, 1]: its up axis, -y for an upright wall)."""
    h, t = np.radians(heading_deg), np.radians(tilt_deg)
    yaw = np.array([[np.cos(h), 0, np.sin(h)], [0, 1, 0], [-np.sin(h), 0, np.cos(h)]])
    pitch = np.array([[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    base = np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]])  # x right, up = -y, normal = -z (to the camera)
    return yaw @ pitch @ base


UP = np.array([0.0, -1.0, 0.0])


def test_heading_difference_ignores_tilt():
    assert heading_difference_deg(wall_R(10)[:, 2], wall_R(13, tilt_deg=12)[:, 2], UP) == pytest.approx(3.0, abs=1e-9)
    assert heading_difference_deg(wall_R(0)[:, 2], wall_R(90)[:, 2], UP) == pytest.approx(90.0)
    assert heading_difference_deg(UP, wall_R(0)[:, 2], UP) == 180.0  # a horizontal plane has no heading


def test_tilt_noise_merges_but_a_corner_or_a_leaning_plane_does_not():
    a = wall_R(4, tilt_deg=0.0)
    assert same_plane(a, wall_R(3, tilt_deg=9.0), UP, tol_deg=5.0)  # 9 deg of tilt, 1 deg of heading: one façade
    assert not same_plane(a, wall_R(3, tilt_deg=9.0), None, tol_deg=5.0)  # without a vertical: rotations only
    assert not same_plane(a, wall_R(3, tilt_deg=9.0), UP, tol_deg=5.0, upright_deg=5.0)  # not upright enough
    assert not same_plane(a, wall_R(-43), UP, tol_deg=5.0)  # the other side of a corner
    assert not same_plane(a, wall_R(4, tilt_deg=70.0), UP, tol_deg=10.0)  # a near-horizontal "wall"
    assert same_plane(a, wall_R(10), UP, tol_deg=5.0) is False and same_plane(a, wall_R(10), UP, tol_deg=7.0)  # 6 deg


def test_vote_axis_takes_the_majority_and_averages_it():
    ups = np.array([wall_R(0)[:, 1], wall_R(0, tilt_deg=2)[:, 1], wall_R(0, tilt_deg=40)[:, 1]])
    axis, inl = vote_axis(ups, np.array([3.0, 2.0, 4.0]), agree_deg=5.0)  # 3 + 2 agree, 4 alone
    assert inl.tolist() == [True, True, False]
    expect = 3 * ups[0] + 2 * ups[1]
    assert np.allclose(axis, expect / np.linalg.norm(expect))
    with pytest.raises(ValueError, match="as many weights as axes"):
        vote_axis(ups, np.array([1.0]), 5.0)
