"""The strip adjustment's problem: one lidar equation, exact analytic Jacobian columns."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from calidar import frames, georef
from calidar.adjust import ParameterSet
from calidar.adjust.solver import numerical_jacobian
from calidar.sensor import Sensor
from calidar.strips.config import Estimate
from calidar.strips.parameters import build_parameters
from calidar.strips.planes import match_pair_planes
from calidar.strips.problem import Centroids, StripProblem
from calidar.strips.strip import Pose, georeference_pose
from calidar.strips.trajectory_errors import TrajectoryModel
from calidar.trajectory import Trajectory
from strips_scene import survey

CONVENTIONS = Path(__file__).resolve().parents[3] / "docs" / "conventions.md"


def test_one_lidar_equation_on_the_worked_example():
    """docs/conventions.md's worked example through every form the code uses: the fused numba
    kernel (georef.forward), the numpy equation (georef.lidar_points) that the strips'
    re-georeferencing calls, the simulator's rays (georef.beams) and the strip adjustment's
    averaged form (Centroids)."""
    block = re.search(r"```text\n(.*?)```", CONVENTIONS.read_text(encoding="utf-8"), re.S).group(1)
    doc = {k.strip(): np.array([float(x) for x in v.split(",")]) for k, v in (ln.split("=") for ln in block.strip().splitlines())}
    d = np.radians
    tr = Trajectory(np.array([0.0, 1.0]), np.full(2, d(45.0)), np.full(2, d(7.0)), np.full(2, 1000.0),
                    np.full(2, d(10.0)), np.zeros(2), np.full(2, d(90.0)))
    sensor = Sensor(lever_arm_x=1.0)
    t, rng, ang = np.array([0.5]), np.array([1000.0]), np.array([[d(10.0), 0.0]])
    kernel = georef.forward(tr, sensor, t, rng, ang)[0]
    position, rotation = georef.poses(tr, t)
    numpy_form = georef.lidar_points(position, rotation, sensor, rng, ang)[0]
    origin, direction = georef.beams(position, rotation, sensor, ang)
    ray = origin[0] + sensor.true_range(rng)[0] * direction[0]
    pose = Pose(np.array([0]), position, rotation, rng, ang)
    strips_form = georeference_pose(sensor, pose)[0]
    averaged = Centroids(sp.csr_matrix(np.ones((1, 1))), pose, Sensor(), True, True)(sensor)[0]
    for p in (kernel, numpy_form, ray, strips_form, averaged):
        assert np.allclose(p, doc["point_ecef_m"], rtol=0, atol=1e-6), p
    assert np.allclose(frames.r_en(d(45.0), d(7.0)).T @ (numpy_form - tr.ecef[0]), doc["point_ned_m"], atol=1e-6)


@pytest.mark.parametrize("point_to_point", [False, True])
def test_sensor_columns_are_exact(point_to_point):
    """Boresight, lever arm, range offset and scale columns (analytic, turned by the trajectory
    tilts) equal central differences of the residuals, along normals and in 3D."""
    truth = Sensor(boresight_roll=np.radians(0.03), boresight_pitch=np.radians(-0.04))
    strips = survey(truth, Sensor(), [((-250, -80, 0), 90, 500, 400), ((250, 80, 0), 270, 500, 400)], n=40_000)
    c = match_pair_planes(1, strips[0].points, 2, strips[1].points)
    if point_to_point:
        c = replace(c, normal=None)
    nominal = Sensor(lever_arm_x=0.2, lever_arm_z=0.3, range_offset=0.01)
    poses = {s.id: s.pose() for s in strips}
    spans = {s.id: (float(s.time.min()), float(s.time.max())) for s in strips}
    model = TrajectoryModel(block_s=2.0, position_sigma_m=0.03, attitude_sigma_rad=np.radians(0.5), correlation_s=20.0,
                            attitude_correlation_s=3.0)
    est = Estimate.of("boresight", "lever_arm", "range_offset", "range_scale")
    params = build_parameters(nominal, est, spans, model)
    rng = np.random.default_rng(5)
    params = ParameterSet(replace(p, value=p.value + rng.normal(0.0, p.prior_sigma or (1e-3 if p.unit == "rad" else 0.02)))
                          if p.free else p for p in params)
    problem = StripProblem(nominal, poses, [c], params.free_names, {s.id: s.time for s in strips}, model, spans)
    analytic = problem.jacobian(params.values(), params.free).toarray()
    numeric = numerical_jacobian(problem, params, params.x())
    sensor_cols = [j for j, n in enumerate(params.free_names) if not n.startswith("trajectory_")]
    assert len(sensor_cols) == 8
    a, n = analytic[:, sensor_cols], numeric[:, sensor_cols]
    assert np.max(np.abs(a - n), axis=0) == pytest.approx(0.0, abs=1e-6 * np.max(np.abs(n)))
    # without trajectory corrections the columns come dense, and the same
    plain = StripProblem(nominal, poses, [c], [params.free_names[j] for j in sensor_cols])
    sub = ParameterSet(p for p in params if not p.name.startswith("trajectory_"))
    dense = plain.jacobian(sub.values(), sub.free)
    assert isinstance(dense, np.ndarray)
    assert np.max(np.abs(dense - numerical_jacobian(plain, sub, sub.x()))) < 1e-6 * np.max(np.abs(dense))


def test_same_rows_problem_equals_one_built_anew():
    """A problem with more parameters free built on another's rows (``same_rows``, the model
    check's, issue 32 eleventh session) gives the residuals and Jacobian of one built from the
    correspondences, to the bit: two pairs sharing strip 2's patches (counted once), the
    trajectory model on, range and lever arm freed (the centroids' other form)."""
    truth = Sensor(boresight_roll=np.radians(0.03), boresight_pitch=np.radians(-0.04))
    strips = survey(truth, Sensor(), [((-250, -80, 0), 90, 500, 400), ((250, 80, 0), 270, 500, 400),
                                      ((0, 0, 0), 0, 500, 400)], n=30_000)
    corrs = [match_pair_planes(1, strips[0].points, 2, strips[1].points),
             match_pair_planes(3, strips[2].points, 2, strips[1].points)]
    nominal = Sensor(lever_arm_x=0.2, lever_arm_z=0.3, range_offset=0.01)
    poses = {s.id: s.pose() for s in strips}
    times = {s.id: s.time for s in strips}
    spans = {s.id: (float(s.time.min()), float(s.time.max())) for s in strips}
    model = TrajectoryModel(block_s=2.0, position_sigma_m=0.03, attitude_sigma_rad=np.radians(0.5), correlation_s=20.0,
                            attitude_correlation_s=3.0)
    params = build_parameters(nominal, Estimate.of("boresight"), spans, model)
    fitted = StripProblem(nominal, poses, corrs, params, times, model, spans)
    freed = [*params.free_names, "lever_arm_x", "range_scale"]
    values = {**params.values(), "lever_arm_x": 0.21, "range_scale": 3e-5}
    at = ParameterSet(p for p in build_parameters(nominal, Estimate.of("boresight", "lever_arm", "range_scale"), spans,
                                                  model) if p.name in freed)
    at = ParameterSet(replace(p, value=values[p.name]) for p in at)
    anew = StripProblem(nominal, poses, corrs, freed, times, model, spans)
    taken = StripProblem(nominal, poses, corrs, freed, times, model, spans, same_rows=fitted)
    assert np.array_equal(taken.sigma, anew.sigma) and np.array_equal(taken.row_share, anew.row_share)
    assert np.array_equal(taken(values), anew(values))
    assert (taken.jacobian(values, at.free) != anew.jacobian(values, at.free)).nnz == 0
    assert anew.jacobian(values, at.free).nnz > 0
