"""The orientation network's prior on the pose CRF's E_o tables (apps.pipeline._with_orientation_prior)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from apps.pipeline import RunOptions, _with_orientation_prior
from posecrf.crops import relative_yaw_shifts
from posecrf.orientnet import N_BINS
from posecrf.pose import PoseEstimate
from posecrf.render import PoseGrid


def _estimate(grid: PoseGrid) -> PoseEstimate:
    yaws = np.arange(grid.n_yaw) * grid.yaw_step
    # E_o of a front/back confusion: two equal minima, at 0 and 180 degrees
    e = 1.0 - 0.1 * np.abs(np.cos(yaws))
    table = np.repeat(e[:, None], grid.n_pitch, axis=1)
    return PoseEstimate("chair", 0.0, 0.2, "m0", "none", 0.5, 0, grid, table, np.stack([table, table + 0.05]),
                        ("m0", "m1"), None)


def test_the_prior_breaks_a_front_back_tie():
    grid = PoseGrid()
    est = _estimate(grid)
    p = np.full(N_BINS, 0.2 / (N_BINS - 1))
    p[N_BINS // 2] = 0.8  # the network: the camera sees the object's back (yaw_rel = 180 deg)
    out = _with_orientation_prior(est, p, 0.1)
    yaws = np.arange(grid.n_yaw) * grid.yaw_step
    assert yaws[np.argmin(out.e_o[:, 0])] == pytest.approx(math.pi)
    for k in range(2):
        assert yaws[np.argmin(out.e_o_models[k, :, 2])] == pytest.approx(math.pi)
    # the same cost for every model and pitch: the models' ranking at a yaw is unchanged
    assert np.allclose(out.e_o_models[1] - out.e_o_models[0], 0.05)
    assert np.allclose(out.e_o[:, 0] - est.e_o[:, 0], out.e_o[:, 3] - est.e_o[:, 3])
    assert est.e_o_at(0.0, 0.2) == est.e_o_at(math.pi, 0.2)  # the input is left alone (frozen records)
    # a uniform network changes nothing
    flat = _with_orientation_prior(est, np.full(N_BINS, 1.0 / N_BINS), 0.1)
    assert np.allclose(flat.e_o, est.e_o)


def test_the_prior_of_two_views_that_agree_breaks_the_tie():
    grid = PoseGrid()
    est = _estimate(grid)
    rays = [np.array([1.0, 0.0, -0.2]), np.array([0.0, 1.0, -0.2])]  # 90 degrees of azimuth apart
    shifts = relative_yaw_shifts(rays)
    # the first view cannot tell front (relative 0 deg) from back (180 deg) either; the second sees the back:
    # relative 270 deg in its own frame is 180 deg in the first one's
    p = np.full((2, N_BINS), 0.1 / (N_BINS - 2))
    p[0, 0] = p[0, N_BINS // 2] = 0.45
    p[1, (N_BINS * 3) // 4] = 0.9
    assert np.argmin(_with_orientation_prior(est, p[0], 0.1).e_o[:, 0]) == 0  # alone: still the tie, 0 first
    out = _with_orientation_prior(est, p, 0.1, shifts)
    yaws = np.arange(grid.n_yaw) * grid.yaw_step
    assert yaws[np.argmin(out.e_o[:, 0])] == pytest.approx(math.pi)
    assert np.allclose(out.e_o_models[1] - out.e_o_models[0], 0.05)


def test_run_options_refuse_an_unknown_orientation_mode():
    assert RunOptions().orientation == "net" and RunOptions(orientation="hog").orientation == "hog"
    assert RunOptions(orientation="net-tile").orientation == "net-tile"
    with pytest.raises(ValueError, match="orientation"):
        RunOptions(orientation="cnn")
