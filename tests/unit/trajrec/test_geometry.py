"""Trajectory reconstruction's equations: numba kernels against the numpy reference, and the
segment fit recovering a known sensor path from synthetic rays and scan lines within its σ."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from calidar.trajrec.fit import FitSettings, Observations, channel_sigma, solve_segment
from calidar.trajrec.geometry import body_vectors, channel_partials, ray_basis, ray_residuals, scan_residuals
from calidar.trajrec.kernels import mount_partials, ray_partials, scan_partials
from calidar.trajrec.spline import Spline

RNG = np.random.default_rng(5)


def _states(n):
    return np.c_[RNG.normal(0, 50, (n, 2)), 1000 + RNG.normal(0, 5, n), RNG.normal(0, 0.03, (n, 2)),
                 RNG.uniform(-np.pi, np.pi, n)]


@pytest.mark.parametrize("kappa,eps", [(0.0, 0.0), (np.radians(13.96), 0.0), (np.radians(0.3), np.radians(-0.5))])
def test_kernels_match_the_numpy_equations(kappa, eps):
    n = 200
    state = _states(n)
    pts = np.c_[RNG.normal(0, 300, (n, 2)), RNG.normal(0, 20, n)]
    scan = RNG.normal(0, 0.3, n)
    r, g = scan_partials(pts, state, scan, kappa, eps)
    r_ref, g_ref = channel_partials(lambda s: scan_residuals(pts, s[:, :3], s[:, 3:], scan, kappa, eps), state,
                                    np.array([1e-3, 1e-3, 1e-3, 1e-7, 1e-7, 1e-7]))
    np.testing.assert_allclose(r, r_ref, atol=1e-12)
    np.testing.assert_allclose(g, g_ref, rtol=1e-5, atol=1e-8)
    # the scan plane's yaw and pitch: partials of the along-track angle
    h = 1e-7
    gm = mount_partials(pts, state, kappa, eps)
    for j, (dk, de) in enumerate(((h, 0.0), (0.0, h))):
        ref = (scan_residuals(pts, state[:, :3], state[:, 3:], scan, kappa + dk, eps + de)[:, 1]
               - scan_residuals(pts, state[:, :3], state[:, 3:], scan, kappa - dk, eps - de)[:, 1]) / (2 * h)
        np.testing.assert_allclose(gm[:, j], ref, rtol=1e-5, atol=1e-8)
    d = RNG.normal(0, 1, (n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    u1, u2 = ray_basis(d)
    np.testing.assert_allclose(np.einsum("ij,ij->i", u1, d), 0, atol=1e-12)
    rr, gr = ray_partials(np.ascontiguousarray(state[:, :3]), pts, u1, u2)
    rr_ref, gr_ref = channel_partials(lambda s: ray_residuals(s[:, :3], pts, u1, u2), state,
                                      np.array([1e-3, 1e-3, 1e-3, 0, 0, 0]))
    np.testing.assert_allclose(rr, rr_ref, atol=1e-14)
    np.testing.assert_allclose(gr, gr_ref, rtol=1e-5, atol=1e-12)


def test_body_vectors_follow_the_conventions_worked_example():
    # docs/conventions.md: flying east (heading 90°) with roll 10°, the +10° beam points straight down
    roll, heading = np.radians(10.0), np.radians(90.0)
    beam_enu = np.array([[0.0, 0.0, -1000.0]])  # straight down
    b = body_vectors(beam_enu, np.zeros((1, 3)), np.array([[roll, 0.0, heading]]))
    assert np.degrees(np.arctan2(b[0, 1], b[0, 2])) == pytest.approx(10.0, abs=1e-9)


TURN_RATE = 0.0  #: rad/s of the synthetic path's heading (a turning line when > 0)


def _truth(t):
    """A sensor at 1000 m flying north at 60 m/s with smoothly varying attitude (turning at TURN_RATE,
    banked as a coordinated turn would be)."""
    head = np.radians(3.0) + np.radians(0.3) * np.cos(t) + TURN_RATE * t
    if TURN_RATE:
        r = 60.0 / TURN_RATE
        east, north = r * (1 - np.cos(TURN_RATE * t)), r * np.sin(TURN_RATE * t)
    else:
        east, north = 5 * np.sin(t / 3), 60 * t
    bank = np.arctan(60.0 * TURN_RATE / 9.81)
    return np.c_[east, north, 1000 + 2 * np.sin(t / 2), bank + np.radians(1.0) * np.sin(t),
                 np.radians(2.0) + np.radians(0.5) * np.sin(t / 1.5), head]


def _scan_points(t, truth, noise_rad):
    """Ground points (z ≈ 0 ± 15 m) hit by a planar scanner at scan angles θ from the truth's poses."""
    from calidar.frames import R_ENU_NED, rpy_to_matrix

    theta = np.radians(20.0) * np.sin(2 * np.pi * 20 * t)
    u_b = np.stack([np.zeros_like(theta), np.sin(theta), np.cos(theta)], 1)
    u_enu = np.einsum("ij,njk,nk->ni", R_ENU_NED, rpy_to_matrix(truth[:, 3], truth[:, 4], truth[:, 5]), u_b)
    ground = RNG.normal(0, 15, t.size)
    rng = (truth[:, 2] - ground) / -u_enu[:, 2]
    pts = truth[:, :3] + rng[:, None] * u_enu
    return pts, theta + RNG.normal(0, noise_rad, t.size), u_enu


def test_rays_alone_recover_the_sensor_position_within_sigma():
    t = np.sort(RNG.uniform(0, 8, 6000))
    truth = _truth(t)
    last, _, u = _scan_points(t, truth, 0.0)
    sep = RNG.uniform(3, 15, t.size)
    first = last - sep[:, None] * u + RNG.normal(0, 0.03, (t.size, 3))
    last = last + RNG.normal(0, 0.03, (t.size, 3))
    d = (first - last) / np.linalg.norm(first - last, axis=1)[:, None]
    u1, u2 = ray_basis(d)
    obs = Observations(np.empty((0, 3)), np.empty(0), np.empty(0), False, False, last, u1, u2, t, 1.0 / sep)
    sp = Spline.covering(0, 8, 0.25)
    ts = np.linspace(0, 8, 200)
    start = _truth(ts) + np.r_[30.0, -40.0, 80.0, 0, 0, 0]  # 100 m off
    fit = solve_segment(obs, sp, sp.fit(ts, start), FitSettings())
    tt = np.linspace(0.5, 7.5, 50)
    err = sp.evaluate(fit.coef, tt)[:, :3] - _truth(tt)[:, :3]
    sig = channel_sigma(fit, tt)[:, :3]
    assert np.median(np.linalg.norm(err, axis=1)) < 0.5
    assert 0.3 < np.sqrt(np.mean((err / sig) ** 2)) < 2.0  # σ honest within a factor 2


@pytest.mark.parametrize("turn_deg_per_s", [0.0, 10.0])
def test_scan_lines_recover_position_and_attitude_within_sigma(monkeypatch, turn_deg_per_s):
    monkeypatch.setattr(sys.modules[__name__], "TURN_RATE", np.radians(turn_deg_per_s))  # 80° over the line
    t = np.sort(RNG.uniform(0, 8, 20000))
    truth = _truth(t)
    assert np.degrees(np.ptp(truth[:, 5])) == pytest.approx(turn_deg_per_s * 8, abs=1.0)
    pts, theta, _ = _scan_points(t, truth, np.radians(0.003))
    obs = Observations(pts, t, theta, True, True, np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)), np.empty(0),
                       np.empty(0))
    sp = Spline.covering(0, 8, 0.25)
    ts = np.linspace(0, 8, 200)
    start = _truth(ts) * np.r_[1, 1, 1, 0, 0, 1] + np.r_[10.0, 20.0, -30.0, 0, 0, 0.01]
    fit = solve_segment(obs, sp, sp.fit(ts, start), FitSettings())
    tt = np.linspace(0.5, 7.5, 50)
    est, tru = sp.evaluate(fit.coef, tt), _truth(tt)
    err = est - tru
    assert np.median(np.linalg.norm(err[:, :3], axis=1)) < 0.05
    assert np.all(np.degrees(np.median(np.abs(err[:, 3:]), axis=0)) < 0.002)
    z = err / channel_sigma(fit, tt)
    assert np.all(np.sqrt(np.mean(z**2, axis=0)) < 2.5)
