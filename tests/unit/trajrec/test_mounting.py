"""The scanner's own calibration in the trajectory fit (issue #30): a scan-angle encoder with an offset
and a scale error and a scan plane yawed and pitched in the body, which points cannot tell from roll,
height, heading and pitch. Drawn from their priors, the errors they cause stay within the σ the fit
reports; with the priors at 0 the fit is the one without them."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.frames import R_ENU_NED, rpy_to_matrix
from calidar.trajrec import mounting
from calidar.trajrec.fit import FitSettings, Observations, channel_sigma, solve_segment
from calidar.trajrec.spline import Spline

PRIOR = mounting.DEFAULT_SIGMA  # offset 0.1°, scale 0.3 %, yaw 0.1°, pitch 0.1°


def truth_of(t):
    """A sensor at 1000 m flying north at 60 m/s with smoothly varying attitude."""
    return np.c_[5 * np.sin(t / 3), 60 * t, 1000 + 2 * np.sin(t / 2), np.radians(1.0) * np.sin(t),
                 np.radians(2.0) + np.radians(0.5) * np.sin(t / 1.5), np.radians(3.0) + np.radians(0.3) * np.cos(t)]


def _rot(axis: int, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def mounted_line(rng, mount, n=20000, relief=40.0, noise_deg=0.003):
    """Ground points (z 0 ± ``relief`` m) of a ±20° scanner whose scan plane is yawed κ and pitched ε in
    the body (b = Rz(κ)·Ry(ε)·s), the scan-angle field the body's across-track angle read by an
    encoder with an offset δ and a scale k (stored = (angle − δ)/(1 + k)); ``mount`` = (δ, k, κ, ε)."""
    d, k, kappa, eps = mount
    t = np.sort(rng.uniform(0, 8, n))
    tr = truth_of(t)
    theta = np.radians(20.0) * np.sin(2 * np.pi * 20 * t)
    u_b = np.stack([np.zeros_like(theta), np.sin(theta), np.cos(theta)], 1) @ (_rot(2, kappa) @ _rot(1, eps)).T
    u_enu = np.einsum("ij,njk,nk->ni", R_ENU_NED, rpy_to_matrix(tr[:, 3], tr[:, 4], tr[:, 5]), u_b)
    pts = tr[:, :3] + ((tr[:, 2] - rng.normal(0, relief, n)) / -u_enu[:, 2])[:, None] * u_enu
    stored = (np.arctan2(u_b[:, 1], u_b[:, 2]) - d) / (1 + k) + rng.normal(0, np.radians(noise_deg), n)
    return t, pts, stored


def _fit(t, pts, stored, sigma):
    obs = Observations(pts, t, stored, True, True, np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)),
                       np.empty(0), np.empty(0))
    sp = Spline.covering(0, 8, 0.25)
    ts = np.linspace(0, 8, 200)
    start = truth_of(ts) * np.r_[1, 1, 1, 0, 0, 1] + np.r_[10.0, 20.0, -30.0, 0, 0, 0.01]
    fit = solve_segment(obs, sp, sp.fit(ts, start), FitSettings(mount_sigma=tuple(sigma)))
    tt = np.linspace(0.5, 7.5, 50)
    return sp.evaluate(fit.coef, tt) - truth_of(tt), channel_sigma(fit, tt), fit


def test_sigma_honest_with_the_encoder_and_scan_plane_drawn_from_their_priors():
    z, scale_err = [], []
    for seed in range(24):
        rng = np.random.default_rng(seed)
        mount = rng.normal(0, PRIOR)
        err, sig, fit = _fit(*mounted_line(rng, mount), PRIOR)
        z.append(np.sqrt(np.mean((err / sig) ** 2, axis=0)))
        scale_err.append((fit.mount[1] - mount[1]) / fit.mount_sigma[1])
    rms = np.sqrt(np.mean(np.array(z) ** 2, axis=0))
    # east, north, up, roll, pitch, heading (measured 0.97, 1.01, 1.15, 0.95, 1.17, 1.12; without the
    # parameters roll, pitch and heading were 50–3000× their σ off)
    assert np.all((rms > 0.7) & (rms < 1.3)), rms
    # the relief determines the encoder's scale: estimated, within its σ; the others are held (prior σ)
    assert fit.mount_sigma[1] < 0.1 * PRIOR[1]
    assert 0.5 < np.sqrt(np.mean(np.square(scale_err))) < 1.5
    np.testing.assert_allclose(fit.mount_sigma[[0, 2, 3]], np.asarray(PRIOR)[[0, 2, 3]], rtol=0.02)


def test_without_the_parameters_sigma_unchanged_and_errors_large():
    rng = np.random.default_rng(3)
    mount = np.array([np.radians(0.1), 0.003, np.radians(0.1), np.radians(0.1)])
    t, pts, stored = mounted_line(rng, mount)
    err0, sig0, _ = _fit(t, pts, stored, (0.0, 0.0, 0.0, 0.0))
    err_tiny, sig_tiny, _ = _fit(t, pts, stored, (1e-9, 1e-9, 1e-9, 1e-9))  # known to 1e-9: the same fit
    np.testing.assert_allclose(np.median(sig_tiny, axis=0), np.median(sig0, axis=0), rtol=0.1)
    np.testing.assert_allclose(err_tiny, err0, atol=1e-3)  # within the iterations' 1 cm stopping rule
    # a user who claims to know a wrong calibration is told σ far below the errors it causes
    assert np.all(np.sqrt(np.mean((err0[:, 3:] / sig0[:, 3:]) ** 2, axis=0)) > 5)


def test_clean_scanner_with_priors_keeps_its_accuracy_and_widens_only_what_the_priors_touch():
    rng = np.random.default_rng(4)
    t, pts, stored = mounted_line(rng, np.zeros(4))
    err0, sig0, _ = _fit(t, pts, stored, (0.0, 0.0, 0.0, 0.0))
    err, sig, _ = _fit(t, pts, stored, PRIOR)
    # attitude: the estimates as before, σ at least the priors (what points cannot know)
    np.testing.assert_allclose(err[:, 3:], err0[:, 3:], atol=np.radians(1e-3))
    assert np.all(np.median(sig[:, 3:], axis=0) > 0.95 * np.radians(0.1))
    # east (across track): σ within 10 % of the fit without the parameters; north (along track) wider:
    # a scan plane yawed in the body moves the points along track by the yaw × their across-track offset
    assert np.median(sig[:, 0]) == pytest.approx(np.median(sig0[:, 0]), rel=0.1)
    assert np.median(sig[:, 1]) > np.median(sig0[:, 1])


@pytest.mark.parametrize("sigma", [mounting.DEFAULT_SIGMA, (0.0, 0.003, 0.0, 0.0)])
def test_notes_say_what_was_estimated_and_what_was_not(sigma):
    rng = np.random.default_rng(5)
    _, _, fit = _fit(*mounted_line(rng, np.zeros(4)), sigma)
    info = {n: (fit.mount[k], fit.mount_sigma[k], sigma[k]) for k, n in enumerate(mounting.NAMES) if sigma[k] > 0}
    text = " ".join(mounting.notes(info))
    assert "estimated from the points: scan-angle scale" in text
    assert ("not determined by the points, their prior σ in the σ columns: scan-angle offset 0.1°" in text) == (sigma[0] > 0)
