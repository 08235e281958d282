"""A synthetic flight line whose scanner has its own calibration errors, for the trajectory fit
(issue #30): a sensor 1000 m above ground flying north at 60 m/s with smoothly varying attitude, a
±20° scanner whose scan plane is yawed κ and pitched ε in the body, and a scan-angle encoder with an
offset δ and a scale k. The truth is known exactly; :func:`fit_line` fits it as `calidar trajectory`
does and returns the errors and σ per channel (E, N, U, roll, pitch, heading)."""

from __future__ import annotations

import numpy as np

from calidar.frames import R_ENU_NED, rpy_to_matrix
from calidar.trajrec.fit import FitSettings, Observations, channel_sigma, solve_segment
from calidar.trajrec.spline import Spline

DURATION_S = 8.0


def truth_of(t_s: np.ndarray) -> np.ndarray:
    """The true trajectory at ``t_s`` (s): E, N, U (m), roll, pitch, heading (rad), one row a
    time."""
    t = np.asarray(t_s, float)
    roll = np.radians(1.0) * np.sin(t)
    pitch = np.radians(2.0) + np.radians(0.5) * np.sin(t / 1.5)
    heading = np.radians(3.0) + np.radians(0.3) * np.cos(t)
    return np.c_[5 * np.sin(t / 3), 60 * t, 1000 + 2 * np.sin(t / 2), roll, pitch, heading]


def _axis_rotation(axis: int, angle_rad: float) -> np.ndarray:
    """The active rotation (3, 3) by ``angle_rad`` about axis 0 (x), 1 (y) or 2 (z)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def mounted_line(rng: np.random.Generator, mount, n: int = 20000, relief_m: float = 40.0,
                 noise_deg: float = 0.003) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (s), ground points (ENU m, heights 0 ± ``relief_m``) and stored scan angles (rad) of
    the line: b = Rz(κ)·Ry(ε)·s in the body, the stored angle the body's across-track angle read by
    the encoder, (angle − δ − q·(angle/30°)²)/(1 + k) plus ``noise_deg`` of noise, the beams at an
    angle c out of the scan plane; ``mount`` = (δ rad, k, κ rad, ε rad[, q rad, c rad])."""
    # curvature q (at 30°) and cone c: 0 when not given
    d, k, kappa, eps, curv, cone = (*mount, 0.0, 0.0)[:6]
    t = np.sort(rng.uniform(0, DURATION_S, n))
    tr = truth_of(t)
    theta = np.radians(20.0) * np.sin(2 * np.pi * 20 * t)
    rot = _axis_rotation(2, kappa) @ _axis_rotation(1, eps)
    beam = [np.full_like(theta, np.sin(cone)), np.cos(cone) * np.sin(theta),
            np.cos(cone) * np.cos(theta)]
    u_b = np.stack(beam, 1) @ rot.T
    u_enu = np.einsum("ij,njk,nk->ni", R_ENU_NED, rpy_to_matrix(tr[:, 3], tr[:, 4], tr[:, 5]), u_b)
    pts = tr[:, :3] + ((tr[:, 2] - rng.normal(0, relief_m, n)) / -u_enu[:, 2])[:, None] * u_enu
    angle = np.arctan2(u_b[:, 1], u_b[:, 2])
    read = angle - d - curv * (angle / np.radians(30.0)) ** 2
    stored = read / (1 + k) + rng.normal(0, np.radians(noise_deg), n)
    return t, pts, stored


def fit_line(t_s, points, stored_rad, mount_sigma):
    """The line fitted from its points and scan angles alone with the mounting priors
    ``mount_sigma`` (δ rad, k, κ rad, ε rad; 0 = known): (errors, σ) at 50 epochs (columns as
    :func:`truth_of`) and the fit itself."""
    obs = Observations(points, t_s, stored_rad, True, True, np.empty((0, 3)), np.empty((0, 3)),
                       np.empty((0, 3)), np.empty(0), np.empty(0))
    spline = Spline.covering(0, DURATION_S, 0.25)
    ts = np.linspace(0, DURATION_S, 200)
    start = truth_of(ts) * np.r_[1, 1, 1, 0, 0, 1] + np.r_[10.0, 20.0, -30.0, 0, 0, 0.01]
    settings = FitSettings(mount_sigma=tuple(mount_sigma))
    fit = solve_segment(obs, spline, spline.fit(ts, start), settings)
    tt = np.linspace(0.5, DURATION_S - 0.5, 50)
    return spline.evaluate(fit.coef, tt) - truth_of(tt), channel_sigma(fit, tt), fit
