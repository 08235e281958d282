"""The strip problem as the engine sees it (calidar.adjust.ResidualProblem): the parameters read as
typed blocks from the engine's values, its Jacobian against central differences, its priors."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from calidar.adjust import ParameterSet
from calidar.adjust.residuals import numerical_jacobian, values_of
from calidar.sensor import Sensor
from calidar.strips.config import Estimate
from calidar.strips.parameters import build_parameters
from calidar.strips.planes import match_pair_planes
from calidar.strips.problem import StripProblem
from calidar.strips.trajectory_errors import TrajectoryModel
from strips_scene import survey


@pytest.fixture(scope="module")
def problem():
    truth = Sensor(boresight_roll=np.radians(0.03), boresight_pitch=np.radians(-0.04))
    strips = survey(truth, Sensor(), [((-250, -80, 0), 90, 500, 400), ((250, 80, 0), 270, 500, 400)], n=40_000)
    c = match_pair_planes(1, strips[0].points, 2, strips[1].points)
    nominal = Sensor(lever_arm_x=0.2, lever_arm_z=0.3, range_offset=0.01)
    spans = {s.id: (float(s.time.min()), float(s.time.max())) for s in strips}
    model = TrajectoryModel(block_s=2.0, position_sigma_m=0.03, attitude_sigma_rad=np.radians(0.05),
                            correlation_s=20.0, attitude_correlation_s=3.0)
    params = build_parameters(nominal, Estimate.of("boresight", "lever_arm", "range_offset"), spans, model)
    rng = np.random.default_rng(7)  # away from zero: the knots' tilts turn the sensor's columns
    params = ParameterSet(replace(p, value=p.value + rng.normal(0.0, p.prior_sigma or (1e-3 if p.unit == "rad" else 0.02)))
                          if p.free else p for p in params)
    return StripProblem(nominal, {s.id: s.pose() for s in strips}, [c], params, {s.id: s.time for s in strips},
                        model, spans), model, spans


def test_typed_blocks_read_what_the_names_say(problem):
    """Residuals from the engine's values (sensor and knots gathered as blocks) equal those from a
    plain name → value mapping, to the last bit; the priors are the model's correlated knots."""
    prob, model, spans = problem
    params = prob.parameters
    by_block = prob.residuals(values_of(params, params.x()))
    assert np.array_equal(by_block, prob(params.values()))
    assert len(prob.knot_block.keys) == sum(p.name.startswith("trajectory_") for p in params)
    assert {k.kind for k in prob.knot_block.keys} == {"bias", "tilt"}
    assert [g for g, _ in prob.prior_correlation] == [g for g, _ in model.prior_correlation(spans)]


def test_the_jacobian_is_central_differences(problem):
    """Every column — boresight, lever arm, range offset (analytic) and the trajectory knots' shifts
    and tilts (exact sparse columns) — equals central differences of the residuals."""
    prob, _, _ = problem
    params = prob.parameters
    x = params.x()
    analytic = prob.jacobian(values_of(params, x)).toarray()
    numeric = numerical_jacobian(prob.residuals, params, x)
    assert analytic.shape == (prob.sigma.size, len(params.free)) and np.all(np.isfinite(analytic))
    scale = np.max(np.abs(numeric), axis=0)
    used = scale > 0
    assert used.sum() > 50  # the sensor and the knots the correspondences reach
    assert np.all(np.abs(analytic - numeric).max(axis=0)[used] <= 1e-6 * scale[used])
    assert np.all(analytic[:, ~used] == 0)


def test_solved_by_blocks_as_by_names(problem):
    """The engine on the problem (sensor and knots read as blocks) and on functions handing it plain
    name → value dicts (read by name) reach the same solution, bit for bit."""
    from calidar.adjust import FunctionProblem, SolverOptions, solve

    prob, _, _ = problem
    by_name = FunctionProblem(lambda v: prob(dict(v)), prob.parameters, sigma=prob.sigma,
                              jacobian_fn=lambda v: prob.jacobian(dict(v)), prior_correlation=prob.prior_correlation)
    a = solve(prob, SolverOptions(max_iter=5))
    b = solve(by_name, SolverOptions(max_iter=5))
    assert a.values == b.values and np.array_equal(a.covariance, b.covariance)
    assert len(a.history) > 2  # it moved
