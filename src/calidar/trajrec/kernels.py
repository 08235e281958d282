"""numba kernels of the fit's hot loops: residuals with their partials per observation, and the
normal equations accumulated row by row (each row touches 4 spline coefficients per channel).
The equations are those of :mod:`calidar.trajrec.geometry` (its numpy forms are the reference;
tests/unit/trajrec/test_geometry.py holds these to them)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_H_POS, _H_ANG = 1e-3, 1e-6  #: central-difference steps, m and rad


@njit(cache=True, nogil=True, inline="always")
def _scan_pair(px, py, pz, st):
    """(across-track angle, along-track angle) of point p from state st (E, N, U, roll, pitch, heading)."""
    de, dn, du = px - st[0], py - st[1], pz - st[2]
    v0, v1, v2 = dn, de, -du
    c, s = math.cos(st[5]), math.sin(st[5])
    v0, v1 = c * v0 + s * v1, -s * v0 + c * v1
    c, s = math.cos(st[4]), math.sin(st[4])
    v0, v2 = c * v0 - s * v2, s * v0 + c * v2
    c, s = math.cos(st[3]), math.sin(st[3])
    v1, v2 = c * v1 + s * v2, -s * v1 + c * v2
    return math.atan2(v1, v2), math.atan2(v0, math.hypot(v1, v2))


@njit(cache=True, nogil=True)
def scan_partials(points, state, scan):  # pragma: no cover - numba
    """Residuals (n, 2) (across − scan angle, along) and partials (n, 2, 6) by central differences."""
    n = points.shape[0]
    r = np.empty((n, 2))
    g = np.empty((n, 2, 6))
    st = np.empty(6)
    for k in range(n):
        for c in range(6):
            st[c] = state[k, c]
        a0, b0 = _scan_pair(points[k, 0], points[k, 1], points[k, 2], st)
        r[k, 0] = a0 - scan[k]
        r[k, 1] = b0
        for c in range(6):
            h = _H_POS if c < 3 else _H_ANG
            st[c] = state[k, c] + h
            a1, b1 = _scan_pair(points[k, 0], points[k, 1], points[k, 2], st)
            st[c] = state[k, c] - h
            a2, b2 = _scan_pair(points[k, 0], points[k, 1], points[k, 2], st)
            st[c] = state[k, c]
            g[k, 0, c] = (a1 - a2) / (2 * h)
            g[k, 1, c] = (b1 - b2) / (2 * h)
    return r, g


@njit(cache=True, nogil=True)
def ray_partials(sensor, last, u1, u2):  # pragma: no cover - numba
    """Residuals (n, 2) of the sensor against each ray and their exact partials (n, 2, 6)."""
    n = sensor.shape[0]
    r = np.empty((n, 2))
    g = np.zeros((n, 2, 6))
    for k in range(n):
        w0, w1, w2 = sensor[k, 0] - last[k, 0], sensor[k, 1] - last[k, 1], sensor[k, 2] - last[k, 2]
        rho = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        e1 = (w0 * u1[k, 0] + w1 * u1[k, 1] + w2 * u1[k, 2]) / rho
        e2 = (w0 * u2[k, 0] + w1 * u2[k, 1] + w2 * u2[k, 2]) / rho
        r[k, 0], r[k, 1] = e1, e2
        for c in range(3):
            wc = (w0, w1, w2)[c] / rho
            g[k, 0, c] = u1[k, c] / rho - e1 * wc / rho
            g[k, 1, c] = u2[k, c] / rho - e2 * wc / rho
    return r, g


@njit(cache=True, nogil=True)
def accumulate(n_mat, rhs, first, w, g, r, weight, k_coef):  # pragma: no cover - numba
    """Upper triangle of n_mat += Σ weight·a aᵀ, and rhs −= Σ weight·a·r, with a = g ⊗ (spline
    weights), row by row over a's nonzero entries (see :func:`symmetrize`)."""
    a = np.empty(24)
    cols = np.empty(24, np.int64)
    for k in range(r.shape[0]):
        wk = weight[k]
        if wk == 0.0:
            continue
        m = 0
        for c in range(6):
            if g[k, c] == 0.0:
                continue
            for j in range(4):
                a[m] = g[k, c] * w[k, j]
                cols[m] = c * k_coef + first[k] + j
                m += 1
        for p in range(m):
            ap = wk * a[p]
            rhs[cols[p]] -= ap * r[k]
            cp = cols[p]
            for q in range(m):
                if cols[q] >= cp:
                    n_mat[cp, cols[q]] += ap * a[q]


def symmetrize(n_mat: np.ndarray) -> np.ndarray:
    """The full normal matrix from the upper triangle :func:`accumulate` fills."""
    return np.triu(n_mat) + np.triu(n_mat, 1).T
