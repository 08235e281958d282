"""Control points as strip-adjustment rows (strips/control.py): the control pseudo-strip goes
through StripProblem unchanged, its residuals are the distance of each control point from the
strip's local plane, the analytic Jacobian matches central differences, and a range offset that
no overlap can see is recovered from 10 control points within its σ."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.adjust import Parameter, ParameterSet
from calidar.adjust.solver import numerical_jacobian, solve
from calidar.sensor import Sensor
from calidar.strips.control import CONTROL_ID, ControlPoints, control_correspondences, control_pose
from calidar.strips.problem import StripProblem
from calidar.strips.strip import Pose, georeference_pose

SLOPE = 0.02  #: the ground: z = SLOPE · x (local m)
R_LB = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  #: heading north: body x → north, z → down


def _strip(range_offset_m: float, rng):
    """A level flight north at 60 m over the sloped ground, scan ±35°; ranges measured with
    ``range_offset_m`` (measured = true + offset) and 5 mm noise."""
    m = 20000
    y = rng.uniform(-50.0, 50.0, m)
    theta = rng.uniform(-np.radians(35.0), np.radians(35.0), m)
    true_range = 60.0 / (np.cos(theta) + SLOPE * np.sin(theta))  # where the beam meets z = SLOPE·x
    measured = true_range + range_offset_m + rng.normal(0.0, 0.005, m)
    return Pose(np.arange(m), np.c_[np.zeros(m), y, np.full(m, 60.0)], np.repeat(R_LB[None], m, axis=0), measured, theta)


def _control(rng, n=10):
    xy = np.c_[rng.uniform(-30.0, 30.0, n), rng.uniform(-40.0, 40.0, n)]
    return ControlPoints(np.array([f"GCP{k}" for k in range(n)]), np.c_[xy, SLOPE * xy[:, 0]], np.full(n, 0.01))


def _problem(pose, control, nominal, free):
    pts = georeference_pose(nominal, pose)
    c = control_correspondences(7, pose.index, pts, len(pose.index), control)
    poses = {7: pose, CONTROL_ID: control_pose(control, pose)}
    return StripProblem(nominal, poses, [c], free), c, pts


def test_rows_are_distances_to_the_local_plane_and_the_jacobian_is_exact():
    rng = np.random.default_rng(1)
    pose, control, nominal = _strip(0.0, rng), _control(rng), Sensor()
    free = ["range_offset", "lever_arm_z", "boresight_roll"]
    problem, c, pts = _problem(pose, control, nominal, free)
    assert c.n_obs == 10 and c.strip_b == CONTROL_ID
    values = {"range_offset": 0.05, "lever_arm_z": 0.0, "boresight_roll": 0.0}
    r = problem(values)
    # independently: the points georeferenced with the 5 cm offset, the same rows and normals
    moved = georeference_pose(nominal.with_parameters(range_offset=0.05), pose)
    expected = np.einsum("ij,ij->i", c.A @ moved - control.local, c.normal)
    np.testing.assert_allclose(r, expected, atol=1e-9)
    shift = r - problem({**values, "range_offset": 0.0})  # 5 cm less range: the surface 5 cm·cos θ higher
    assert np.all(shift > 0.05 * np.cos(np.radians(35.0)) - 1e-3) and np.all(shift < 0.05 + 1e-9)
    params = ParameterSet([Parameter(n, values[n], "rad" if n.startswith("bore") else "m") for n in free])
    J = problem.jacobian(values, params.free)
    Jn = numerical_jacobian(problem, params, np.array([values[n] for n in free]))
    np.testing.assert_allclose(J, Jn, atol=1e-6)
    assert np.allclose(J[:, 1], -c.normal[:, 2], atol=1e-3)  # a lever arm down (body z) lowers the surface


def test_a_range_offset_is_recovered_from_ten_control_points():
    rng = np.random.default_rng(2)
    pose, control, nominal = _strip(0.05, rng), _control(rng), Sensor()
    problem, c, _ = _problem(pose, control, nominal, ["range_offset"])
    params = ParameterSet([Parameter("range_offset", 0.0, "m")])
    sol = solve(problem, params, sigma=problem.sigma, jacobian_fn=lambda v: problem.jacobian(v, params.free),
                robust=None)
    err = sol.values["range_offset"] - 0.05
    assert sol.sigma["range_offset"] < 0.01
    assert abs(err) < 2 * sol.sigma["range_offset"], (err, sol.sigma["range_offset"])
    assert problem(sol.values) == pytest.approx(0.0, abs=0.01)


def test_points_and_cells_near_control_reach_every_point_that_can_form_a_plane():
    from calidar.strips.control import RADIUS_M, cells_near, near_control
    from calidar.strips.overlap import cell_keys

    rng = np.random.default_rng(3)
    pts = np.c_[rng.uniform(-50, 50, (20000, 2)), np.zeros(20000)]
    control = ControlPoints(np.array(["A", "B"]), np.array([[1.0, 2.0, 0.0], [-30.0, 40.0, 0.0]]), np.full(2, 0.01))
    idx = near_control(pts, control, reach_m=3.0)
    d = np.min(np.hypot(pts[:, None, 0] - control.local[None, :, 0], pts[:, None, 1] - control.local[None, :, 1]), axis=1)
    np.testing.assert_array_equal(idx, np.flatnonzero(d <= 3.0))
    cells = cells_near(control.local[:, :2], 5.0, reach_m=RADIUS_M + 1.0)
    inside = np.flatnonzero(d <= RADIUS_M + 1.0)
    assert np.all(np.isin(cell_keys(pts[inside], 5.0), cells))  # every point within reach lies in a kept cell
    assert cells.size <= 2 * 3 * 3  # a 6 m square touches at most 3 × 3 cells of 5 m


def test_control_rows_report_the_vertical_residual_before_and_after():
    from calidar.strips.control import control_rows, control_summary

    rng = np.random.default_rng(4)
    pose, control, nominal = _strip(0.05, rng), _control(rng), Sensor()
    problem, c, _ = _problem(pose, control, nominal, ["range_offset"])
    before = control_rows(problem, problem({"range_offset": 0.0}))
    after = control_rows(problem, problem({"range_offset": 0.05}))
    assert [r["point"] for r in before] == list(range(10)) and all(r["strip"] == 7 for r in before)
    dz = np.array([r["dz_m"] for r in before])
    # 5 cm too long ranges put the surface 5 cm·cos θ (θ ≤ 35°) too low at each control point
    assert np.all(dz < -0.05 * np.cos(np.radians(35.0)) + 0.01) and np.all(dz > -0.06)
    s = control_summary(control, before, after)
    assert s["n_used"] == 10 and s["not_covered"] == [] and s["rms_dz_after_m"] < 0.01 < s["rms_dz_before_m"]
    assert s["points"][0]["id"] == "GCP0" and s["points"][0]["dz_before_m"] == pytest.approx(dz[0])


def test_a_common_height_bias_is_observed_by_control_only_and_its_jacobian_is_exact():
    rng = np.random.default_rng(6)
    pose, control, nominal = _strip(0.0, rng), _control(rng), Sensor()
    free = ["height_bias", "range_offset", "boresight_roll"]
    problem, c, _ = _problem(pose, control, nominal, free)
    values = {"height_bias": 0.04, "range_offset": 0.0, "boresight_roll": 0.0}
    # every strip 4 cm up: each control row's residual grows by 4 cm × the normal's up part
    np.testing.assert_allclose(problem(values) - problem({**values, "height_bias": 0.0}), 0.04 * c.normal[:, 2], atol=1e-12)
    params = ParameterSet([Parameter(n, values[n], "rad" if n.startswith("bore") else "m") for n in free])
    J = problem.jacobian(values, params.free)
    Jn = numerical_jacobian(problem, params, np.array([values[n] for n in free]))
    np.testing.assert_allclose(J, Jn, atol=1e-6)
    # two strips' tie rows: a shift of both cancels (only control sees it)
    from calidar.strips.correspond import Correspondences
    import scipy.sparse as sp

    tie = Correspondences(7, 8, sp.csr_matrix(np.eye(3, len(pose.index))), sp.csr_matrix(np.eye(3, len(pose.index))),
                          np.tile([0.0, 0.0, 1.0], (3, 1)), np.full(3, 0.01), "planes")
    two = StripProblem(nominal, {7: pose, 8: pose}, [tie], ["height_bias"])
    assert np.allclose(two({"height_bias": 0.04}), two({"height_bias": 0.0}))
    assert np.allclose(two.jacobian({"height_bias": 0.0}, [Parameter("height_bias", 0.0, "m")]), 0.0)


def test_height_bias_without_control_is_refused():
    from calidar.errors import InputError
    from calidar.strips.calibrate import calibrate
    from calidar.strips.config import CalibrationConfig, Estimate
    from calidar.strips.control import check_estimate

    estimate = Estimate.of("boresight", "height_bias")
    with pytest.raises(InputError, match="height_bias .* needs ground control"):
        calibrate([], Sensor(), CalibrationConfig(estimate))
    check_estimate(estimate, object())  # with control: fine


def test_the_height_bias_goes_into_every_strips_trajectory_correction():
    from calidar.strips.control import with_height_bias
    from calidar.strips.trajectory_errors import StripCorrection

    fix = {1: StripCorrection(0.0, 1.0, np.array([[0.0, 0.0, 0.01], [0.0, 0.0, 0.02]]), np.zeros((2, 3)))}
    out = with_height_bias(fix, 0.04, {1: (0.0, 1.0), 2: (5.0, 9.0)})
    np.testing.assert_allclose(out[1].shift[:, 2], [0.05, 0.06])
    pts = np.zeros((3, 3))
    np.testing.assert_allclose(out[2].apply(pts, pts, np.array([5.0, 7.0, 9.0]))[:, 2], 0.04)
    assert with_height_bias(fix, 0.0, {1: (0.0, 1.0)}) is fix
