"""The strip's surface at a control point (strips/control_surface.py): a quadric read at the point.
On curved ground a plane through the points misses the ground at the centre by κR²/4 (for
z = ½κ(x² + y²) over a disc of radius R, the plane sits at the mean height, ½κ·R²/2); the quadric
reads it exactly. Its noise σ is checked against the scatter of the reading over noise draws, and
points that do not surround the control point give no row."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.strips.control_surface import local_surface

KAPPA = 0.02  #: curvature 1/m: 1 cm of sag over 1 m, gentle ground
R = 2.0


def _ground(rng, n=60, centre=(3.0, -2.0)):
    r, phi = R * np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 2 * np.pi, n)
    dx, dy = r * np.cos(phi), r * np.sin(phi)
    z = 100.0 + 0.1 * dx - 0.05 * dy + 0.5 * KAPPA * (dx**2 + dy**2)
    return np.c_[centre[0] + dx, centre[1] + dy, z], np.array([centre[0], centre[1], 100.0])


def test_the_quadric_reads_curved_ground_where_a_plane_misses_it():
    rng = np.random.default_rng(1)
    pts, at = _ground(rng)
    w, normal, var = local_surface(pts, at)
    assert w.sum() == pytest.approx(1.0) and np.allclose(w @ (pts[:, :2] - at[:2]), 0.0, atol=1e-9)
    assert w @ pts[:, 2] == pytest.approx(100.0, abs=1e-9)  # exact on a quadric
    assert np.allclose(normal, np.array([-0.1, 0.05, 1.0]) / np.sqrt(1 + 0.01 + 0.0025), atol=1e-9)
    plane = np.linalg.lstsq(np.c_[np.ones(len(pts)), pts[:, :2] - at[:2]], pts[:, 2], rcond=None)[0][0]
    assert plane - 100.0 == pytest.approx(KAPPA * R**2 / 4, rel=0.3)  # what the rows missed before: 2 cm here
    assert var == pytest.approx(0.0, abs=1e-20)


def test_its_noise_sigma_is_the_readings_scatter():
    rng = np.random.default_rng(2)
    pts, at = _ground(rng)
    readings, variances = [], []
    for _ in range(400):
        noisy = pts + np.c_[np.zeros((len(pts), 2)), rng.normal(0, 0.01, len(pts))]
        w, _, var = local_surface(noisy, at)
        readings.append(w @ noisy[:, 2] - 100.0)
        variances.append(var)
    assert np.std(readings) == pytest.approx(np.sqrt(np.mean(variances)), rel=0.1)
    assert np.sqrt(np.mean(variances)) == pytest.approx(0.02 / np.sqrt(60), rel=0.35)  # ≈ 2σ/√n on a disc


def test_points_that_do_not_surround_the_control_point_give_no_row():
    rng = np.random.default_rng(3)
    pts, at = _ground(rng)
    one_side = pts[pts[:, 0] > at[0] + 0.8]  # a control point beyond the strip's edge
    assert local_surface(one_side, at) is None
    assert local_surface(pts[:10], at) is None  # too few for six coefficients and their scatter
