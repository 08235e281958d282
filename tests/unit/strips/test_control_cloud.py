"""A reference point cloud as control (strips/control_cloud.py): its planar cells against an
independent per-cell least-squares fit, cells that are not one smooth surface left out, and over
many draws the range offset and the height from two strips against a cloud whose datum is off by
N(0, its stated σ) match their σ."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.adjust import Parameter, ParameterSet, SolverOptions
from calidar.adjust.solver import estimate
from calidar.errors import InputError
from calidar.sensor import Sensor
from calidar.strips.control import CONTROL_ID, control_pose
from calidar.strips.control_cloud import CELL_M, DATUM, ControlCloud, planar_cells
from calidar.strips.control_planes import INSET_M
from calidar.strips.control_survey import SurveyErrors, with_survey_parameters
from calidar.strips.problem import StripProblem
from calidar.strips.strip import Pose, georeference_pose

R_LB = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  #: heading north: body x → north, z → down


def test_planar_cells_match_a_least_squares_fit_of_each_and_leave_out_the_rest():
    rng = np.random.default_rng(4)
    xy = rng.uniform(0.0, 4 * CELL_M, (8000, 2))  # 4 × 4 cells, ~500 points each
    z = 10.0 + 0.1 * xy[:, 0] - 0.05 * xy[:, 1] + rng.normal(0.0, 0.004, len(xy))
    wall = (xy[:, 0] < CELL_M) & (xy[:, 1] < CELL_M)
    z[wall & (xy[:, 0] > CELL_M / 2)] += 0.5  # a step inside cell (0, 0): not one surface
    sparse = (xy[:, 0] > 3 * CELL_M) & (xy[:, 1] > 3 * CELL_M)
    keep = ~sparse | (rng.uniform(size=len(xy)) < 0.02)  # cell (3, 3): ~10 points
    p = np.c_[xy, z][keep]
    key, cent, coef, cov = planar_cells(p, CELL_M)
    assert key.size == 14  # 16 less the step and the sparse cell
    ij = np.floor(p[:, :2] / CELL_M).astype(int)
    u = p[:, :2] - ij * CELL_M
    inner = np.all((u >= INSET_M) & (u <= CELL_M - INSET_M), axis=1)  # where a strip's points are taken
    for k in range(key.size):
        i, j = np.floor(cent[k, :2] / CELL_M).astype(int)
        q = p[(ij[:, 0] == i) & (ij[:, 1] == j) & inner]
        X = np.c_[np.ones(len(q)), q[:, :2] - q[:, :2].mean(axis=0)]
        c, rss, *_ = np.linalg.lstsq(X, q[:, 2], rcond=None)
        s2 = rss[0] / (len(q) - 3)
        np.testing.assert_allclose(cent[k], q.mean(axis=0), atol=1e-9)
        np.testing.assert_allclose(coef[k], c, atol=1e-9)
        np.testing.assert_allclose(cov[k], s2 * np.linalg.inv(X.T @ X), rtol=1e-6, atol=1e-15)
    with pytest.raises(InputError, match="smooth surface"):
        ControlCloud.from_points(np.c_[xy, rng.uniform(0, 2, len(xy))], 0.02, "rough.laz")


def _strip(x0: float, offset: float, rng, m: int = 40000) -> Pose:
    """A level flight north at x0, 60 m over flat ground (z = 0), scan ±35°, ranges with ``offset``, 5 mm noise."""
    y = rng.uniform(-30.0, 30.0, m)
    theta = rng.uniform(-np.radians(35.0), np.radians(35.0), m)
    measured = 60.0 / np.cos(theta) + offset + rng.normal(0.0, 0.005, m)
    return Pose(np.arange(m), np.c_[np.full(m, x0), y, np.full(m, 60.0)], np.repeat(R_LB[None], m, axis=0), measured, theta)


def _draw(rng, sigma_datum: float):
    """Two strips (5 cm range offset) over a reference cloud of the ground between them, its datum off by N(0, σ)."""
    nominal = Sensor()
    g = np.arange(-3.0, 33.0, 0.3)
    gx, gy = np.meshgrid(g, np.arange(-24.0, 24.0, 0.3))
    datum = rng.normal(0.0, sigma_datum)
    ref = np.c_[gx.ravel(), gy.ravel(), datum + rng.normal(0.0, 0.003, gx.size)]
    cloud = ControlCloud.from_points(ref, sigma_datum, max_targets=60)
    poses = {1: _strip(0.0, 0.05, rng), 2: _strip(30.0, 0.05, rng)}
    corrs = [c for i, p in poses.items()
             if (c := cloud.rows(i, p.index, georeference_pose(nominal, p), len(p.index))) is not None]
    poses[CONTROL_ID] = control_pose(cloud, poses[1])
    params = with_survey_parameters(ParameterSet([Parameter("range_offset", 0.0, "m"), Parameter("lever_arm_z", 0.0, "m")]),
                                    cloud)
    return SurveyErrors(StripProblem(nominal, poses, corrs, params), cloud), datum


def test_range_offset_and_height_against_a_cloud_match_their_sigma_over_draws():
    rng = np.random.default_rng(8)
    z, datum_z = [], []
    for _ in range(30):
        problem, datum = _draw(rng, 0.02)
        assert problem.G.shape[1] == 1 and problem.parameters[DATUM].prior_sigma == 0.02
        sol = estimate(problem, SolverOptions(robust=None)).solution()
        s = {n: sol.sigma[n] / max(sol.sigma0, 1.0) for n in sol.parameters.free_names}  # a-priori σ
        z.append([(sol.values["range_offset"] - 0.05) / s["range_offset"], sol.values["lever_arm_z"] / s["lever_arm_z"]])
        datum_z.append((sol.values[DATUM] - datum) / s[DATUM])
        assert 0.015 < s["lever_arm_z"] < 0.021  # the height is known to the cloud's datum σ, not better
    rms = np.sqrt(np.mean(np.square(z), axis=0))
    assert np.all((rms > 0.75) & (rms < 1.3)), rms  # 30 draws: ±0.13
    assert 0.75 < np.sqrt(np.mean(np.square(datum_z))) < 1.3
