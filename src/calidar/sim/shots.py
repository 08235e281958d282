"""The simulator's pulses: shot times and encoder angles along a line, the true beams cast into the
scene (with the beam's divergence when asked), and what the instrument records of each return.

Beam divergence (``SurveyConfig.beam_divergence_rad`` γ, full angle): a real pulse lights a
footprint of radius ρ·γ/2 and its return comes from somewhere within it. The simulator draws, per
pulse, the direction the return comes from out of the Gaussian beam profile: an angular offset of
σ = γ/4 on each of the two axes square to the beam (the footprint's edge, ρ·γ/2, taken as 2σ, as
the TPU models it: Baltsavias 1999, ISPRS J. 54:199; Glennie 2007, J. Appl. Geodesy 1:147). The
return's range is the distance to where that perturbed ray meets the scene; the instrument records
it with the encoder angle of the NOMINAL beam, so the delivered point lies along the nominal beam at
that range, as with a real system. ``true_enu`` stays the actual hit (on the perturbed ray).
Random numbers for the divergence are drawn only when γ > 0: without it every simulation is the
same, bit for bit, as before the divergence existed.
"""

from __future__ import annotations

import numpy as np

from calidar import georef
from calidar.sensor import Sensor
from calidar.sim.patterns import scan_angles
from calidar.sim.raycast import SURFACE_TERRAIN, cast
from calidar.sim.scene import CLASS_BUILDING, CLASS_GROUND, CLASS_VEGETATION

SURFACE_VEGETATION = -3  #: ``Strip.surface`` of crown returns


def line_shots(cfg, sensor: Sensor, window: tuple[float, float], half_fov: float):
    """Shot times (GPS s) and encoder angles (rad) over a scan window."""
    prf = cfg.pulse_rate_hz * cfg.density
    t = window[0] + np.arange(int((window[1] - window[0]) * prf)) / prf
    scan_rate_hz = cfg.scan_rate_hz * np.sqrt(cfg.density)
    return t, scan_angles(sensor.scanner, t, scan_rate_hz, half_fov, cfg.scan_pattern)


def diverge(directions: np.ndarray, divergence_rad: float, rng: np.random.Generator) -> np.ndarray:
    """Unit directions (N, 3) turned by a Gaussian angular offset of σ = γ/4 on each of two axes
    square to each beam (module docstring)."""
    d = directions / np.linalg.norm(directions, axis=1)[:, None]
    helper = np.where(np.abs(d[:, 2:]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(d, e1)
    off = rng.normal(0.0, divergence_rad / 4.0, (d.shape[0], 2))
    # exact rotation by the offset's angle about the axis square to it (small angles: d + off)
    angle = np.linalg.norm(off, axis=1)
    axis_dir = (off[:, :1] * e1 + off[:, 1:] * e2) / np.where(angle > 0, angle, 1.0)[:, None]
    return np.cos(angle)[:, None] * d + np.sin(angle)[:, None] * axis_dir


def shoot(cfg, scene, traj_true, truth: Sensor, t, enc, rng):
    """Cast the true beams; per return: pulse index, range (m), surface id, return number, number
    of returns, exact ENU hit."""
    noisy = enc
    if cfg.angle_noise_rad:
        noisy = enc + rng.normal(0.0, cfg.angle_noise_rad, np.shape(enc))
    origin_e, dir_e = georef.beams(*georef.poses(traj_true, t), truth, noisy)
    o, d = scene.ecef_to_enu(origin_e), dir_e @ scene.r_e_enu
    if cfg.beam_divergence_rad > 0:  # drawn only then: γ = 0 keeps every simulation bit-identical
        d = diverge(d, cfg.beam_divergence_rad, rng)
    hits = cast(scene, o, d, 1.0 - rng.random(t.size))
    solid, veg = np.isfinite(hits.t_solid), np.isfinite(hits.t_vegetation)
    pulse = np.r_[np.flatnonzero(veg), np.flatnonzero(solid)]
    rng_m = np.r_[hits.t_vegetation[veg], hits.t_solid[solid]]
    surface = np.r_[np.full(veg.sum(), SURFACE_VEGETATION), hits.surface[solid]]
    first = np.r_[np.ones(veg.sum(), bool), ~veg[solid]]
    order = np.lexsort((~first, pulse))
    pulse, rng_m, surface, first = pulse[order], rng_m[order], surface[order], first[order]
    n_ret = (veg.astype(np.uint8) + solid)[pulse]
    return_number = np.where(first, 1, 2).astype(np.uint8)
    return pulse, rng_m, surface, return_number, n_ret, o[pulse] + rng_m[:, None] * d[pulse]


def intensity(surface, range_m, ref_range_m, rng) -> np.ndarray:
    """Plausible 16-bit intensities: class reflectance × (R₀/R)² with speckle."""
    solid = np.where(surface == SURFACE_TERRAIN, 0.35, 0.5)
    refl = np.where(surface == SURFACE_VEGETATION, 0.25, solid)
    val = refl * (ref_range_m / range_m) ** 2 * rng.uniform(0.8, 1.2, range_m.size)
    return np.clip(val * 40000, 1, 65535).astype(np.uint16)


def record(cfg, scene, traj_true, traj, truth: Sensor, nominal: Sensor, t, enc, rng) -> dict:
    """One chunk of shots as delivered: the returns georeferenced from the instrument's records
    (measured range, encoder angle) with the nominal sensor and the measured trajectory, with their
    attributes and exact hits (the fields of ``calidar.sim.survey.Strip`` but ``xyz`` and
    ``line``)."""
    pulse, rho, surface, ret, n_ret, hit = shoot(cfg, scene, traj_true, truth, t, enc, rng)
    measured = truth.measured_range(rho + rng.normal(0.0, cfg.range_noise_m, rho.size))
    ecef = georef.forward(traj, nominal, t[pulse], measured, enc[pulse])
    u = nominal.scanner.directions(enc[pulse])
    solid = np.where(surface == SURFACE_TERRAIN, CLASS_GROUND, CLASS_BUILDING)
    cls = np.where(surface == SURFACE_VEGETATION, CLASS_VEGETATION, solid).astype(np.uint8)
    return dict(ecef=ecef, gps_time=t[pulse], range_m=measured, angles=enc[pulse],
                scan_angle_deg=np.degrees(np.arctan2(u[:, 1], u[:, 2])), return_number=ret,
                number_of_returns=n_ret, classification=cls,
                intensity=intensity(surface, rho, cfg.height_agl_m, rng), surface=surface,
                true_enu=hit)
