"""Platform motion along a flight plan: the true trajectory at 200 Hz, and its measured copy.

The nominal path is the flight lines (extended by a run-in) joined by cubic Hermite turns flown at
constant speed (a ferry leg back for same-direction plans). On top come smooth random perturbations:
along-track position (speed changes), lateral and vertical wander, crab, and roll/pitch/ heading
turbulence — Gaussian-filtered white noise with a correlation time. Attitude is built in the scene's
ENU frame and converted exactly to the local NED at each position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.fft import next_fast_len
from scipy.ndimage import gaussian_filter1d

from calidar import frames
from calidar.sim.flightplan import FlightLine
from calidar.trajectory import Trajectory
from calidar.trajectory_accuracy import TrajectoryAccuracy

G = 9.80665  #: m/s²
SBET_RATE_HZ = 200.0
#: white noise drawn this many kernel stds beyond each end of a smooth_noise record (the
#: Gaussian is 4e-6 of its peak there: nothing wraps around)
WRAP_MARGIN_TAU = 5.0
SIGMA_VARIATION_S = 60.0  #: time scale of the simulated trajectory σ's variation, s
ACCURACY_RATE_HZ = 1.0  #: epochs of the written smrmsg.out, as POSPac writes them
#: bank limit in turns; U-turns tighter than the platform could fly keep this bank (no scanning
#: there)
MAX_BANK_RAD = np.radians(35.0)


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


def smooth_noise(rng: np.random.Generator, n: int, dt_s: float, tau_s: float, sigma: float,
                 dims: int = 1, stationary: bool = False) -> np.ndarray:
    """Gaussian-filtered white noise (n, dims): kernel std ``tau_s`` (s), output std ``sigma``:
    that of this draw about its mean, or (``stationary``) the process's, of which this draw is one
    sample (its RMS then varies from draw to draw as a real error's does, and its mean over the
    record is part of it: a trajectory error whose σ a smrmsg states).

    A linear, not circular, convolution: the white noise runs ``WRAP_MARGIN_TAU`` kernel stds
    beyond both ends and is filtered in the frequency domain over that longer record, so the
    record's last samples do not share the first ones' errors (a real GNSS/INS does not wrap)."""
    pad = int(np.ceil(WRAP_MARGIN_TAU * tau_s / dt_s))
    size = next_fast_len(n + 2 * pad, real=True)
    w = rng.standard_normal((size, dims))  # drawn for σ = 0 too: the later draws do not shift
    if sigma == 0:
        return np.zeros((n, dims))
    f = np.fft.rfftfreq(size, dt_s)
    kernel = np.exp(-2.0 * (np.pi * f * tau_s) ** 2)  # a Gaussian of std tau_s (s), in frequency
    s = np.fft.irfft(np.fft.rfft(w, axis=0) * kernel[:, None], size, axis=0)[pad:pad + n]
    if stationary:  # the filter's power gain on unit white noise (Parseval over the full spectrum)
        power = np.exp(-4.0 * (np.pi * np.fft.fftfreq(size, dt_s) * tau_s) ** 2)
        return s * (sigma / np.sqrt(np.mean(power)))
    return s * (sigma / s.std(axis=0))


def _hermite(p0, d0, p1, d1, s) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Hermite curve from p0 to p1 with end derivatives d0, d1 (m): points and dP/ds at s ∈
    [0, 1]."""
    s = np.asarray(s, float)[:, None]
    # the Hermite basis h and its derivative g
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    g00, g10, g01, g11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
    return h00 * p0 + h10 * d0 + h01 * p1 + h11 * d1, g00 * p0 + g10 * d0 + g01 * p1 + g11 * d1


def _turn(p0, u0, p1, u1, speed_mps: float, dt_s: float,
          radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """A turn from p0 (heading u0) to p1 (heading u1) flown at constant speed, sampled every dt_s.

    Hermite curve with tangents scaled to the turn's size, resampled by arc length; returns
    positions and velocities (n, 3) at dt_s, 2·dt_s, …, the last one at p1.
    """
    scale = max(np.linalg.norm(p1 - p0), np.pi * radius_m) * 1.3
    s = np.linspace(0.0, 1.0, 4001)
    pos, _ = _hermite(p0, scale * u0, p1, scale * u1, s)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))]
    n = max(int(np.ceil(arc[-1] / (speed_mps * dt_s))), 1)
    sk = np.interp(np.arange(1, n + 1) * arc[-1] / n, arc, s)
    pos, der = _hermite(p0, scale * u0, p1, scale * u1, sk)
    return pos, der / np.linalg.norm(der, axis=1)[:, None] * (arc[-1] / (n * dt_s))


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
    # uniform 200 Hz grid: every leg and turn lasts a whole number of samples
    a0 = legs[0][0]
    times, pos, vel, windows = [np.array([t0])], [a0[None]], [None], []
    t = t0
    for k, (a, b, scanning) in enumerate(legs):
        length = np.linalg.norm(b - a)
        u = (b - a) / length
        if k:
            p0, u0 = pos[-1][-1], vel[-1][-1] / np.linalg.norm(vel[-1][-1])
            p, vv = _turn(p0, u0, a, u, v, dt, spec.turn_radius_m)
            times.append(t + np.arange(1, len(p) + 1) * dt), pos.append(p), vel.append(vv)
            t += len(p) * dt
        m = max(int(round(length / v / dt)), 1)
        v_leg = length / (m * dt)
        kk = np.arange(1, m + 1)
        times.append(t + kk * dt)
        pos.append(a + np.outer(kk / m * length, u))
        vel.append(np.tile(v_leg * u, (m, 1)))
        if k == 0:
            vel[0] = vel[1][:1]
        if scanning:
            windows.append((t + spec.run_in_m / v_leg, t + (length - spec.run_in_m) / v_leg))
        t += m * dt
    return np.concatenate(times), np.concatenate(pos), np.concatenate(vel), windows


def fly(scene, lines: list[FlightLine], spec: MotionSpec, rng: np.random.Generator, t0: float):
    """The true trajectory (200 Hz) over the plan and the scan windows [(t_start, t_end)] per
    line."""
    time, pos, vel, windows = nominal_path(lines, spec, t0)
    n, dt = time.size, 1.0 / SBET_RATE_HZ
    speed_h = np.hypot(vel[:, 0], vel[:, 1])
    # the horizontal direction of flight smoothed over 1 s: no kinks where turns meet lines
    direction = np.stack([vel[:, 0], vel[:, 1], np.zeros(n)], -1) / speed_h[:, None]
    fwd = gaussian_filter1d(direction, SBET_RATE_HZ, axis=0)
    fwd /= np.linalg.norm(fwd, axis=1)[:, None]
    side = np.stack([fwd[:, 1], -fwd[:, 0], np.zeros(n)], -1)  # to the right
    wander_sigma = [spec.along_sigma_m, spec.across_sigma_m, spec.vertical_sigma_m]
    wander = smooth_noise(rng, n, dt, spec.wander_tau_s, 1.0, 3) * wander_sigma
    pos = pos + wander[:, :1] * fwd + wander[:, 1:2] * side + wander[:, 2:3] * [0, 0, 1]
    vel = np.gradient(pos, dt, axis=0)
    azimuth = np.unwrap(np.arctan2(vel[:, 0], vel[:, 1]))
    # the bank follows the turn rate within ~0.5 s: tan(bank) = v·ω / g (a coordinated turn)
    turn_rate = gaussian_filter1d(np.gradient(azimuth, dt), SBET_RATE_HZ / 2)
    turb = smooth_noise(rng, n, dt, spec.turbulence_tau_s, 1.0, 3)
    crab = smooth_noise(rng, n, dt, 4 * spec.wander_tau_s, spec.heading_sigma_rad)[:, 0]
    ground_speed = np.hypot(vel[:, 0], vel[:, 1])
    bank = np.clip(np.arctan(ground_speed * turn_rate / G), -MAX_BANK_RAD, MAX_BANK_RAD)
    roll = bank + spec.attitude_sigma_rad * turb[:, 0]
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
    truth = Trajectory(time, lat, lon, h, roll, pitch, heading, v_ned, source="<simulated truth>")
    return truth, windows


def measured_trajectory(truth: Trajectory, rng: np.random.Generator, gnss_sigma_m,
                        attitude_sigma_rad,
                        strip_errors: list[tuple[float, float, dict]] = ()) -> Trajectory:
    """What the GNSS/INS delivers: truth + smooth position (τ 10 s) and attitude (τ 2 s) errors.

    ``gnss_sigma_m``, ``attitude_sigma_rad``: their σ — one number, or per record and axis
    (N, 3) north/east/down m and roll/pitch/heading rad (the errors then follow the σ in time,
    as a trajectory's stated accuracy says they do).
    ``strip_errors``: per line (t_start, t_end, errors) with errors ``position_bias_m`` (3,) NED,
    ``position_drift_mps`` (3,) NED, ``attitude_bias_rad`` (3,) and ``attitude_drift_radps`` (3,)
    roll/pitch/heading; drifts grow from the window's middle; a 5 s cosine taper outside the window.
    """
    n, dt = len(truth), 1.0 / truth.rate_hz
    # stationary: the errors' σ is the σ stated (smrmsg.out), their mean over the flight included
    # (a draw's own std about its mean would scale a short flight's errors by 0.8–2×, all of the
    # excess in the flight-wide part that no overlap sees: benchmarks/control_montecarlo.py)
    d_ned = smooth_noise(rng, n, dt, 10.0, 1.0, 3, stationary=True) * gnss_sigma_m
    d_att = smooth_noise(rng, n, dt, 2.0, 1.0, 3, stationary=True) * attitude_sigma_rad
    for t_a, t_b, e in strip_errors:
        gap = np.maximum(np.maximum(t_a - truth.time, truth.time - t_b), 0.0)
        w = np.where(gap < 5.0, 0.5 * (1 + np.cos(np.pi * gap / 5.0)), 0.0)[:, None]
        tc = (np.clip(truth.time, t_a, t_b) - 0.5 * (t_a + t_b))[:, None]
        d_ned = d_ned + w * (e["position_bias_m"] + tc * e["position_drift_mps"])
        d_att = d_att + w * (e["attitude_bias_rad"] + tc * e["attitude_drift_radps"])
    ecef = truth.ecef + np.einsum("nij,nj->ni", frames.r_en(truth.lat, truth.lon), d_ned)
    lat, lon, h = frames.ecef_to_geodetic(ecef)
    roll, pitch = truth.roll + d_att[:, 0], truth.pitch + d_att[:, 1]
    heading = truth.heading + d_att[:, 2]
    return Trajectory(truth.time, lat, lon, h, roll, pitch, heading, truth.velocity_ned,
                      truth.time_system, "<simulated SBET>")


def accuracy_epochs(time: np.ndarray, sig_pos: np.ndarray,
                    sig_att: np.ndarray) -> TrajectoryAccuracy:
    """The trajectory's σ at whole seconds over its span, as POSPac's smrmsg holds them (σ of a
    noiseless trajectory floored at 0.1 mm and 0.02″)."""
    epochs = np.arange(np.ceil(time[0]), np.floor(time[-1]) + 0.5, 1.0 / ACCURACY_RATE_HZ)

    def at(s: np.ndarray, floor: float) -> np.ndarray:
        at_epochs = np.stack([np.interp(epochs, time, s[:, k]) for k in range(3)], 1)
        return np.maximum(at_epochs, floor)

    pos, att = at(sig_pos, 1e-4), at(sig_att, 1e-7)
    return TrajectoryAccuracy(epochs, pos, att, pos / 10.0, "<simulated smrmsg>")


def trajectory_sigma(cfg, time: np.ndarray,
                     rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """σ of the trajectory (``cfg``: a :class:`calidar.sim.survey.SurveyConfig`)'s errors per record
    (N, 3): north/east/down m and roll/pitch/heading rad (constant unless
    ``trajectory_sigma_variation``; the per-axis ``trajectory_sigma_scale``)."""
    scale = np.asarray(cfg.trajectory_sigma_scale, float)
    base = np.r_[cfg.gnss_noise_m * scale[:3], cfg.attitude_noise_rad * scale[3:]]
    sig = np.tile(base, (time.size, 1))
    if cfg.trajectory_sigma_variation > 0:
        dt = float(np.median(np.diff(time)))
        g = smooth_noise(rng, time.size, dt, SIGMA_VARIATION_S, 1.0, 6)
        # the filter keeps the white noise's mean: remove it
        g = (g - g.mean(axis=0)) / g.std(axis=0)
        sig *= np.exp(cfg.trajectory_sigma_variation * g)
    return sig[:, :3], sig[:, 3:]
