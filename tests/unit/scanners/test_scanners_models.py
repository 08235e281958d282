"""Palmer, wedge and linear scanner models: geometry, inverse, sensor.toml, bad input."""

import numpy as np
import pytest

from calidar import georef
from calidar.errors import InputError
from calidar.scanners import SCANNERS, LinearScanner, PalmerScanner, Scanner, WedgeScanner
from calidar.scanners.palmer import palmer_directions
from calidar.scanners.wedge import deviation_angle
from calidar.sensor import Sensor
from calidar.trajectory import Trajectory

PERTURBED = {
    "palmer": PalmerScanner(eccentricity_ratio=3e-4, eccentricity_phase=0.7, delta_l=4e-4, delta_r=-3e-4),
    "wedge": WedgeScanner(wedge_angle_error=1e-3, wedge_axis_tilt_x=2e-3, wedge_axis_tilt_y=-1e-3,
                          eccentricity_ratio=5e-4, eccentricity_phase=1.0),
}


def _wrap(a):
    return np.angle(np.exp(1j * a))


@pytest.mark.parametrize("scanner", [PalmerScanner(), WedgeScanner(), *PERTURBED.values()], ids=lambda s: s.model)
def test_rotating_round_trip(scanner):
    beta = np.random.default_rng(1).uniform(-np.pi, np.pi, 5000)
    u = scanner.directions(beta)
    assert isinstance(scanner, Scanner)
    assert np.allclose(np.linalg.norm(u, axis=1), 1.0, atol=1e-14)
    b2 = scanner.angles(u)
    assert b2.shape == beta.shape
    assert np.max(np.abs(_wrap(b2 - beta))) < 1e-10
    assert np.max(np.abs(scanner.directions(b2) - u)) < 1e-12
    assert np.allclose(scanner.directions(beta[:, None]), u)  # (N, 1) accepted too


def test_linear_round_trip():
    s = LinearScanner(scan_angle_offset=1e-3, scan_angle_scale=2e-4)
    th = np.linspace(-0.5, 0.5, 101)
    u = s.directions(th)
    assert np.allclose(s.directions(s.angles(u)), u, atol=1e-14)
    assert np.allclose(s.angles(u)[:, 0], th, atol=1e-12)


@pytest.mark.parametrize("scanner", list(PERTURBED.values()), ids=lambda s: s.model)
def test_off_pattern_angle_is_the_closest_pattern_direction(scanner):
    beta = np.linspace(-3, 3, 50)
    u = scanner.directions(beta)
    rng = np.random.default_rng(2)
    noisy = u + rng.normal(0, 2e-4, u.shape)  # ~40″ off the pattern
    noisy /= np.linalg.norm(noisy, axis=1, keepdims=True)
    b = scanner.angles(noisy)
    # the returned β minimises the distance: a dense local search cannot beat it
    grid = b[:, None] + np.linspace(-2e-3, 2e-3, 401)[None, :]
    d_grid = np.linalg.norm(scanner.directions(grid.ravel()).reshape(*grid.shape, 3) - noisy[:, None, :], axis=2)
    d_best = np.linalg.norm(scanner.directions(b) - noisy, axis=1)
    assert np.all(d_best <= d_grid.min(axis=1) + 1e-12)
    assert np.max(np.abs(_wrap(b - beta))) < 5e-3


def test_palmer_geometry_nominal():
    s = PalmerScanner()
    u = s.directions(np.array([0.0, np.pi / 2, np.pi, -np.pi / 2]))
    # β = 0: mirror normal tilted in the laser–axis plane → beam 2B = 15° forward of nadir
    assert np.allclose(u[0], [np.sin(np.radians(15)), 0, np.cos(np.radians(15))], atol=1e-14)
    assert np.allclose(u[2], [-np.sin(np.radians(15)), 0, np.cos(np.radians(15))], atol=1e-14)
    assert u[1, 1] > 0.17 and u[3, 1] < -0.17 and abs(u[1, 0]) < 0.05  # β = 90° → right
    # with B = 0 every β gives nadir: the scanner frame's z is the nominal beam
    flat = palmer_directions(np.linspace(0, 6, 7), np.radians(45), 0.0)
    assert np.allclose(flat, [0, 0, 1], atol=1e-14)


def test_palmer_errors_are_what_they_say():
    s = PalmerScanner()
    beta = np.linspace(0, 2 * np.pi, 73)
    # δ_R is an error of B
    assert np.allclose(s.with_parameters(delta_r=1e-3).directions(beta),
                       PalmerScanner(palmer_mirror_tilt=s.palmer_mirror_tilt + 1e-3).directions(beta))
    # eccentricity shifts the true angle by (ε/r)·sin(β − C)
    e, c = 1e-3, 0.4
    assert np.allclose(s.with_parameters(eccentricity_ratio=e, eccentricity_phase=c).directions(beta),
                       s.directions(beta + e * np.sin(beta - c)), atol=1e-15)
    # δ_L changes the laser–axis angle A → A + δ_L with the laser fixed: with the mirror normal on the axis
    # (B = 0) the beam is the laser reflected at incidence A + δ_L, i.e. 2 δ_L away from nadir about y
    d = np.radians(0.5)
    u = palmer_directions(beta, s.palmer_axis_angle, 0.0, delta_l=d)
    assert np.allclose(u, [np.cos(2 * (s.palmer_axis_angle + d)), 0.0, np.sin(2 * (s.palmer_axis_angle + d))], atol=1e-14)
    assert u[0, 0] == pytest.approx(-np.sin(2 * d), abs=1e-15)


def test_palmer_delta_l_readings_differ_by_a_rigid_rotation():
    from calidar.frames import rot_y

    beta = np.linspace(0, 2 * np.pi, 100)
    a, b, d = np.radians(45), np.radians(7.5), np.radians(0.02)
    laser = palmer_directions(beta, a, b, delta_l=d)
    motor = palmer_directions(beta, a, b, delta_l=d, reference="motor")
    assert not np.allclose(laser, motor, atol=1e-6)
    assert np.allclose(motor, laser @ rot_y(d).T, atol=1e-15)


def test_wedge_exact_refraction_and_thin_prism():
    w = WedgeScanner(wedge_angle=np.radians(20), wedge_refractive_index=1.5)
    u = w.directions(np.array([0.0, np.pi / 2]))
    expected = np.arcsin(1.5 * np.sin(np.radians(20))) - np.radians(20)
    assert np.degrees(expected) == pytest.approx(10.865, abs=1e-3)
    assert np.arccos(u[:, 2]) == pytest.approx([expected, expected], abs=1e-12)
    assert u[0, 0] > 0 and u[1, 1] > 0  # β = 0 → +x, β = 90° → +y
    # the thin-prism formula is the small-angle limit only
    assert deviation_angle(np.radians(2), 1.5, exact=False) == pytest.approx(deviation_angle(np.radians(2), 1.5), rel=2e-3)
    assert deviation_angle(np.radians(20), 1.5, exact=False) < 0.95 * expected
    # a wedge-angle error is an error of α; a tilted axis moves the circle
    beta = np.linspace(0, 6, 13)
    assert np.allclose(w.with_parameters(wedge_angle_error=1e-3).directions(beta),
                       WedgeScanner(np.radians(20) + 1e-3, 1.5).directions(beta))
    assert not np.allclose(w.with_parameters(wedge_axis_tilt_x=1e-3).directions(beta), w.directions(beta), atol=1e-6)


@pytest.mark.parametrize("scanner", [PalmerScanner(), WedgeScanner(), *PERTURBED.values(),
                                     LinearScanner(scan_angle_offset=1e-3, scan_angle_scale=5e-5)],
                         ids=lambda s: s.model)
def test_sensor_toml_round_trip(tmp_path, scanner):
    sensor = Sensor(boresight_roll=1e-3, scanner=scanner)
    path = sensor.write(tmp_path / "sensor.toml")
    back = Sensor.read(path)
    assert type(back.scanner) is type(scanner)
    for k, v in scanner.parameters().items():
        assert back.scanner.parameters()[k] == pytest.approx(v, abs=1e-15)
    assert set(scanner.parameters()) <= set(sensor.parameters())
    assert scanner.model in SCANNERS


def test_parameters_flat_and_settable():
    s = PalmerScanner()
    assert set(s.parameters()) == {"palmer_axis_angle", "palmer_mirror_tilt", "eccentricity_ratio",
                                   "eccentricity_phase", "delta_l", "delta_r"}
    assert Sensor(scanner=s).with_parameters(delta_r=1e-4, boresight_pitch=2e-3).scanner.delta_r == 1e-4
    with pytest.raises(KeyError):
        s.with_parameters(wedge_angle=0.1)
    with pytest.raises(KeyError):
        WedgeScanner().with_parameters(delta_l=0.1)


@pytest.mark.parametrize("table, field", [
    ({"model": "palmer", "mirror_tilt_deg": 0.0}, "scanner.mirror_tilt_deg"),
    ({"model": "palmer", "mirror_tilt_deg": -2.0}, "scanner.mirror_tilt_deg"),
    ({"model": "palmer", "axis_angle_deg": 95.0}, "scanner.axis_angle_deg"),
    ({"model": "palmer", "eccentricity_ratio": 1.5}, "scanner.eccentricity_ratio"),
    ({"model": "palmer", "delta_l_deg": "x"}, "scanner.delta_l_deg"),
    ({"model": "palmer", "tilt": 1.0}, "scanner"),
    ({"model": "wedge", "refractive_index": 0.8}, "scanner.refractive_index"),
    ({"model": "wedge", "wedge_angle_deg": 60.0}, "scanner.wedge_angle_deg"),  # 1.52·sin 60° > 1
    ({"model": "wedge", "wedge_angle_deg": 0.0}, "scanner.wedge_angle_deg"),
])
def test_bad_scanner_tables_are_clear_errors(tmp_path, table, field):
    body = "[scanner]\n" + "\n".join(f"{k} = {v!r}".replace("'", '"') for k, v in table.items()) + "\n"
    path = tmp_path / "sensor.toml"
    path.write_text(body)
    with pytest.raises(InputError) as e:
        Sensor.read(path)
    assert str(e.value).startswith(f"{path}: {field}:")


def test_bad_direct_construction():
    with pytest.raises(InputError, match="B"):
        PalmerScanner(palmer_mirror_tilt=0.0)
    with pytest.raises(InputError, match="n > 1"):
        WedgeScanner(wedge_refractive_index=0.99)


@pytest.mark.parametrize("scanner", list(PERTURBED.values()), ids=lambda s: s.model)
def test_georeferencing_round_trip_with_rotating_scanner(scanner):
    n = 201
    t = np.linspace(1000.0, 1010.0, n)
    tr = Trajectory(t, np.full(n, np.radians(45.0)), np.radians(7.0) + np.linspace(0, 1e-4, n), np.full(n, 600.0),
                    np.full(n, 0.01), np.full(n, -0.02), np.full(n, 1.0))
    sensor = Sensor(boresight_roll=2e-3, boresight_pitch=-1e-3, lever_arm_x=0.2, scanner=scanner)
    rng = np.random.default_rng(3)
    tt = rng.uniform(1000, 1010, 3000)
    beta = rng.uniform(-np.pi, np.pi, tt.size)
    rng_m = rng.uniform(400, 700, tt.size)
    p = georef.forward(tr, sensor, tt, rng_m, beta)
    obs = georef.inverse(tr, sensor, tt, p)
    assert np.max(np.abs(_wrap(obs.angles - beta))) < 1e-9
    assert np.max(np.abs(georef.forward(tr, sensor, tt, obs.range_m, obs.angles) - p)) < 1e-6


def test_negative_eccentricity_is_reported_as_the_same_encoder_error_with_positive_ratio():
    from calidar.adjust import Parameter, ParameterSet, Solution
    from calidar.scanners.rotating import canonical_eccentricity

    params = ParameterSet([Parameter("boresight_pitch", 1e-4, "rad"), Parameter("eccentricity_ratio", -4.8e-4, "1"),
                           Parameter("eccentricity_phase", np.radians(-150.0), "rad")])
    cov = np.array([[4.0, 1.0, 0.5], [1.0, 9.0, -2.0], [0.5, -2.0, 16.0]]) * 1e-10
    sol = Solution(params, cov.copy(), sigma0=1.0, dof=10.0, condition_number=1.0)
    canonical_eccentricity(sol)
    v = sol.values
    assert v["eccentricity_ratio"] == pytest.approx(4.8e-4)
    assert np.degrees(v["eccentricity_phase"]) == pytest.approx(30.0)
    assert v["boresight_pitch"] == 1e-4
    assert np.allclose(np.diag(sol.covariance), np.diag(cov))
    assert sol.covariance[0, 1] == -cov[0, 1] and sol.covariance[1, 2] == -cov[1, 2] and sol.covariance[0, 2] == cov[0, 2]
    beta = np.linspace(0, 2 * np.pi, 50)
    before = palmer_directions(beta, np.radians(45), np.radians(7.5), -4.8e-4, np.radians(-150.0))
    after = palmer_directions(beta, np.radians(45), np.radians(7.5), v["eccentricity_ratio"], v["eccentricity_phase"])
    assert np.max(np.abs(after - before)) < 1e-15  # the same encoder error
