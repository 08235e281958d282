"""The simulated GNSS/INS errors have the σ the simulated smrmsg states: E[e²] = σ² at every epoch.

Found twice on 27 Nov: by `benchmarks/tpu_vs_cblue.py` (issue 31: on 150 m UAV surveys, ≈ 100 s of
trajectory, the points' horizontal errors were 1.8× the TPU's σ in calidar and cBLUE alike) and by
`benchmarks/control_montecarlo.py` (issue 28: height_bias RMS z 1.50). The errors were Gaussian-filtered
white noise scaled to the realisation's std about its own mean, which left the mean on top: with τ = 10 s
over 100 s the RMS came out 1.4–1.5 σ per axis. They are now scaled by the filter's power gain
(``smooth_noise(..., stationary=True)``): each epoch's error has variance σ², the flight-wide mean included
(a real flight's error has one; only ground control sees it).
"""

import numpy as np

from calidar import frames
from calidar.sim.motion import measured_trajectory, smooth_noise
from calidar.trajectory import Trajectory

SIGMA_M, SIGMA_RAD = 0.02, np.radians(0.002)


def _straight(duration_s: float, rate_hz: float = 50.0) -> Trajectory:
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    n = t.size
    return Trajectory(t, np.radians(47.0) + 1e-7 * t, np.full(n, np.radians(8.0)), np.full(n, 530.0),
                      np.zeros(n), np.zeros(n), np.zeros(n))


def test_short_trajectory_errors_have_the_stated_sigma():
    """100 short flights (104 s): RMS of the position and attitude errors over σ, pooled over the flights and
    the three axes, within 0.9–1.1, and each axis within 0.85–1.15 (≈ 4 and 3.5 standard errors: the
    position error holds ≈ 3 independent values per flight and axis). Before the fix: 1.42–1.49 per axis."""
    truth = _straight(104.0)
    r_en = frames.r_en(truth.lat, truth.lon)
    ms_pos, ms_att = [], []
    for seed in range(100):
        meas = measured_trajectory(truth, np.random.default_rng(seed), SIGMA_M, SIGMA_RAD)
        ned = np.einsum("nji,nj->ni", r_en, meas.ecef - truth.ecef)
        ms_pos.append(np.mean(ned ** 2, axis=0))
        att = np.stack([meas.roll - truth.roll, meas.pitch - truth.pitch, meas.heading - truth.heading], 1)
        ms_att.append(np.mean(att ** 2, axis=0))
    for ms, sigma in ((ms_pos, SIGMA_M), (ms_att, SIGMA_RAD)):
        per_axis = np.sqrt(np.mean(ms, axis=0)) / sigma
        assert 0.9 < np.sqrt(np.mean(ms)) / sigma < 1.1, per_axis
        assert np.all((per_axis > 0.85) & (per_axis < 1.15)), per_axis


def test_stationary_noise_has_sigma_at_every_sample():
    """Over 1000 draws each sample's variance is σ² (within 15 %, ≈ 3 standard errors), at the ends as in
    the middle, and each draw keeps its mean (the flight-wide part of the error). The old scaling (to the
    draw's own std about its mean) leaves that mean on top: its RMS exceeds σ."""
    draws = np.stack([smooth_noise(np.random.default_rng(s), 2000, 0.05, 10.0, 2.0, 1, stationary=True)[:, 0]
                      for s in range(1000)])
    var = np.mean(draws ** 2, axis=0)[[0, 500, 1000, 1999]]
    assert np.all(np.abs(var / 4.0 - 1.0) < 0.15), var / 4.0
    assert np.std(draws.mean(axis=1)) > 0.5  # the mean over the record is part of the error, not removed
    old = np.stack([smooth_noise(np.random.default_rng(s), 2000, 0.05, 10.0, 2.0)[:, 0] for s in range(1000)])
    assert np.sqrt(np.mean(old ** 2)) > 1.2 * 2.0


def test_smooth_noise_does_not_wrap_around():
    """The record's last samples are independent of its first (a linear convolution): over 2000 draws
    of a 60 s record with a 10 s kernel, first and last sample correlate |ρ| < 0.1 (the circular
    filter it replaced gave ρ = 0.99999 here), while samples 1 s apart still correlate ρ > 0.9."""
    draws = np.stack([smooth_noise(np.random.default_rng(s), 1200, 0.05, 10.0, 1.0, 1, stationary=True)[:, 0]
                      for s in range(2000)])
    ends = np.corrcoef(draws[:, 0], draws[:, -1])[0, 1]
    near = np.corrcoef(draws[:, 600], draws[:, 620])[0, 1]
    assert abs(ends) < 0.1, ends
    assert near > 0.9, near
