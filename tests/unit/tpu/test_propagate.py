"""Per-point TPU (calidar.tpu.propagate) against a simulated truth and against the lidar equation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import calidar
from calidar.tpu.propagate import (CalibrationCovariance, TpuSettings, point_covariance, surface_normals,
                                   thu_tvu)
from calidar.trajectory_accuracy import TrajectoryAccuracy


@pytest.fixture(scope="module")
def survey():
    """A small UAV survey whose trajectory is nearly exact (0.1 mm, 0.02″): its points' errors are
    the range and encoder noise alone, independent from point to point."""
    cfg = calidar.survey_config("uav", seed=3, density=0.3, directions="cross", gnss_noise_m=1e-4,
                                attitude_noise_rad=1e-7)
    return cfg, calidar.simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=150.0, length_m=150.0)))


def test_sigma_matches_the_actual_errors_by_scan_angle_and_slope(survey):
    """RMS of error/σ per axis within 0.9–1.1 over all points, and 0.85–1.2 in every |scan angle|
    bin and every terrain-slope bin (the slope from the true hits' local planes)."""
    cfg, res = survey
    settings = TpuSettings(cfg.range_noise_m, cfg.angle_noise_rad, beam_divergence_rad=0.0)
    z, scan, slope = [], [], []
    for s in res.strips:
        cov = point_covariance(res.trajectory, res.nominal, res.accuracy, s.gps_time, s.ecef, settings)
        err = res.scene.ecef_to_enu(s.ecef) - s.true_enu
        z.append(err / np.sqrt(np.diagonal(cov, axis1=1, axis2=2)))
        scan.append(np.abs(s.scan_angle_deg))
        slope.append(np.degrees(np.arccos(surface_normals(s.true_enu, 2.0)[:, 2])))
    z, scan, slope = np.concatenate(z), np.concatenate(scan), np.concatenate(slope)
    rms = lambda m: np.sqrt(np.mean(z[m] ** 2, axis=0))  # noqa: E731
    assert np.all((rms(slice(None)) > 0.9) & (rms(slice(None)) < 1.1)), rms(slice(None))
    for lo, hi in [(0, 10), (10, 20), (20, 30), (30, 40)]:
        m = (scan >= lo) & (scan < hi)
        assert m.sum() > 10_000 and np.all((rms(m) > 0.85) & (rms(m) < 1.2)), (lo, hi, rms(m))
    for lo, hi in [(0, 5), (5, 20), (20, 60), (60, 90)]:
        m = (slope >= lo) & (slope < hi)
        assert m.sum() > 1_000 and np.all((rms(m) > 0.85) & (rms(m) < 1.2)), (lo, hi, m.sum(), rms(m))


def _traj_with(traj, **delta):
    return calidar.Trajectory(traj.time, traj.lat, traj.lon, traj.height, traj.roll + delta.get("roll", 0.0),
                              traj.pitch + delta.get("pitch", 0.0), traj.heading + delta.get("heading", 0.0),
                              traj.velocity_ned, traj.time_system)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_attitude_terms_are_the_lidar_equations_derivatives(survey, axis):
    """With σ on one attitude angle only, σ per axis equals |∂p/∂angle|·σ from georeferencing with
    that angle moved (the lidar equation itself, not the propagation's own formula), within 1 %."""
    cfg, res = survey
    s = res.strips[0]
    idx = np.arange(0, len(s), 997)
    t, rng_m, ang = s.gps_time[idx], s.range_m[idx], s.angles[idx]
    sig = np.full(3, 1e-9)
    sig[axis] = np.radians(0.01)
    acc = TrajectoryAccuracy.uniform_ned([1e-9] * 3, sig, "test")
    p = calidar.georeference(res.trajectory, res.nominal, t, rng_m, ang)
    cov = point_covariance(res.trajectory, res.nominal, acc, t, p, TpuSettings(1e-9, 0.0, 0.0))
    h = 1e-6
    name = ("roll", "pitch", "heading")[axis]
    moved = calidar.georeference(_traj_with(res.trajectory, **{name: h}), res.nominal, t, rng_m, ang)
    d = res.scene.ecef_to_enu(moved) - res.scene.ecef_to_enu(p)
    expected = np.abs(d / h) * sig[axis]
    got = np.sqrt(np.diagonal(cov, axis1=1, axis2=2))
    big = expected > 1e-4  # components that matter (> 0.1 mm)
    np.testing.assert_allclose(got[big], expected[big], rtol=0.01)


def test_calibration_covariance_propagates_with_its_correlations(survey):
    """A boresight-roll σ moves nadir points across the track by ρ·σ; two fully anti-correlated
    parameters with equal effect cancel."""
    cfg, res = survey
    s = res.strips[0]
    idx = np.flatnonzero(np.abs(s.scan_angle_deg) < 1.0)[::50]
    acc = TrajectoryAccuracy.uniform(1e-9, 1e-12, "test")
    quiet = TpuSettings(1e-9, 0.0, 0.0)
    sigma = np.radians(0.01)
    cal = CalibrationCovariance(("boresight_roll",), np.array([[sigma ** 2]]), ("rad",))
    cov = point_covariance(res.trajectory, res.nominal, acc, s.gps_time[idx], s.ecef[idx], quiet, cal)
    thu, tvu = thu_tvu(cov)
    np.testing.assert_allclose(thu, s.range_m[idx] * sigma, rtol=0.03)
    assert np.all(tvu < 0.1 * thu)
    both = CalibrationCovariance(("boresight_roll", "boresight_roll"), np.array([[1, -1], [-1, 1]]) * sigma ** 2,
                                 ("rad", "rad"))
    cov = point_covariance(res.trajectory, res.nominal, acc, s.gps_time[idx], s.ecef[idx], quiet, both)
    assert np.all(thu_tvu(cov)[0] < 1e-6)


def test_local_surface_normals_of_a_45_degree_plane():
    """The incidence angle of the footprint term comes from these normals: a 45° plane's, exactly."""
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 20, (4000, 2))
    plane = np.c_[xy, xy[:, 0]]  # z = x: 45°
    normal = surface_normals(plane, 2.0)
    np.testing.assert_allclose(normal, np.tile([-np.sqrt(0.5), 0, np.sqrt(0.5)], (4000, 1)), atol=1e-6)


@pytest.fixture(scope="module")
def diverging():
    """A small UAV survey whose beam diverges by 3 mrad (footprint σ = ρ·γ/4 ≈ 6 cm at 80 m, six
    times the range noise), the trajectory nearly exact: the footprint dominates every error."""
    cfg = calidar.survey_config("uav", seed=4, density=0.3, directions="cross", gnss_noise_m=1e-4,
                                attitude_noise_rad=1e-7, beam_divergence_rad=3e-3)
    return cfg, calidar.simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=150.0, length_m=150.0)))


def test_footprint_sigma_matches_the_errors_by_incidence(diverging):
    """Against the spot each return came from (``true_enu``), RMS of error/σ within 0.85–1.2 in every
    incidence-angle bin: along the beam, on both axes across it, and along the surface's normal
    (where the spot and the nominal beam's hit on the plane agree). Measured from the nominal
    beam's hit instead, the error is along the beam and grows as tan α: not what σ describes."""
    cfg, res = diverging
    settings = TpuSettings(cfg.range_noise_m, cfg.angle_noise_rad, beam_divergence_rad=cfg.beam_divergence_rad)
    z, inc, across_m, rho = [], [], [], []
    for s in res.strips:
        cov = point_covariance(res.trajectory, res.nominal, res.accuracy, s.gps_time, s.ecef, settings)
        _, dir_e = calidar.georef.beams(*calidar.georef.poses(res.trajectory, s.gps_time), res.nominal, s.angles)
        b = dir_e @ res.scene.r_e_enu
        e1 = np.cross(b, [0.0, 0.0, 1.0])
        e1 /= np.linalg.norm(e1, axis=1)[:, None]
        normal = surface_normals(s.true_enu, 2.0)
        err = res.scene.ecef_to_enu(s.ecef) - s.true_enu
        axes = (b, e1, np.cross(b, e1), normal)
        z.append(np.stack([np.einsum("ni,ni->n", err, v) / np.sqrt(np.einsum("ni,nij,nj->n", v, cov, v))
                           for v in axes], 1))
        inc.append(np.degrees(np.arccos(np.abs(np.einsum("ni,ni->n", normal, b)))))
        across_m.append(np.einsum("ni,ni->n", err, e1))
        rho.append(s.range_m)
    z, inc, across_m, rho = map(np.concatenate, (z, inc, across_m, rho))
    # the simulator itself: the spread across the beam is ρ·γ/4 (the Gaussian beam, σ = γ/4 per axis)
    assert 0.95 < np.sqrt(np.mean((across_m / (rho * cfg.beam_divergence_rad / 4)) ** 2)) < 1.05
    for lo, hi in [(0, 15), (15, 30), (30, 45), (45, 60), (60, 85)]:
        m = (inc >= lo) & (inc < hi)
        rms = np.sqrt(np.mean(z[m] ** 2, axis=0))
        assert m.sum() > 2_000 and np.all((rms > 0.85) & (rms < 1.2)), (lo, hi, m.sum(), rms)


def test_divergence_turns_each_beam_by_the_gaussian_profile_and_only_when_asked(monkeypatch):
    """The simulator's ray offsets: unit directions, RMS angle √2·γ/4 (two axes of σ = γ/4); and with
    γ = 0 the divergence (its random draws included) is never reached, so every simulation without
    it stays bit-identical to the single-ray simulator's."""
    from calidar.sim import shots

    d = np.random.default_rng(0).normal(size=(20_000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    turned = shots.diverge(d, 3e-3, np.random.default_rng(1))
    np.testing.assert_allclose(np.linalg.norm(turned, axis=1), 1.0, atol=1e-12)
    angle = np.arccos(np.clip(np.einsum("ni,ni->n", d, turned), -1, 1))
    assert 0.97 < np.sqrt(np.mean(angle ** 2)) / (np.sqrt(2) * 3e-3 / 4) < 1.03

    def refuse(*args):
        raise AssertionError("divergence drawn with γ = 0")

    monkeypatch.setattr(shots, "diverge", refuse)
    cfg = calidar.survey_config("uav", seed=2, density=0.02)
    assert calidar.simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=150.0, length_m=150.0))).n_points
