"""The range calibration's observation equations as the engine's problem (calidar.adjust.ResidualProblem)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.adjust.residuals import numerical_jacobian, values_of
from calidar.rangecal.fit import P_PARTS, RangeProblem, observation_sigma
from calidar.sim.total_station import TotalStationSimConfig, simulate_total_station


@pytest.mark.parametrize("fix_scale", [False, True])
def test_the_jacobian_is_central_differences(fix_scale):
    """Offset, scale and every setup's P (slope, vertical angle, direction: one typed block keyed
    (setup, part)) against central differences, away from the start values."""
    obs, _ = simulate_total_station(3, TotalStationSimConfig(n_setups=3))
    prob = RangeProblem(obs, fix_scale)
    params = prob.parameters
    assert prob.p_block.keys == tuple((i, part) for i in range(3) for part in P_PARTS)
    assert np.array_equal(prob.sigma, observation_sigma(obs))
    x = params.x() + np.random.default_rng(1).normal(0.0, 1e-3, params.x().size)
    J = prob.jacobian(values_of(params, x))
    numeric = numerical_jacobian(prob.residuals, params, x)
    assert J.shape == (len(obs), 2 + 9 - fix_scale)
    assert np.max(np.abs(J - numeric)) < 1e-6 * np.max(np.abs(numeric))
