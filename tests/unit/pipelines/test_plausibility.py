"""The geometry checks of calidar.ingest.plausibility against simulated flights (issue 27, 26)."""

import numpy as np
import pytest

import calidar
from calidar.errors import InputError
from calidar.frames import r_en
from calidar.ingest.plausibility import GeometryCheck

HEIGHT_M = 1000.0


def _flight(seed: int, lift_m: float, roll_deg: float = 0.3, n: int = 1000, sign: float = 1.0):
    """A 20 s straight flight north at 1 000 m over flat ground (height 0); n points at scan
    angles ±30° (aircraft roll ``roll_deg``), their heights raised by ``lift_m``, and the scan
    angles as a LAS 1.2 file stores them (whole degrees, without the roll; ``sign`` −1: positive left)."""
    rng = np.random.default_rng(seed)
    tt = np.linspace(0.0, 20.0, 2001)
    lat0, lon0 = np.radians(47.0), np.radians(8.0)
    traj = calidar.Trajectory(time=tt, lat=lat0 + tt * 60.0 / 6.37e6, lon=np.full(tt.size, lon0),
                              height=np.full(tt.size, HEIGHT_M), roll=np.full(tt.size, np.radians(roll_deg)),
                              pitch=np.zeros(tt.size), heading=np.zeros(tt.size))
    t = np.sort(rng.uniform(0.5, 19.5, n))
    theta = rng.uniform(-30.0, 30.0, n)
    lat = lat0 + t * 60.0 / 6.37e6
    up = -r_en(lat, np.full(n, lon0))[:, :, 2]  # minus the down axis
    pos = traj.interpolate(t)[0]
    unit = calidar.georeference(traj, calidar.Sensor(), t, np.ones(n), np.radians(theta)) - pos
    rng_m = HEIGHT_M / -np.einsum("ij,ij->i", unit, up)  # flat ground 1 000 m below the sensor
    ecef = calidar.georeference(traj, calidar.Sensor(), t, rng_m, np.radians(theta))
    return traj, t, ecef + lift_m * up, sign * np.round(theta)


def test_the_vertical_offset_is_recovered_with_honest_sigma():
    """100 flights with heights raised by 0 to 40 m: δ = the lift within its σ (RMS of error/σ
    0.8–1.3, 1.15 measured; whole-degree angles scatter each point's δ by ~0.25 % of the height)."""
    z = []
    for seed in range(100):
        lift = 0.4 * seed
        traj, t, ecef, theta = _flight(seed, lift)
        check = GeometryCheck("flight.las")
        check.add(traj, t, ecef, theta)
        delta, sigma, height = check.vertical_offset()
        assert abs(height - HEIGHT_M) < 50
        z.append((delta - lift) / sigma)
    z = np.array(z)
    assert 0.8 < np.sqrt(np.mean(z**2)) < 1.3, z  # 1.15 measured
    assert np.max(np.abs(z)) < 4.0


def test_the_vertical_warning_names_the_offset():
    traj, t, ecef, theta = _flight(1, 30.0)
    check = GeometryCheck("flight.las")
    check.add(traj, t, ecef, theta)
    w = check.vertical_warning("ellipsoidal (assumed)")
    assert w.startswith("flight.las: the heights are +") and "vertical-datum mismatch" in w
    delta, sigma = (float(v) for v in w.split("are ")[1].split(" m off")[0].split(" ± "))
    assert abs(delta - 30.0) < 3 * sigma
    traj, t, ecef, theta = _flight(2, 0.0, sign=-1.0)  # scan angles positive to the left: the same answer
    check = GeometryCheck("flight.las")
    check.add(traj, t, ecef, theta)
    assert check.vertical_warning("ellipsoidal") is None and abs(check.vertical_offset()[0]) < 2.0


def test_impossible_geometry_is_an_error():
    traj, t, ecef, theta = _flight(3, 0.0)
    with pytest.raises(InputError, match="flight.las: xyz: points 0–999: the points lie a median .* sideways"):
        east = np.array([-np.sin(np.radians(8.0)), np.cos(np.radians(8.0)), 0.0])
        GeometryCheck("flight.las").add(traj, t, ecef + 300e3 * east, theta)  # 300 km east: another UTM zone
    with pytest.raises(InputError, match="flight.las: z: .* above the trajectory"):
        GeometryCheck("flight.las").add(traj, t, ecef + 1.5 * (traj.interpolate(t)[0] - ecef), theta)
    with pytest.raises(InputError, match="flight.las: scan_angle: .* by a median .*wrong time system"):
        GeometryCheck("flight.las").add(traj, t, ecef, np.clip(theta * 3, -89, 89))
