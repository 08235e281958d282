"""TileLinear: the CRS coordinates of points moved by metres from a Jacobian per tile, and ECEF near them."""

from __future__ import annotations

import numpy as np
import pytest

from calidar import georef


@pytest.mark.parametrize("crs, span", [("EPSG:32611", 3000.0), ("EPSG:4979", 0.03)])
def test_moved_points_match_the_full_transform(crs, span):
    rng = np.random.default_rng(3)
    base = np.array([500000.0, 4100000.0, 1500.0]) if crs == "EPSG:32611" else np.array([-117.0, 37.0, 1500.0])
    xyz = base + rng.uniform(-span, span, (20000, 3)) * [1, 1, 0]
    ecef = georef.from_crs(xyz, crs)
    moved = ecef + rng.normal(0.0, 2.0, ecef.shape)  # a few metres, as a new mounting moves points
    got = georef.tile_linear(xyz, crs).moved(moved - ecef)
    want = georef.to_crs(moved, crs)
    back = georef.from_crs(got, crs)  # compare in metres whatever the CRS units
    assert np.max(np.linalg.norm(back - georef.from_crs(want, crs), axis=1)) < 1e-4
    assert np.max(np.linalg.norm(back - moved, axis=1)) < 1e-4
    assert np.max(np.linalg.norm(moved - ecef, axis=1)) > 5.0  # the moves are not trivial


@pytest.mark.parametrize("crs, span", [("EPSG:32611", 100.0), ("EPSG:4979", 0.001)])
def test_near_ecef_is_within_a_millimetre(crs, span):
    rng = np.random.default_rng(5)
    base = np.array([500000.0, 4100000.0, 1500.0]) if crs == "EPSG:32611" else np.array([-117.0, 37.0, 1500.0])
    # 4 points/m² over 200 m × 200 m (a chunk of a strip), heights spread over 100 m
    xyz = base + rng.uniform(-span, span, (160_000, 3)) * [1, 1, 0] + rng.uniform(-50, 50, (160_000, 3)) * [0, 0, 1]
    lin = georef.tile_linear(xyz, crs)
    err = np.linalg.norm(lin.near_ecef() - georef.from_crs(xyz, crs), axis=1)
    assert 1e-6 < np.max(err) < 1e-3  # an approximation, of at most a millimetre
    assert lin.anchor.size < xyz.shape[0] / 1000  # far fewer PROJ calls than points


def test_regeoreferencing_through_near_ecef_equals_the_exact_transform():
    """Inverse and forward through the same approximate ECEF: only the moves count, so the
    millimetre of near_ecef moves the re-georeferenced points by < 0.01 mm (≈ the mounting
    change, 2e-3 rad, times it: what
    calidar.ingest.source.line_chunks relies on); with the tiles' Jacobians, within 0.1 mm."""
    from calidar.sensor import Sensor
    from calidar.trajectory import Trajectory

    n, crs = 2001, "EPSG:32632"
    t = np.linspace(1000.0, 1010.0, n)
    traj = Trajectory(t, np.full(n, np.radians(45.0)), np.radians(7.0) + np.linspace(0, 1e-2, n), np.full(n, 1000.0),
                      np.zeros(n), np.zeros(n), np.full(n, np.pi / 2))
    old, new = Sensor(), Sensor(boresight_roll=np.radians(0.05), boresight_yaw=np.radians(-0.1), lever_arm_x=0.2)
    rng = np.random.default_rng(0)
    ts, ang, rho = rng.uniform(1000, 1010, 100_000), rng.uniform(-0.6, 0.6, 100_000), rng.uniform(900, 1100, 100_000)
    xyz = georef.to_crs(georef.forward(traj, old, ts, rho, ang), crs)
    want = georef.to_crs(georef.regeoreference(traj, old, new, ts, georef.from_crs(xyz, crs)), crs)
    lin = georef.tile_linear(xyz, crs)
    ecef = lin.near_ecef()
    got = lin.moved(georef.regeoreference(traj, old, new, ts, ecef) - ecef)
    exact = georef.from_crs(xyz, crs)
    assert np.max(np.linalg.norm(got - lin.moved(georef.regeoreference(traj, old, new, ts, exact) - exact), axis=1)) < 1e-5
    assert np.max(np.linalg.norm(got - want, axis=1)) < 1e-4
    assert np.max(np.linalg.norm(want - xyz, axis=1)) > 0.5  # the new mounting moves the points
