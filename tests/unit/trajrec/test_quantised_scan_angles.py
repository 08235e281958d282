"""σ of the reconstructed trajectory with scan angles stored in whole degrees (LAS 1.0–1.3, issue 30):
a scanner that fires the same angles every sweep shares each stored value's rounding error across
all its points, which the independent-error covariance took for noise that averages (σ 8–12× too small)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.frames import R_ENU_NED, rpy_to_matrix
from calidar.trajrec.fit import FitSettings, Observations, channel_sigma, scan_quantum, solve_segment
from calidar.trajrec.spline import Spline


def truth_of(t):
    """A sensor at 1000 m flying north at 60 m/s with smoothly varying attitude."""
    return np.c_[5 * np.sin(t / 3), 60 * t, 1000 + 2 * np.sin(t / 2), np.radians(1.0) * np.sin(t),
                 np.radians(2.0) + np.radians(0.5) * np.sin(t / 1.5), np.radians(3.0) + np.radians(0.3) * np.cos(t)]


def phase_locked_line(rng, pulses_per_sweep=25, n=2500):
    """Ground points (z 0 ± 15 m) of a ±20° sine scanner at 20 sweeps a second firing at the same
    phases every sweep, their scan angles rounded to whole degrees."""
    t = np.sort(rng.choice(np.arange(0, 8, 1 / (20 * pulses_per_sweep)) + 1e-4, n, replace=False))
    truth = truth_of(t)
    theta = np.radians(20.0) * np.sin(2 * np.pi * 20 * t)
    u_b = np.stack([np.zeros_like(theta), np.sin(theta), np.cos(theta)], 1)
    u_enu = np.einsum("ij,njk,nk->ni", R_ENU_NED, rpy_to_matrix(truth[:, 3], truth[:, 4], truth[:, 5]), u_b)
    ground = rng.normal(0, 15, t.size)
    pts = truth[:, :3] + ((truth[:, 2] - ground) / -u_enu[:, 2])[:, None] * u_enu
    return t, pts, np.radians(np.round(np.degrees(theta)))


def test_scan_quantum_finds_whole_degrees_and_not_fine_angles():
    assert scan_quantum(np.radians([-3.0, 1.0, 2.0, 7.0, np.nan])) == pytest.approx(np.radians(1.0))
    assert scan_quantum(np.radians(np.arange(-20, 20, 0.006))) == 0.0  # LAS 1.4: 0.006° steps are not quantised
    assert scan_quantum(np.radians([4.0])) == 0.0


def test_sigma_honest_when_every_sweep_repeats_the_same_rounded_angles():
    z = []
    for seed in range(6):
        t, pts, stored = phase_locked_line(np.random.default_rng(seed))
        obs = Observations(pts, t, stored, True, True, np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)),
                           np.empty(0), np.empty(0))
        sp = Spline.covering(0, 8, 0.25)
        ts = np.linspace(0, 8, 200)
        start = truth_of(ts) * np.r_[1, 1, 1, 0, 0, 1] + np.r_[10.0, 20.0, -30.0, 0, 0, 0.01]
        fit = solve_segment(obs, sp, sp.fit(ts, start), FitSettings())
        tt = np.linspace(0.5, 7.5, 50)
        err = sp.evaluate(fit.coef, tt) - truth_of(tt)
        z.append(np.median(err / channel_sigma(fit, tt), axis=0))  # the shared errors are a bias along the line
    rms = np.sqrt(np.mean(np.array(z) ** 2, axis=0))
    # east, north, up, roll: the channels the across-track angles fix (8–12 before; 0.7–1.5 measured)
    assert np.all(rms[[0, 1, 2, 3]] < 2.2), rms
    assert np.all(rms[[0, 1, 2, 3]] > 0.3), rms
