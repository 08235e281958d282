"""Scan angles stored in coarse steps (LAS 1.0–1.3: whole degrees): the step, and the covariance of
a segment's fit when points sharing a stored value share its rounding error (see
:mod:`calidar.trajrec.fit`)."""

from __future__ import annotations

import numpy as np

from calidar.trajrec import mounting
from calidar.trajrec.kernels import accumulate, one_blas_thread, symmetrize

#: a scan-angle field stored in steps at least this coarse (rad) is quantised (LAS 1.0–1.3: whole
#: degrees); LAS 1.4's 0.006° steps are not
QUANTUM_MIN = np.radians(0.05)


def scan_quantum(scan: np.ndarray) -> float:
    """The step (rad) of a quantised scan-angle field: every value a multiple of it, at least
    QUANTUM_MIN; 0.0 when the field is finer (or has fewer than two values)."""
    v = np.unique(scan[np.isfinite(scan)])
    if v.size < 2:
        return 0.0
    step = float(np.min(np.diff(v)))
    k = (v - v[0]) / step
    return step if step >= QUANTUM_MIN and np.all(np.abs(k - np.round(k)) < 1e-3) else 0.0


def clustered_covariance(across, wr: np.ndarray, scan: np.ndarray, quantum: float,
                         n_full: np.ndarray, k: int) -> np.ndarray:
    """(6, K, K) channel blocks of N⁻¹ + N⁻¹·(M − N_a)·N⁻¹, the scan-angle residuals' information
    N_a replaced by that of errors with a part shared by every point of one stored value (a random
    effect, the survey statistician's design effect, Kish 1965): M = (1 − ρ)·N_a + ρ·σ²·Σ_c a_c
    a_cᵀ, a_c the sum of value c's weighted partials, ρ the share of the residuals' variance
    between the values' means (0 when each value's points scatter over its whole quantum, → 1 for
    a scanner firing the same angles every sweep).

    ``across``: the fit's across-track type (name, basis, residuals, partials, relative σ,
    partials by the mounting parameters), ``wr`` its weights, ``scan`` its stored angles;
    ``n_full``: the normal matrix (6K + m)² with its mounting border
    (:mod:`calidar.trajrec.mounting`)."""
    _, basis, r, g, _, gm = across
    m = gm.shape[1]
    first, bw = basis
    labels = np.unique(np.round(scan / quantum), return_inverse=True)[1].ravel()
    n_groups = int(labels.max()) + 1 if labels.size else 0
    if n_groups < 2:
        return np.full((6, k, k), np.inf)
    size = np.bincount(labels, minlength=n_groups)
    mean = np.bincount(labels, weights=r, minlength=n_groups) / np.maximum(size, 1)
    # at least a uniform rounding error's variance: the fit absorbs part of the shared errors
    total = max(float(np.mean((r - r.mean()) ** 2)), quantum**2 / 12.0)
    within = float(np.mean((r - mean[labels]) ** 2))
    rho = float(np.clip(1.0 - within / total, 0.0, 1.0))
    a = np.zeros((n_groups, 6 * k + m))
    for c in range(6):
        for j in range(4):
            np.add.at(a, (labels, c * k + first + j), bw[:, j] * g[:, c] * wr)
    for p in range(m):
        a[:, 6 * k + p] = np.bincount(labels, weights=gm[:, p] * wr, minlength=n_groups)
    n_a, rhs = np.zeros((6 * k + m, 6 * k + m)), np.zeros(6 * k)
    inner = np.zeros((6 * k, 6 * k))
    accumulate(inner, rhs, first, bw, np.ascontiguousarray(g), r, wr, k)
    n_a[:6 * k, :6 * k] = symmetrize(inner)
    if m:
        b, c_m, _ = mounting.border(basis, g, gm, wr, k)
        n_a[:6 * k, 6 * k:], n_a[6 * k:, :6 * k], n_a[6 * k:, 6 * k:] = b, b.T, c_m
    meat = (1.0 - rho) * n_a + rho * total * (a.T @ a)
    with one_blas_thread():
        n_inv = np.linalg.inv(n_full)
        cov = n_inv + n_inv @ (meat - n_a) @ n_inv
    return np.stack([cov[c * k:(c + 1) * k, c * k:(c + 1) * k] for c in range(6)])


def widest(model: np.ndarray, robust: np.ndarray) -> np.ndarray:
    """Per channel the block of the two (6, K, K) covariances whose variances sum to more."""
    wider = np.trace(robust, axis1=1, axis2=2) > np.trace(model, axis1=1, axis2=2)
    return np.where(wider[:, None, None], robust, model)
