"""Platform motion along a flight plan: the true trajectory at 200 Hz, and its measured copy.

The nominal path is the flight lines (extended by a run-in) joined by cubic Hermite turns
(a ferry leg back for same-direction plans). On top come smooth random perturbations:
along-track position (speed changes), lateral and vertical wander, crab, and roll/pitch/
heading turbulence — Gaussian-filtered white noise with a correlation time. Attitude is
built in the scene's ENU frame and converted exactly to the local NED at each position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from calidar import frames
from calidar.sim.flightplan import FlightLine
from calidar.trajectory import Trajectory

G = 9.80665  #: m/s²
SBET_RATE_HZ = 200.0


@dataclass(frozen=True)
class MotionSpec:
    """Platform dynamics; σ values are standard deviations of the smooth perturbations."""

    speed_mps: float = 8.0
    run_in_m: float = 30.0  #: straight flight before/after the scanned part of a line
    turn_radius_m: float = 30.0
    pitch_rad: float = 0.0  #: mean pitch (nose up > 0)
    attitude_sigma_rad: float = np.radians(1.5)  #: roll/pitch turbulence
    heading_sigma_rad: float = np.radians(1.0)  #: crab and heading turbulence
    turbulence_tau_s: float = 1.0  #: correlation time of the attitude turbulence
    along_sigma_m: float = 1.5  #: along-track position wander (speed changes)
    across_sigma_m: float = 0.8  #: lateral wander
    vertical_sigma_m: float = 0.5
    wander_tau_s: float = 6.0


def smooth_noise(rng: np.random.Generator, n: int, dt_s: float, tau_s: float, sigma: float, dims: int = 1) -> np.ndarray:
    """Gaussian-filtered white noise (n, dims) with correlation time ``tau_s`` and std ``sigma``."""
    w = rng.standard_normal((n, dims))
    if sigma == 0:
        return np.zeros((n, dims))
    s = gaussian_filter1d(w, sigma=max(tau_s / dt_s, 1e-3), axis=0, mode="reflect")
    return s * (sigma / s.std(axis=0))


def _hermite(p0, v0, p1, v1, t) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Hermite positions and velocities at times t ∈ [0, T] (T = t[-1] span), m and m/s."""
    T = t[-1]
    s = (t / T)[:, None]
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
    pos = h00 * p0 + h10 * T * v0 + h01 * p1 + h11 * T * v1
    vel = (d00 * p0 + d10 * T * v0 + d01 * p1 + d11 * T * v1) / T
    return pos, vel


def nominal_path(lines: list[FlightLine], spec: MotionSpec, t0: float):
    """Nominal 3-D path at 200 Hz: times, ENU positions and velocities, and each line's scan window.

    Returns (time (N,), pos (N, 3), vel (N, 3), windows [(t_start, t_end)] per line).
    """
    dt, v = 1.0 / SBET_RATE_HZ, spec.speed_mps
    legs: list[tuple[np.ndarray, np.ndarray, bool]] = []  # straight legs (start, end, scanning)
    for k, line in enumerate(lines):
        d = line.direction
        a = np.r_[line.start - spec.run_in_m * d, line.altitude_m]
        b = np.r_[line.end + spec.run_in_m * d, line.altitude_m]
        if k and np.dot(lines[k - 1].direction, d) > 0.5:
            # same direction as the previous line: fly a ferry leg back, offset sideways
            off = np.r_[2 * spec.turn_radius_m * np.array([d[1], -d[0]]), 0.0]
            legs.append((legs[-1][1] + off, a + off, False))
        legs.append((a, b, True))
    times, pos, vel, windows = [], [], [], []
    t = t0
    for k, (a, b, scanning) in enumerate(legs):
        if k:
            p0, v0 = pos[-1][-1], vel[-1][-1]
            u1 = (b - a) / np.linalg.norm(b - a)
            gap = np.linalg.norm(a - p0)
            turn_len = max(gap, np.pi * spec.turn_radius_m) * 1.3
            T = turn_len / v
            tt = np.arange(1, int(np.ceil(T / dt))) * dt
            tt = np.r_[tt, T]
            p, vv = _hermite(p0, v0, a, v * u1, tt)
            times.append(t + tt[:-1]), pos.append(p[:-1]), vel.append(vv[:-1])
            t += T
        length = np.linalg.norm(b - a)
        u = (b - a) / length
        tt = np.arange(int(np.floor(length / v / dt)) + 1) * dt
        times.append(t + tt), pos.append(a + np.outer(tt * v, u)), vel.append(np.tile(v * u, (tt.size, 1)))
        if scanning:
            windows.append((t + spec.run_in_m / v, t + (length - spec.run_in_m) / v))
        t += tt[-1] + dt
    return np.concatenate(times), np.concatenate(pos), np.concatenate(vel), windows


def fly(scene, lines: list[FlightLine], spec: MotionSpec, rng: np.random.Generator, t0: float):
    """The true trajectory (200 Hz) over the plan and the scan windows [(t_start, t_end)] per line."""
    time, pos, vel, windows = nominal_path(lines, spec, t0)
    n, dt = time.size, 1.0 / SBET_RATE_HZ
    speed_h = np.hypot(vel[:, 0], vel[:, 1])
    fwd = np.stack([vel[:, 0], vel[:, 1], np.zeros(n)], -1) / speed_h[:, None]
    side = np.stack([fwd[:, 1], -fwd[:, 0], np.zeros(n)], -1)  # to the right
    wander = smooth_noise(rng, n, dt, spec.wander_tau_s, 1.0, 3) * [spec.along_sigma_m, spec.across_sigma_m,
                                                                   spec.vertical_sigma_m]
    pos = pos + wander[:, :1] * fwd + wander[:, 1:2] * side + wander[:, 2:3] * [0, 0, 1]
    vel = np.gradient(pos, dt, axis=0)
    azimuth = np.unwrap(np.arctan2(vel[:, 0], vel[:, 1]))
    turn_rate = np.gradient(azimuth, dt)
    turb = smooth_noise(rng, n, dt, spec.turbulence_tau_s, 1.0, 3)
    crab = smooth_noise(rng, n, dt, 4 * spec.wander_tau_s, spec.heading_sigma_rad)[:, 0]
    roll = np.arctan(np.hypot(vel[:, 0], vel[:, 1]) * turn_rate / G) + spec.attitude_sigma_rad * turb[:, 0]
    pitch = spec.pitch_rad + spec.attitude_sigma_rad * turb[:, 1]
    heading = azimuth + crab + 0.3 * spec.heading_sigma_rad * turb[:, 2]
    # attitude w.r.t. the origin's NED → ECEF → local NED at each position
    r_e_b = scene.r_e_enu @ frames.R_ENU_NED @ frames.rpy_to_matrix(roll, pitch, heading)
    ecef = scene.enu_to_ecef(pos)
    lat, lon, h = frames.ecef_to_geodetic(ecef)
    r_en = frames.r_en(lat, lon)
    r_nb = np.swapaxes(r_en, -1, -2) @ r_e_b
    roll, pitch, heading = frames.matrix_to_rpy(r_nb)
    v_ned = np.einsum("nji,nj->ni", r_en, vel @ scene.r_e_enu.T)
    return Trajectory(time, lat, lon, h, roll, pitch, heading, v_ned, source="<simulated truth>"), windows


def measured_trajectory(truth: Trajectory, rng: np.random.Generator, gnss_sigma_m: float, attitude_sigma_rad: float,
                        strip_offsets: list[tuple[float, float, np.ndarray, np.ndarray, np.ndarray]] = ()) -> Trajectory:
    """What the GNSS/INS delivers: truth + smooth position (τ 10 s) and attitude (τ 2 s) errors.

    ``strip_offsets``: per line (t_start, t_end, position bias (3,) m NED, drift (3,) m/s NED,
    attitude bias (3,) rad roll/pitch/heading), applied with a 5 s cosine taper outside the window.
    """
    n, dt = len(truth), 1.0 / truth.rate_hz
    d_ned = smooth_noise(rng, n, dt, 10.0, gnss_sigma_m, 3)
    d_att = smooth_noise(rng, n, dt, 2.0, attitude_sigma_rad, 3)
    for t_a, t_b, bias, drift, att in strip_offsets:
        gap = np.maximum(np.maximum(t_a - truth.time, truth.time - t_b), 0.0)
        w = np.where(gap < 5.0, 0.5 * (1 + np.cos(np.pi * gap / 5.0)), 0.0)[:, None]
        tc = np.clip(truth.time, t_a, t_b) - 0.5 * (t_a + t_b)
        d_ned = d_ned + w * (bias + tc[:, None] * drift)
        d_att = d_att + w * att
    ecef = truth.ecef + np.einsum("nij,nj->ni", frames.r_en(truth.lat, truth.lon), d_ned)
    lat, lon, h = frames.ecef_to_geodetic(ecef)
    return Trajectory(truth.time, lat, lon, h, truth.roll + d_att[:, 0], truth.pitch + d_att[:, 1],
                      truth.heading + d_att[:, 2], truth.velocity_ned, truth.time_system, "<simulated SBET>")
