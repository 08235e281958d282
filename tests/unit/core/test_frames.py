import numpy as np
import pytest

from calidar import frames


def test_geodetic_ecef_round_trip():
    rng = np.random.default_rng(0)
    lat = rng.uniform(-np.pi / 2, np.pi / 2, 1000)
    lon = rng.uniform(-np.pi, np.pi, 1000)
    h = rng.uniform(-500, 9000, 1000)
    lat2, lon2, h2 = frames.ecef_to_geodetic(frames.geodetic_to_ecef(lat, lon, h))
    assert np.max(np.abs(lat2 - lat)) < 1e-12
    assert np.max(np.abs(np.angle(np.exp(1j * (lon2 - lon))))) < 1e-12
    assert np.max(np.abs(h2 - h)) < 1e-6


def test_ecef_known_point():
    # equator / prime meridian at 0 m is (a, 0, 0); north pole at 0 m is (0, 0, b)
    assert np.allclose(frames.geodetic_to_ecef(0, 0, 0), [frames.WGS84_A, 0, 0])
    assert np.allclose(frames.geodetic_to_ecef(np.pi / 2, 0, 0), [0, 0, frames.WGS84_B], atol=1e-6)


def test_rpy_matrix_quaternion_round_trip():
    rng = np.random.default_rng(1)
    r, p, h = rng.uniform(-1, 1, 50), rng.uniform(-1.4, 1.4, 50), rng.uniform(-3, 3, 50)
    m = frames.rpy_to_matrix(r, p, h)
    assert np.allclose(np.stack(frames.matrix_to_rpy(m)), np.stack([r, p, h]))
    assert np.allclose(frames.quat_to_matrix(frames.matrix_to_quat(m)), m)


def test_heading_90_points_body_x_east():
    m = frames.rpy_to_matrix(0.0, 0.0, np.pi / 2)
    assert np.allclose(m @ [1, 0, 0], [0, 1, 0])  # forward → east in NED
    m = frames.rpy_to_matrix(np.radians(10), 0.0, 0.0)
    # right wing down: body y tilts towards +down
    assert np.allclose(m @ [0, 1, 0], [0, np.cos(np.radians(10)), np.sin(np.radians(10))])


def test_r_en_axes():
    lat, lon = np.radians(37.0), np.radians(-119.0)
    m = frames.r_en(lat, lon)
    x = frames.geodetic_to_ecef(lat, lon, 0.0)
    up = frames.geodetic_to_ecef(lat, lon, 1.0) - x
    assert np.allclose(m @ [0, 0, -1], up, atol=1e-9)
    north = frames.geodetic_to_ecef(lat + 1e-7, lon, 0.0) - x
    assert np.allclose(m @ [1, 0, 0], north / np.linalg.norm(north), atol=1e-6)
    assert np.allclose(m.T @ m, np.eye(3))


def test_slerp_matches_rotation_about_fixed_axis():
    q0 = frames.matrix_to_quat(frames.rot_z(0.2))
    q1 = frames.matrix_to_quat(frames.rot_z(1.0))
    q = frames.slerp(q0, q1, 0.25)
    assert np.allclose(frames.quat_to_matrix(q), frames.rot_z(0.4))


def test_small_angle_matrix_first_order():
    a = 1e-4
    exact = frames.rpy_to_matrix(a, -a, 2 * a)
    assert np.max(np.abs(exact - frames.small_angle_matrix(a, -a, 2 * a))) < 1e-7


def test_meridian_convergence_sign():
    # west of UTM 11N's central meridian true north points clockwise of grid north
    import pyproj

    lon, lat = -119.024, 37.764
    gamma, k = frames.grid_factors("EPSG:32611", np.radians(lon), np.radians(lat))
    t = pyproj.Transformer.from_crs(4326, 32611, always_xy=True)
    x0, y0 = t.transform(lon, lat)
    x1, y1 = t.transform(lon, lat + 0.001)
    grid_azimuth_of_true_north = np.arctan2(x1 - x0, y1 - y0)
    # true heading = grid heading + γ  ⇒  true north (0) has grid heading −γ
    assert grid_azimuth_of_true_north == pytest.approx(-gamma, abs=1e-6)
    assert 0.9996 < k < 1.0
