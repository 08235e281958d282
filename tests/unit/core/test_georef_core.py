import numpy as np
import pytest

from calidar import frames, georef
from calidar.scanners.linear import LinearScanner
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory


def _traj(heading=np.pi / 2, roll=0.0, n=2001):
    t = np.linspace(1000.0, 1010.0, n)
    lat = np.full(n, np.radians(45.0))
    lon = np.radians(7.0) + np.linspace(0, 1e-4, n)
    return Trajectory(t, lat, lon, np.full(n, 1000.0), np.full(n, roll), np.zeros(n), np.full(n, heading))


def test_level_flight_nadir_point_is_below():
    tr = _traj(heading=0.0)
    p = georef.forward(tr, Sensor(), np.array([1005.0]), np.array([500.0]), np.array([0.0]))
    lat, lon, h = frames.ecef_to_geodetic(p)
    pos, _ = tr.interpolate(np.array([1005.0]))
    lat0, lon0, h0 = frames.ecef_to_geodetic(pos)
    assert h[0] == pytest.approx(h0[0] - 500.0, abs=1e-6)
    assert lat[0] == pytest.approx(lat0[0], abs=1e-10)


def test_heading_90_roll_10_lever_arm_hand_worked():
    # heading east, roll 10° right-wing-down, beam at nadir of the scanner, lever arm 1 m forward:
    # in NED the beam (0,0,ρ) becomes ρ·(0, −sin 10°, cos 10°) rotated by heading 90° → east/north:
    # NED = (ρ sin10°, 0, ρ cos10°) ... worked out: Rz(90)·Rx(10)·(0,0,ρ) = (ρ sin10, 0, ρ cos10)
    tr = _traj(heading=np.pi / 2, roll=np.radians(10.0))
    rho = 1000.0
    s = Sensor(lever_arm_x=1.0)
    t = np.array([1005.0])
    p = georef.forward(tr, s, t, np.array([rho]), np.array([0.0]))
    pos, _ = tr.interpolate(t)
    lat0, lon0, _ = frames.ecef_to_geodetic(pos)
    ned = frames.r_en(lat0[0], lon0[0]).T @ (p[0] - pos[0])
    s10, c10 = np.sin(np.radians(10)), np.cos(np.radians(10))
    assert np.allclose(ned, [rho * s10, 1.0, rho * c10], atol=1e-6)


def test_round_trip_forward_inverse_forward():
    tr = _traj()
    s = Sensor(boresight_roll=0.01, boresight_pitch=-0.02, boresight_yaw=0.005, lever_arm_x=0.3, lever_arm_z=-0.2,
               range_offset=0.05, range_scale=2e-5)
    rng = np.random.default_rng(0)
    t = rng.uniform(1000, 1010, 200_000)
    ang = rng.uniform(-0.6, 0.6, t.size)
    rng_m = rng.uniform(500, 1500, t.size)
    p = georef.forward(tr, s, t, rng_m, ang)
    obs = georef.inverse(tr, s, t, p)
    assert np.max(np.abs(obs.range_m - rng_m)) < 1e-6
    assert np.max(np.abs(obs.angles[:, 0] - ang)) < 1e-9
    p2 = georef.forward(tr, s, obs.time, obs.range_m, obs.angles)
    assert np.max(np.abs(p2 - p)) < 1e-6


def test_regeoreference_changes_only_by_mounting():
    tr = _traj()
    old, new = Sensor(), Sensor(boresight_roll=np.radians(0.1))
    t = np.array([1005.0])
    p_old = georef.forward(tr, old, t, np.array([1000.0]), np.array([0.0]))
    p_new = georef.regeoreference(tr, old, new, t, p_old)
    # roll 0.1° at 1000 m moves the nadir point ≈ 1.745 m across track
    assert np.linalg.norm(p_new - p_old) == pytest.approx(1000 * np.radians(0.1), rel=1e-4)


@pytest.mark.parametrize("new", [Sensor(boresight_roll=0.01, lever_arm_x=0.3),  # a new mounting: the same vectors
                                 Sensor(boresight_roll=0.01, range_offset=0.05,
                                        scanner=LinearScanner(scan_angle_offset=1e-3))])
def test_reforward_from_scanner_vectors_equals_forward_of_the_observations(new):
    tr = _traj()
    old = Sensor(boresight_pitch=-0.02, range_scale=2e-5)
    rng = np.random.default_rng(1)
    t, ang, rng_m = rng.uniform(1000, 1010, 50_000), rng.uniform(-0.6, 0.6, 50_000), rng.uniform(500, 1500, 50_000)
    p = georef.forward(tr, old, t, rng_m, ang)
    obs = georef.inverse(tr, old, t, p)
    want = georef.forward(tr, new, obs.time, obs.range_m, obs.angles)
    got = georef.reforward(old, new, tr, t, georef.scanner_vectors(tr, old, t, p))
    assert np.max(np.abs(got - want)) < 1e-8
    assert np.max(np.abs(got - p)) > 1.0  # the new sensor moves the points
