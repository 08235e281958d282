"""The centroid form's weighted sums (:func:`calidar.strips.centroids._weighted_sums`) against the
sums written out in Python, to the bit: the kernel keeps each row's sums in locals (issue 32,
eleventh session) and must add the same terms in the same order as before, so that the
calibration's results stay identical."""

from __future__ import annotations

import numpy as np

from calidar.strips.centroids import _weighted_sums


def _sums_python(indptr, local, data, rows, position, r_lb, rho, u, with_u):
    """Each output element's sum over the row's entries in entry order, as the kernel always
    added them: w·r, w·R_lb, (w·R_lb·ρ)·u, (w·R_lb)·u."""
    n = indptr.size - 1
    r, R = np.zeros((n, 3)), np.zeros((n, 3, 3))
    M_rho, M_u = np.zeros((n, 3, 3, 3)), np.zeros((n if with_u else 0, 3, 3, 3))
    for i in range(n):
        for k in range(indptr[i], indptr[i + 1]):
            j, w = int(local[k]), float(data[k])
            p = int(rows[j])
            for a in range(3):
                r[i, a] += w * float(position[p, a])
                for b in range(3):
                    wr = w * float(r_lb[p, a, b])
                    R[i, a, b] += wr
                    for c in range(3):
                        M_rho[i, a, b, c] += wr * float(rho[j]) * float(u[j, c])
                        if with_u:
                            M_u[i, a, b, c] += wr * float(u[j, c])
    return r, R, M_rho, M_u


def test_weighted_sums_bit_for_bit():
    """40 rows of 0 to 30 entries (an empty row too), columns repeated and out of order, weights
    of both signs, positions of 10⁵ m: every output equal to the Python sums' bits."""
    rng = np.random.default_rng(32)
    counts = rng.integers(0, 31, 40)
    counts[5] = 0
    indptr = np.r_[0, np.cumsum(counts)]
    local = rng.integers(0, 60, indptr[-1])
    data = rng.normal(0.0, 1.0, indptr[-1]) / 7.0
    rows = rng.permutation(200)[:60]
    position = rng.normal(0.0, 1e5, (200, 3))
    r_lb = rng.normal(0.0, 1.0, (200, 3, 3))
    rho, u = rng.uniform(50.0, 900.0, 60), rng.normal(0.0, 1.0, (60, 3))
    for with_u in (False, True):
        args = (indptr, local, data, rows, position, r_lb, rho, u, with_u)
        for got, want in zip(_weighted_sums(*args), _sums_python(*args)):
            assert got.shape == want.shape
            assert np.array_equal(got, want)
