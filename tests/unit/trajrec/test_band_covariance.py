"""The σ of a segment's fit from the band of N⁻¹ alone (Takahashi's recurrence on the banded Cholesky factor)
equal what the whole inverse gives, mounting's low-rank part included."""

from __future__ import annotations

import numpy as np

from calidar.trajrec.banded import band_covariance, interleaved


def _banded_spd(k: int, rng) -> np.ndarray:
    """A normal matrix shaped as the fit's: rows touching 4 consecutive coefficients of each of 6 channels."""
    n = np.zeros((6 * k, 6 * k))
    for first in rng.integers(0, k - 3, 40 * k):
        cols = (np.arange(6)[:, None] * k + first + np.arange(4)).ravel()
        a = rng.normal(size=cols.size)
        n[np.ix_(cols, cols)] += np.outer(a, a)
    return n + 1e-3 * np.eye(6 * k)


def test_band_of_the_inverse_equals_the_whole_inverse_there():
    rng = np.random.default_rng(0)
    k = 30
    n = _banded_spd(k, rng)
    low = rng.normal(size=(6 * k, 3)) * 0.1  # interleaved rows, as the fit's
    cov = band_covariance(n, low, k, 2.0)
    full = np.linalg.inv(n)[np.ix_(interleaved(k), interleaved(k))] + low @ low.T  # interleaved order
    for c in range(6):
        want = 2.0 * full[c::6, c::6]
        for d in range(4):
            np.testing.assert_allclose(np.diagonal(cov[c], d), np.diagonal(want, d), rtol=1e-8, atol=1e-12)
            np.testing.assert_allclose(np.diagonal(cov[c], -d), np.diagonal(want, -d), rtol=1e-8, atol=1e-12)
