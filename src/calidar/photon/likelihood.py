"""Cramér–Rao bound of the CCR calibration: Fisher information of the photon counts recorded by each shot.

Model of one shot (distances m): the CCR at (x_c, y_c) in track coordinates sits at r from
the true footprint centre (x_shot + b_a + e_x, b_c + e_y), e ~ N(0, σ_j²) on each axis the
shot's pointing jitter. The footprint energy is Gaussian, so the mean number of CCR photons
is λ = Λ·exp(−2r²/w²) (Λ at the centre, w the 1/e² radius, set by the 50 %-detection
diameter D through Λ·exp(−2(D/2)²/w²) = ln 2). The return arrives within the dead time, so
each of the N detector channels records at most one photon: k ~ Binomial(N, π),
π = 1 − e^(−λ/N). A fraction q of shots lose their CCR return (k = 0):

    P(k) = q·[k = 0] + (1 − q)·E_e[Binomial(k; N, π(e))],

the expectation over the jitter by Gauss–Hermite quadrature. The Fisher information
Σ_shots Σ_k ∂P_k ∂P_kᵀ / P_k bounds the covariance of any unbiased estimate from below
(Cramér–Rao): it tells how well the data of a pass can fix the bias and the diameter at all.
"""

from __future__ import annotations

import numpy as np
from scipy.special import gammaln, logsumexp

#: Unknowns, in this order (m, m, m, photons, fraction).
NAMES = ("along_track_bias", "cross_track_bias", "footprint_diameter", "ccr_peak_photons", "shot_loss_rate")
QUADRATURE_POINTS = 5  #: Gauss–Hermite nodes per jitter axis


def footprint_radius_1e2(diameter: float, peak_photons: float) -> float:
    """1/e² radius w (m) of a Gaussian footprint whose 50 %-detection diameter for a CCR
    returning ``peak_photons`` (mean, at the centre) is ``diameter``: Λ·exp(−2(D/2)²/w²) = ln 2."""
    return 0.5 * diameter * np.sqrt(2.0 / np.log(max(peak_photons, 1.01) / np.log(2.0)))


def count_probabilities(x_shot: np.ndarray, x_ccr: np.ndarray, y_ccr: np.ndarray, v: dict, channels: int,
                        jitter: float) -> np.ndarray:
    """P(k) for k = 0 … N of every shot, (n_shots, N + 1); shot and CCR positions in m
    (reported along-track x, CCR track x, y), ``v`` the NAMES, jitter σ_j in m."""
    n = QUADRATURE_POINTS if jitter > 0 else 1
    z, wz = np.polynomial.hermite_e.hermegauss(n)  # nodes of the standard normal
    ex, ey = (a.ravel() for a in np.meshgrid(jitter * z, jitter * z, indexing="ij"))
    logw = np.log(np.outer(wz, wz).ravel() / wz.sum() ** 2)
    w = footprint_radius_1e2(v["footprint_diameter"], v["ccr_peak_photons"])
    dx = (x_shot + v["along_track_bias"] - x_ccr)[:, None] + ex
    dy = (v["cross_track_bias"] - y_ccr)[:, None] + ey
    u = v["ccr_peak_photons"] * np.exp(-2.0 * (dx * dx + dy * dy) / w**2) / channels  # λ/N, (shots, nodes)
    log_pi = np.log(np.clip(-np.expm1(-u), 1e-300, None))
    k = np.arange(channels + 1.0)[None, :, None]
    log_c = gammaln(channels + 1.0) - gammaln(k + 1.0) - gammaln(channels - k + 1.0)
    log_b = log_c + k * log_pi[:, None, :] - (channels - k) * u[:, None, :]
    mix = np.exp(logsumexp(log_b + logw, axis=2))
    q = v["shot_loss_rate"]
    return (1.0 - q) * mix + q * (np.arange(channels + 1) == 0)


def fisher_information(x_shot, x_ccr, y_ccr, v: dict, channels: int, jitter: float) -> np.ndarray:
    """Expected Fisher information (5 × 5, order NAMES) of the shots' counts at ``v``;
    derivatives by central differences."""
    steps = {"along_track_bias": 1e-3, "cross_track_bias": 1e-3, "footprint_diameter": 1e-3,
             "ccr_peak_photons": 1e-3 * v["ccr_peak_photons"], "shot_loss_rate": 1e-4}
    p0 = count_probabilities(x_shot, x_ccr, y_ccr, v, channels, jitter)
    grads = []
    for name in NAMES:
        hi, lo = dict(v), dict(v)
        hi[name] += steps[name]
        lo[name] -= steps[name]
        grads.append((count_probabilities(x_shot, x_ccr, y_ccr, hi, channels, jitter)
                      - count_probabilities(x_shot, x_ccr, y_ccr, lo, channels, jitter)) / (2.0 * steps[name]))
    g = np.stack(grads)
    return np.einsum("isk,jsk->ij", g, g / np.clip(p0, 1e-300, None)[None])


def cramer_rao_sigma(x_shot, x_ccr, y_ccr, v: dict, channels: int, jitter: float) -> dict[str, float]:
    """Smallest σ (Cramér–Rao bound) any unbiased estimate of each of NAMES can have."""
    cov = np.linalg.pinv(fisher_information(x_shot, x_ccr, y_ccr, v, channels, jitter))
    return dict(zip(NAMES, np.sqrt(np.clip(np.diag(cov), 0.0, None)).tolist()))
