"""A segment's normal matrix in banded storage: with the unknowns interleaved (coefficient j,
channel c → 6j + c) a row touches 4 consecutive coefficients of each channel, so N is banded
(half-bandwidth 23) and solved, and its inverse's band found, in O(n)
(:mod:`calidar.trajrec.fit`)."""

from __future__ import annotations

import numpy as np

from calidar.trajrec.kernels import band_of_inverse, one_blas_thread

#: half-bandwidth of the interleaved normal matrix: 4 coefficients × 6 channels − 1
HALF_BANDWIDTH = 23


def interleaved(k: int) -> np.ndarray:
    """Interleaved position (coefficient j, channel c → 6j + c) → channel-major index (c·K + j)."""
    return (np.arange(6 * k) % 6) * k + np.arange(6 * k) // 6


def band(n_mat: np.ndarray, k: int) -> np.ndarray:
    """N in upper banded storage with its unknowns interleaved (see the module docstring), gathered
    diagonal by diagonal, without reordering the whole matrix."""
    cm, u, n = interleaved(k), HALF_BANDWIDTH, 6 * k
    ab = np.zeros((u + 1, n))
    for d in range(u + 1):
        ab[u - d, d:] = n_mat[cm[:n - d], cm[d:]]
    return ab


def banded_solve(n_mat: np.ndarray, rhs: np.ndarray, k: int) -> np.ndarray:
    """N⁻¹·rhs (rhs (6K,) or (6K, m) in channel-major order, the answer in that order) by a banded
    Cholesky (:func:`band`)."""
    from scipy.linalg import solveh_banded

    cm = interleaved(k)
    x = np.empty_like(rhs)
    x[cm] = solveh_banded(band(n_mat, k), rhs[cm], check_finite=False)
    return x


def band_covariance(n_mat: np.ndarray, low: np.ndarray | None, k: int, f: float) -> np.ndarray:
    """(6, K, K) channel blocks of f·(N⁻¹ + L·Lᵀ) where a channel's coefficients are at most 3
    apart (all that :func:`calidar.trajrec.fit.channel_sigma` and the traces of quantised.widest
    use; 0 elsewhere), from N's band alone."""
    from scipy.linalg import cholesky_banded

    u = HALF_BANDWIDTH
    with one_blas_thread():
        z = band_of_inverse(cholesky_banded(band(n_mat, k), check_finite=False))
    cov = np.zeros((6, k, k))
    j = np.arange(k)
    for c in range(6):
        for d in range(4):
            a, b = 6 * j[:k - d] + c, 6 * j[d:] + c  # interleaved rows and columns, 6·d apart
            v = z[u - 6 * d, b]
            if low is not None:
                v = v + np.einsum("ij,ij->i", low[a], low[b])
            cov[c, j[:k - d], j[d:]] = cov[c, j[d:], j[:k - d]] = f * v
    return cov
