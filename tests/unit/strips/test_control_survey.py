"""Each control point's survey error as one nuisance parameter (strips/control_survey.py): the
adjustment equals the generalised least squares with the rows' full covariance (an independent
computation with numpy), and over many draws whose survey errors are shared by the strips that see
a point, the range offset's and the height's errors match their σ."""

from __future__ import annotations

import numpy as np

from calidar.adjust import Parameter, ParameterSet, SolverOptions
from calidar.adjust.solver import estimate
from calidar.sensor import Sensor
from calidar.strips.control import CONTROL_ID, ControlPoints, control_correspondences, control_pose
from calidar.strips.control_survey import PREFIX, SurveyErrors, survey_parameters, with_survey_parameters
from calidar.strips.problem import StripProblem
from calidar.strips.strip import Pose, georeference_pose

R_LB = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  #: heading north: body x → north, z → down
FREE = ("range_offset", "lever_arm_z")
SIGMA_C = 0.01  #: the control's survey σ, m


def _strip(x0: float, offset: float, rng, m: int = 12000) -> Pose:
    """A level flight north at x0, 60 m over flat ground (z = 0), scan ±35°, ranges measured with
    ``offset`` and 5 mm noise: a point at scan angle θ is raised by offset·cos θ."""
    y = rng.uniform(-40.0, 40.0, m)
    theta = rng.uniform(-np.radians(35.0), np.radians(35.0), m)
    measured = 60.0 / np.cos(theta) + offset + rng.normal(0.0, 0.005, m)
    return Pose(np.arange(m), np.c_[np.full(m, x0), y, np.full(m, 60.0)], np.repeat(R_LB[None], m, axis=0), measured, theta)


def _control(rng, errors: np.ndarray) -> ControlPoints:
    """Points on the ground between the two lines (each seen by both, at different scan angles),
    surveyed with the height ``errors``."""
    n = errors.size
    xy = np.c_[rng.uniform(-5.0, 35.0, n), rng.uniform(-30.0, 30.0, n)]
    return ControlPoints(np.array([f"P{k}" for k in range(n)]), np.c_[xy, errors], np.full(n, SIGMA_C))


def _problem(rng, offset: float, errors: np.ndarray):
    """The two strips' control rows (no overlap rows: only the control observes range and height)."""
    nominal, control = Sensor(), _control(rng, errors)
    poses = {1: _strip(0.0, offset, rng), 2: _strip(30.0, offset, rng)}
    corrs = [control_correspondences(i, p.index, georeference_pose(nominal, p), len(p.index), control)
             for i, p in poses.items()]
    poses[CONTROL_ID] = control_pose(control, poses[1])
    base = ParameterSet([Parameter(n, 0.0, "m") for n in FREE])
    params = with_survey_parameters(base, control)
    inner = StripProblem(nominal, poses, corrs, params)
    return SurveyErrors(inner, control), inner, control, corrs


def test_the_nuisance_adjustment_is_the_gls_with_the_rows_full_covariance():
    rng = np.random.default_rng(3)
    problem, inner, control, corrs = _problem(rng, 0.05, rng.normal(0.0, SIGMA_C, 10))
    assert [p.name for p in survey_parameters(control)] == [f"{PREFIX}{k}" for k in range(10)]
    assert problem.G.nnz == sum(c.n_obs for c in corrs) == 20  # every point in both strips' rows
    est = estimate(problem, SolverOptions(robust=None))
    sol = est.solution()
    # independently: the rows' full covariance, each point's survey variance shared by its two rows
    values = {n: 0.0 for n in problem.parameters.names}
    J = np.asarray(inner.jacobian(values, problem.inner_free))
    r0 = inner(values)
    own = np.concatenate([c.sigma_m for c in corrs]) ** 2  # a row's own variance: survey + surface
    target = np.concatenate([c.B.tocsr().indices for c in corrs])
    nz = np.concatenate([c.normal[:, 2] for c in corrs])
    same = target[:, None] == target[None, :]
    cov = np.diag(own - SIGMA_C**2) + SIGMA_C**2 * same * np.outer(nz, nz)
    W = np.linalg.inv(cov)
    N_inv = np.linalg.inv(J.T @ W @ J)
    theta = -N_inv @ (J.T @ W @ r0)  # the model is linear in range offset and height
    got = np.array([sol.values[n] for n in FREE])
    np.testing.assert_allclose(got, theta, rtol=1e-6, atol=1e-8)
    i = [sol.parameters.free_names.index(n) for n in FREE]
    C = sol.covariance[np.ix_(i, i)] / max(sol.sigma0**2, 1.0)
    np.testing.assert_allclose(C, N_inv, rtol=1e-6)
    # the Jacobian's nuisance columns are −n_z at each point's rows (the protocol: the problem owns them)
    Jfull = np.asarray(problem.jacobian(values))
    k = problem.parameters.free_names.index(f"{PREFIX}0")
    np.testing.assert_allclose(Jfull[target == 0, k], -nz[target == 0])


def test_the_range_offset_and_height_errors_match_their_sigma_over_draws():
    rng = np.random.default_rng(11)
    z = []
    for _ in range(40):
        problem, *_ = _problem(rng, 0.05, rng.normal(0.0, SIGMA_C, 10))
        sol = estimate(problem, SolverOptions(robust=None)).solution()
        a_priori = np.sqrt(np.diag(sol.covariance)) / max(sol.sigma0, 1.0)
        names = sol.parameters.free_names
        z.append([(sol.values[n] - t) / a_priori[names.index(n)] for n, t in zip(FREE, (0.05, 0.0))])
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((rms > 0.8) & (rms < 1.25)), rms  # sampling spread ±0.11 for 40 draws


def _planes(rng, errors: np.ndarray):
    """Flat 12 m × 12 m patches (z = 0) surveyed at their corners (σ 1 cm), some reaching past the
    first line's swath (|x| ≤ 42 m) so that its points cover part of them: the slopes' errors count."""
    from calidar.strips.control_planes import ControlPlanes

    cx = np.array([0.0, 15.0, 30.0, 40.0, 45.0, 20.0])
    cy = np.array([-20.0, 0.0, 20.0, -10.0, 10.0, -25.0])
    corners = np.array([[-6.0, -6.0], [6.0, -6.0], [6.0, 6.0], [-6.0, 6.0]])
    X = np.c_[np.ones(4), corners]
    cov = SIGMA_C**2 * np.linalg.inv(X.T @ X)
    coef = np.c_[errors[:, 0], errors[:, 1:]]  # the surveyed plane: off by the drawn errors
    hulls = tuple(corners + [x, y] for x, y in zip(cx, cy))
    return ControlPlanes(np.array([f"R{k}" for k in range(cx.size)]), np.c_[cx, cy, errors[:, 0]], coef,
                         np.repeat(cov[None], cx.size, axis=0), hulls), cov


def test_the_planes_height_and_slopes_errors_are_the_gls_with_their_covariance():
    from calidar.strips.control_survey import row_places

    rng = np.random.default_rng(5)
    nominal = Sensor()
    errors = rng.multivariate_normal(np.zeros(3), _planes(rng, np.zeros((6, 3)))[1], 6)
    planes, cov = _planes(rng, errors)
    poses = {1: _strip(0.0, 0.05, rng, 40000), 2: _strip(30.0, 0.05, rng, 40000)}
    corrs = [planes.rows(i, p.index, georeference_pose(nominal, p), len(p.index)) for i, p in poses.items()]
    poses[CONTROL_ID] = control_pose(planes, poses[1])
    params = with_survey_parameters(ParameterSet([Parameter(n, 0.0, "m") for n in FREE]), planes)
    inner = StripProblem(nominal, poses, corrs, params)
    problem = SurveyErrors(inner, planes)
    assert len(problem.prior_correlation) == 6 and problem.G.shape[1] == 18
    sol = estimate(problem, SolverOptions(robust=None)).solution()
    values = {n: 0.0 for n in problem.parameters.names}
    J = np.asarray(inner.jacobian(values, problem.inner_free))
    r0 = inner(values)
    target = np.concatenate([c.B.tocsr().indices for c in corrs])
    nz = np.concatenate([c.normal[:, 2] for c in corrs])
    at = np.concatenate([row_places(inner, i) for i in range(len(corrs))])
    g = nz[:, None] * np.c_[np.ones(len(at)), at[:, :2] - planes.local[target, :2]]
    shared = (target[:, None] == target[None, :]) * (g @ cov @ g.T)  # the same plane's error in both rows
    own = np.concatenate([c.sigma_m for c in corrs]) ** 2
    W = np.linalg.inv(np.diag(own - np.diag(shared)) + shared)
    N_inv = np.linalg.inv(J.T @ W @ J)
    np.testing.assert_allclose([sol.values[n] for n in FREE], -N_inv @ (J.T @ W @ r0), rtol=1e-6, atol=1e-8)
    i = [sol.parameters.free_names.index(n) for n in FREE]
    np.testing.assert_allclose(sol.covariance[np.ix_(i, i)] / max(sol.sigma0**2, 1.0), N_inv, rtol=1e-6)
    assert np.ptp(at[target == 4, 0]) > 3.0  # the plane past the first swath: its two rows stand apart
