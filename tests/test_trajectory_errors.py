"""Trajectory corrections as nuisance parameters (calidar.strips.trajectory_errors)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.strips.trajectory_errors import TrajectoryModel, corrections, parse_name


def test_gauss_markov_blocks_keep_the_prior_sigma_and_correlate_neighbours():
    m = TrajectoryModel(block_s=2.0, position_sigma_m=0.03, correlation_s=20.0)
    L = m.mixing(30)
    cov = L @ L.T  # innovations of unit variance
    assert np.allclose(np.diag(cov), 1.0)  # every block has the stated σ
    phi = np.exp(-2.0 / 20.0)
    assert np.allclose(np.diag(cov, 1), phi) and np.allclose(np.diag(cov, 5), phi**5)
    assert np.allclose(TrajectoryModel(2.0, 0.03).mixing(4), np.eye(4))  # no correlation time: independent


def test_corrections_from_named_innovations():
    m = TrajectoryModel(block_s=10.0, position_sigma_m=0.03, attitude_sigma_rad=1e-5, correlation_s=10.0,
                        attitude_correlation_s=10.0)
    spans = {7: (100.0, 125.0)}
    names = [p.name for p in m.parameters(spans)]
    assert len(names) == 3 * 6 and "trajectory_bias_up_7_2" in names and "trajectory_tilt_east_7_0" in names
    assert parse_name("trajectory_tilt_north_7_1") == ("tilt", 1, 7, 1) and parse_name("boresight_roll") is None
    values = dict.fromkeys(names, 0.0) | {"trajectory_bias_up_7_0": 0.02, "trajectory_tilt_up_7_1": 1e-5}
    c = corrections(values, m, spans)[7]
    phi = np.exp(-1.0)
    assert np.allclose(c.shift[:, 2], [0.02, 0.02 * phi, 0.02 * phi**2])
    assert np.allclose(c.tilt[:, 2], [0.0, 1e-5 * np.sqrt(1 - phi**2), 1e-5 * np.sqrt(1 - phi**2) * phi])
    assert list(c.blocks(np.array([99.0, 100.0, 109.9, 110.0, 124.0, 130.0]))) == [0, 0, 0, 1, 2, 2]
    p = c.apply(np.array([[10.0, 0.0, -1000.0]]), np.zeros((1, 3)), np.array([1]))
    # shift, then a rotation about up by the tilt: (10, 0) moves along +north by 10 m × tilt
    assert p[0, 2] == pytest.approx(-1000.0 + 0.02 * phi) and p[0, 1] == pytest.approx(10.0 * c.tilt[1, 2])


def test_blocks_without_a_prior_are_refused():
    with pytest.raises(InputError, match="need the trajectory's a-priori position σ"):
        TrajectoryModel(block_s=2.0)
    with pytest.raises(InputError, match="block_s: expected a number > 0"):
        TrajectoryModel(block_s=-1.0, position_sigma_m=0.03)
