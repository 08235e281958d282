"""The numba georeferencing kernels against a plain numpy evaluation of the same equations."""

from dataclasses import dataclass

import numpy as np
import pytest

from calidar import frames, georef
from calidar.errors import InputError
from calidar.scanners.linear import LinearScanner
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory

SENSOR = Sensor(boresight_roll=0.01, boresight_pitch=-0.02, boresight_yaw=0.005, lever_arm_x=0.3, lever_arm_y=-0.1,
                lever_arm_z=-0.2, range_offset=0.05, range_scale=2e-5,
                scanner=LinearScanner(scan_angle_offset=1e-3, scan_angle_scale=-2e-4))


def _traj(n=3001):
    """A wiggly trajectory whose heading crosses ±180° (quaternion sign continuity matters)."""
    t = 5000.0 + np.arange(n) * 0.005
    s = t - t[0]
    return Trajectory(t, np.radians(45.0) + 1e-6 * s, np.radians(7.0) - 2e-6 * s, 1000 + 5 * np.sin(s),
                      0.1 * np.sin(3 * s), 0.05 * np.cos(2 * s), np.pi - 0.3 + 0.04 * s)


def _numpy_pose(traj, t):
    pos, q = traj.interpolate(t)  # numpy: searchsorted, linear positions, frames.slerp
    return pos, frames.quat_to_matrix(q)


def _numpy_forward_vectors(traj, sensor, t, v_s):
    pos, r_eb = _numpy_pose(traj, t)
    return pos + np.einsum("nij,nj->ni", r_eb, v_s @ sensor.r_bs.T + sensor.lever_arm)


def _numpy_inverse_vectors(traj, sensor, t, p):
    pos, r_eb = _numpy_pose(traj, t)
    return (np.einsum("nji,nj->ni", r_eb, p - pos) - sensor.lever_arm) @ sensor.r_bs


def _observations(traj, n, sort, seed=0):
    rng = np.random.default_rng(seed)
    t = rng.uniform(traj.time[0], traj.time[-1], n)
    t[:3] = traj.time[0], traj.time[-1], traj.time[7]  # the ends and a record time exactly
    if sort:
        t.sort()
    return t, rng.uniform(300, 3000, n), rng.uniform(-0.7, 0.7, n), rng.uniform(-0.2, 0.2, n)


@pytest.mark.parametrize("sort", [True, False])
def test_forward_equals_numpy(sort):
    tr = _traj()
    t, r, th, ph = _observations(tr, 50_000, sort)
    for angles in (th, np.c_[th, ph]):
        v_s = SENSOR.true_range(r)[:, None] * SENSOR.scanner.directions(angles)
        ref = _numpy_forward_vectors(tr, SENSOR, t, v_s)
        assert np.max(np.abs(georef.forward(tr, SENSOR, t, r, angles) - ref)) < 1e-9
        assert np.max(np.abs(georef.forward_vectors(tr, SENSOR, t, v_s) - ref)) < 1e-9


@pytest.mark.parametrize("sort", [True, False])
def test_poses_equal_numpy(sort):
    tr = _traj()
    t = _observations(tr, 50_000, sort, seed=2)[0]
    pos, r_eb = georef.poses(tr, t)
    pos_ref, r_ref = _numpy_pose(tr, t)
    assert np.max(np.abs(pos - pos_ref)) < 1e-9 and np.max(np.abs(r_eb - r_ref)) < 1e-12
    with pytest.raises(InputError, match="outside the trajectory"):
        georef.poses(tr, np.r_[t[:10], tr.time[-1] + 1.0])


@pytest.mark.parametrize("sort", [True, False])
def test_inverse_equals_numpy(sort):
    tr = _traj()
    t, r, th, ph = _observations(tr, 50_000, sort, seed=1)
    p = georef.forward(tr, SENSOR, t, r, np.c_[th, ph])
    obs = georef.inverse(tr, SENSOR, t, p)
    v_ref = _numpy_inverse_vectors(tr, SENSOR, t, p)
    assert np.max(np.abs(obs.vector_s - v_ref)) < 1e-9
    rho = np.linalg.norm(v_ref, axis=1)
    assert np.max(np.abs(obs.range_m - SENSOR.measured_range(rho))) < 1e-9
    assert np.max(np.abs(obs.angles - SENSOR.scanner.angles(v_ref / rho[:, None]))) < 1e-12
    assert np.max(np.abs(obs.range_m - r)) < 1e-8
    assert np.max(np.abs(obs.angles - np.c_[th, ph])) < 1e-11


@dataclass(frozen=True)
class _ConeScanner(LinearScanner):
    """A scanner the fused linear kernel does not know (goes through directions + forward_vectors)."""

    model: str = "cone"

    def directions(self, angles):
        a = np.asarray(angles, float)
        c = np.radians(15.0)
        return np.stack([np.sin(c) * np.cos(a), np.sin(c) * np.sin(a), np.full_like(a, np.cos(c))], axis=-1)


def test_generic_scanner_path_equals_numpy():
    tr = _traj()
    s = Sensor(boresight_yaw=0.01, lever_arm_x=1.0, range_offset=0.2, scanner=_ConeScanner())
    t, r, th, _ = _observations(tr, 10_000, True, seed=2)
    ref = _numpy_forward_vectors(tr, s, t, s.true_range(r)[:, None] * s.scanner.directions(th))
    p = georef.forward(tr, s, t, r, th)
    assert np.max(np.abs(p - ref)) < 1e-9
    obs = georef.inverse(tr, s, t, p)  # generic path: the scanner's own angles()
    v_ref = _numpy_inverse_vectors(tr, s, t, p)
    assert np.max(np.abs(obs.vector_s - v_ref)) < 1e-9
    assert np.allclose(obs.angles, s.scanner.angles(v_ref / np.linalg.norm(v_ref, axis=1)[:, None]), atol=1e-12)


def test_times_outside_the_trajectory_are_a_clear_error():
    tr = _traj()
    t = np.array([tr.time[0] - 1.0, tr.time[5], tr.time[-1] + 2.0, tr.time[-1] + 3.0])
    with pytest.raises(InputError, match="3 of 4 points have GPS times outside the trajectory"):
        georef.forward(tr, SENSOR, t, np.full(4, 500.0), np.zeros(4))
    with pytest.raises(InputError, match="outside the trajectory"):
        georef.inverse(tr, SENSOR, t, np.zeros((4, 3)))


def test_empty_and_mismatched_inputs():
    tr = _traj()
    assert georef.forward(tr, SENSOR, np.empty(0), np.empty(0), np.empty(0)).shape == (0, 3)
    with pytest.raises(ValueError, match="expected 3 rows"):
        georef.forward(tr, SENSOR, tr.time[:3], np.ones(4), np.zeros(3))
    with pytest.raises(ValueError, match="expected 3 rows"):
        georef.forward(tr, SENSOR, tr.time[:3], np.empty(0), np.zeros(3))
    with pytest.raises(ValueError, match="expected 3 rows"):
        georef.inverse(tr, SENSOR, tr.time[:3], np.zeros((2, 3)))


def test_nan_times_are_an_error_not_garbage():
    tr = _traj()
    with pytest.raises(InputError, match="outside the trajectory"):
        georef.forward(tr, SENSOR, np.array([tr.time[3], np.nan]), np.full(2, 500.0), np.zeros(2))
