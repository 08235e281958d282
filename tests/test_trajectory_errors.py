"""Trajectory corrections as nuisance parameters (calidar.strips.trajectory_errors)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.errors import InputError
from calidar.strips.trajectory_errors import TrajectoryModel, corrections, parse_name


def test_gauss_markov_prior_of_the_blocks():
    m = TrajectoryModel(block_s=2.0, position_sigma_m=0.03, correlation_s=20.0)
    R = m.correlation(30)
    phi = np.exp(-2.0 / 20.0)
    assert np.allclose(np.diag(R), 1.0) and np.allclose(np.diag(R, 1), phi) and np.allclose(np.diag(R, 5), phi**5)
    P = np.linalg.inv(R)  # a first-order Gauss–Markov process: tridiagonal precision
    assert np.allclose(np.triu(P, 2), 0.0, atol=1e-9)
    spans = {1: (0.0, 7.0), 2: (10.0, 11.0)}
    groups = m.prior_correlation(spans)
    assert [names[0] for names, _ in groups] == [f"trajectory_bias_{ax}_1_0" for ax in ("east", "north", "up")]
    assert all(len(names) == 4 for names, _ in groups)  # strip 2 has a single block: nothing to correlate
    assert TrajectoryModel(2.0, 0.03).prior_correlation(spans) == []  # no correlation time: independent


def test_corrections_from_named_block_values():
    m = TrajectoryModel(block_s=10.0, position_sigma_m=0.03, attitude_sigma_rad=1e-5, correlation_s=10.0,
                        attitude_correlation_s=10.0)
    spans = {7: (100.0, 125.0)}
    names = [p.name for p in m.parameters(spans)]
    assert len(names) == 3 * 6 and "trajectory_bias_up_7_2" in names and "trajectory_tilt_east_7_0" in names
    assert parse_name("trajectory_tilt_north_7_1") == ("tilt", 1, 7, 1) and parse_name("boresight_roll") is None
    values = dict.fromkeys(names, 0.0) | {"trajectory_bias_up_7_0": 0.02, "trajectory_tilt_up_7_1": 1e-5}
    c = corrections(values, m, spans)[7]
    assert np.allclose(c.shift[:, 2], [0.02, 0.0, 0.0]) and np.allclose(c.tilt[:, 2], [0.0, 1e-5, 0.0])
    assert list(c.blocks(np.array([99.0, 100.0, 109.9, 110.0, 124.0, 130.0]))) == [0, 0, 0, 1, 2, 2]
    p = c.apply(np.array([[10.0, 0.0, -1000.0]]), np.zeros((1, 3)), np.array([1]))
    # block 1: no shift, a rotation about up by 1e-5 rad: (10, 0) moves along +north by 10 m × 1e-5
    assert p[0, 2] == pytest.approx(-1000.0) and p[0, 1] == pytest.approx(1e-4)
    p0 = c.apply(np.array([[10.0, 0.0, -1000.0]]), np.zeros((1, 3)), np.array([0]))
    assert p0[0, 2] == pytest.approx(-1000.0 + 0.02)


def test_blocks_without_a_prior_are_refused():
    with pytest.raises(InputError, match="need the trajectory's a-priori position σ"):
        TrajectoryModel(block_s=2.0)
    with pytest.raises(InputError, match="block_s: expected a number > 0"):
        TrajectoryModel(block_s=-1.0, position_sigma_m=0.03)
