"""The CCR likelihood as the engine's problem (calidar.adjust.ResidualProblem): its Jacobian against
central differences, its normal matrix the Fisher information, two beams' rows read as one typed block."""

from __future__ import annotations

import numpy as np

from calidar.adjust import SolverOptions, solve
from calidar.adjust.residuals import numerical_jacobian, values_of
from calidar.photon.fit import Layout, Problem, parameter_set
from calidar.photon.likelihood import Shots, count_distribution, simulate_counts

TRUTH = {"along_track_bias": 0.6, "cross_track_bias": -0.9, "footprint_diameter": 11.0, "ccr_peak_photons": 18.0,
         "shot_loss_rate": 0.25}


def two_beams(seed=0) -> Problem:
    """Model-drawn counts over 4 CCR windows seen by two beams, one shared bias."""
    x = np.arange(-17.5, 17.5, 0.7)
    y = np.array([3.0, -4.5, 1.0, -1.5])
    n, m = x.size, y.size
    beam = np.repeat([0, 0, 1, 1], n)
    s = Shots(np.tile(x, m), np.zeros(n * m), np.repeat(y, n), np.full(n * m, 0.02), np.zeros(n * m, np.int64),
              beam, np.full(n * m, 16), np.repeat(np.arange(m), n))
    lay = Layout(("gt1l", "gt2l"), shared_bias=True)
    truth = {**{lay.name(g, b): v for g in range(2) for b, v in TRUTH.items()}, lay.name(1, "footprint_diameter"): 12.0}
    p, _ = count_distribution(lay.theta(truth), s, 0.3)
    return Problem(s.with_counts(simulate_counts(p, np.random.default_rng(seed))), lay, 0.3), truth


def test_the_jacobian_is_central_differences_and_the_normal_matrix_the_information():
    prob, truth = two_beams()
    start = {**truth, "along_track_bias": 1.1, "footprint_diameter[gt1l]": 10.2}
    params = parameter_set(prob.layout, start)
    keys = prob.layout.block.keys
    assert len(keys) == 8 and (None, "along_track_bias") in keys and (1, "footprint_diameter") in keys
    fit = prob.at(params)
    x = params.x()
    J = fit.jacobian(values_of(params, x))
    numeric = numerical_jacobian(fit.residuals, params, x)
    assert J.shape == (len(prob.shots), 8)
    scale = np.abs(numeric).max(axis=0)
    assert np.all(scale > 0)  # every beam's parameters reach some shots
    assert np.all(np.abs(J - numeric).max(axis=0) < 1e-6 * scale)
    info = fit.normal_matrix(values_of(params, x))
    assert np.allclose(info, prob.information(start, params.free_names), rtol=1e-12, atol=0)


def test_solved_through_the_protocol_as_by_functions():
    """solve(problem.at(params), options) is the former lambda call to the last bit."""
    prob, truth = two_beams(1)
    params = parameter_set(prob.layout, {**truth, "along_track_bias": 0.9})
    free = params.free_names
    old = solve(prob.residuals, params, jacobian_fn=lambda v: prob.jacobian(v, free), robust=None, max_iter=40,
                normal_fn=lambda v: prob.scoring_information(v, free))
    new = solve(prob.at(params), SolverOptions(robust=None, max_iter=40))
    assert new.values == old.values and np.array_equal(new.covariance, old.covariance)
    assert abs(new.values["along_track_bias"] - truth["along_track_bias"]) < 4 * new.sigma["along_track_bias"]
