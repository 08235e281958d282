"""How a VGICP row's two sides sample the surface's unevenness (issue 26, thirteenth session).

A row's residual is a's ball mean minus b's fitted plane at a's mean, along b's normal:
r = Σ_i w_i z_i over the two sides' points, w_i = 1/n_a on a's points and −l_j(x̄_a) on b's (the
plane's prediction weights, Σ l_j = 1). The weights sum to 0 and annihilate a plane (Σ w_i x_i =
0), so a constant or tilted surface cancels, and for heights z = u + e, e white noise of variance
σ_e² and u the surface's unevenness with covariance σ_u²·R(d),

    Var r = σ_e²·Σ w_i² + σ_u²·Q,   Q = wᵀ R w

(the variance of an authorised linear combination: Matheron 1973, "The intrinsic random functions
and their applications", Adv. Appl. Prob. 5),

while each side's scatter about its plane holds the unevenness's non-planar part:
E[s_b²] = σ_e² + σ_u²·g_b, g_b = tr((I − H_b) R_bb)/(k − 3) (H_b b's hat matrix), and a's about
its mean along b's normal E[s_a²] = σ_e²·(1 + t) + σ_u²·g_a, g_a = tr(C M R Mᵀ C)/(n_a − 1)
(M: a's heights minus b's plane there, C: centring over a; t: b's tilt,
:mod:`calidar.strips.vgicp_planes`). The white-noise formula σ² = s_a²/n_a + s_b²·h takes
the unevenness as white (R = I: Q = Σ w², g = 1). When the unevenness is correlated over the
points' spacing it is wrong both ways: two sides spread over the same disc average a smooth bump
alike and cancel it (Q/g < Σ w²: airborne rows, 5 m neighbourhoods on 4 m facets), while a's
points along one scan line sample it at one place (Q/g > Σ w²: UAV rows, a's ball a line
across b's disc).

So a row's unevenness σ_u² = ρ²/ḡ is read from its scatter beyond the pair's noise level, ρ²
(ḡ the two sides' g weighted by their degrees of freedom), and enters the row's σ² as
ρ²·(Q/ḡ − Σw²) on top of the white formula: the unevenness re-counted as the two sides' sampling
of it makes it count. R(d) = exp(−d²/2ℓ²) over the in-plane distance, ℓ =
``unevenness_length_m``. a's ball is an equal-weight mean (:func:`calidar.strips.vgicp_planes.
_ball_means`). Measured: docs/validation.md, "VGICP's rows on rough ground"; the numba kernel:
"ℓ pooled over the survey".
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit


@njit(cache=True, nogil=True)
def _row_cofactors(indptr, indices, a_points, b_rows, centroid, eigval, eigvec,
                   length_m, rows):  # pragma: no cover - numba
    """Q, g_a, g_b of :func:`sampling_cofactors` at the ``rows``, row by row (no (M, P, Q)
    temporaries)."""
    k = b_rows.shape[1]
    q, g_a, g_b = np.empty(rows.size), np.empty(rows.size), np.empty(rows.size)
    inv2l2 = 1.0 / (2.0 * length_m * length_m)
    ub = np.empty((k, 2))
    pw = np.empty(k)
    Rbb = np.empty((k, k))
    for out in range(rows.size):
        m = rows[out]
        n = indptr[m + 1] - indptr[m]
        na = float(n)
        lam0, lam1 = max(eigval[m, 1], 1e-300), max(eigval[m, 2], 1e-300)
        for i in range(k):  # b's points in b's plane (axes 1, 2 of eigvec)
            d0, d1, d2 = (b_rows[m, i, 0] - centroid[m, 0], b_rows[m, i, 1] - centroid[m, 1],
                          b_rows[m, i, 2] - centroid[m, 2])
            ub[i, 0] = d0 * eigvec[m, 0, 1] + d1 * eigvec[m, 1, 1] + d2 * eigvec[m, 2, 1]
            ub[i, 1] = d0 * eigvec[m, 0, 2] + d1 * eigvec[m, 1, 2] + d2 * eigvec[m, 2, 2]
        ua = np.empty((n, 2))
        mean0 = mean1 = 0.0
        for p in range(n):
            j = indices[indptr[m] + p]
            d0, d1, d2 = (a_points[j, 0] - centroid[m, 0], a_points[j, 1] - centroid[m, 1],
                          a_points[j, 2] - centroid[m, 2])
            ua[p, 0] = d0 * eigvec[m, 0, 1] + d1 * eigvec[m, 1, 1] + d2 * eigvec[m, 2, 1]
            ua[p, 1] = d0 * eigvec[m, 0, 2] + d1 * eigvec[m, 1, 2] + d2 * eigvec[m, 2, 2]
            mean0 += ua[p, 0] / na
            mean1 += ua[p, 1] / na
        hat_r = 0.0  # Σ hat_b ∘ Rbb
        for i in range(k):
            pw[i] = 1.0 / k + mean0 / lam0 * ub[i, 0] + mean1 / lam1 * ub[i, 1]
            for l in range(k):
                e0, e1 = ub[i, 0] - ub[l, 0], ub[i, 1] - ub[l, 1]
                Rbb[i, l] = np.exp(-(e0 * e0 + e1 * e1) * inv2l2)
                hat = 1.0 / k + ub[i, 0] * ub[l, 0] / lam0 + ub[i, 1] * ub[l, 1] / lam1
                hat_r += hat * Rbb[i, l]
        pwRpw = 0.0
        for i in range(k):
            for l in range(k):
                pwRpw += pw[i] * Rbb[i, l] * pw[l]
        raa = 0.0  # Σ Raa
        for p in range(n):
            for r in range(n):
                e0, e1 = ua[p, 0] - ua[r, 0], ua[p, 1] - ua[r, 1]
                raa += np.exp(-(e0 * e0 + e1 * e1) * inv2l2)
        pred = np.empty(k)
        s = np.zeros(k)  # Pᵀ1
        rab_pw = rab_pred = pred_r_pred = 0.0
        col = np.zeros(k)  # Σ_p Rab[p, :]
        for p in range(n):
            for i in range(k):
                pred[i] = 1.0 / k + ua[p, 0] / lam0 * ub[i, 0] + ua[p, 1] / lam1 * ub[i, 1]
                s[i] += pred[i]
                e0, e1 = ua[p, 0] - ub[i, 0], ua[p, 1] - ub[i, 1]
                rab = np.exp(-(e0 * e0 + e1 * e1) * inv2l2)
                col[i] += rab
                rab_pw += rab * pw[i]
                rab_pred += pred[i] * rab
            for i in range(k):
                for l in range(k):
                    pred_r_pred += pred[i] * Rbb[i, l] * pred[l]
        sRs = scol = 0.0
        for i in range(k):
            scol += s[i] * col[i]
            for l in range(k):
                sRs += s[i] * Rbb[i, l] * s[l]
        q[out] = raa / (na * na) - 2.0 * rab_pw / na + pwRpw
        g_b[out] = (k - hat_r) / (k - 3)
        trace = na - 2.0 * rab_pred + pred_r_pred
        g_a[out] = (trace - (raa - 2.0 * scol + sRs) / na) / max(na - 1.0, 1.0)
    return q, g_a, g_b


def sampling_cofactors(A: sp.csr_matrix, a_points: np.ndarray, b_rows: np.ndarray,
                       centroid: np.ndarray, eigval: np.ndarray, eigvec: np.ndarray,
                       length_m: float, rows: np.ndarray | None = None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row (M; ``rows``: those row indices only): Q = wᵀRw, g_a and g_b (module docstring;
    dimensionless) for a's points
    ``a_points`` (m) averaged by the rows of ``A`` (M, len(a_points)) and b's ``b_rows`` (M, k, 3)
    m, b's plane through ``centroid`` (M, 3) m with scatter ``eigval`` (M, 3) m² along ``eigvec``
    (M, 3, 3; column 0 the normal), R's length ``length_m`` (m): a numba kernel, row by row (a's
    ball an equal-weight mean of A's nonzeros)."""
    A = sp.csr_matrix(A)
    f = np.ascontiguousarray
    rows = np.arange(A.shape[0]) if rows is None else rows
    return _row_cofactors(f(A.indptr, np.int64), f(A.indices, np.int64), f(a_points, float),
                          f(b_rows, float), f(centroid, float), f(eigval, float), f(eigvec, float),
                          float(length_m), f(rows, np.int64))


def unevenness_variance(var_a: np.ndarray, dof_a: np.ndarray, var_b: np.ndarray, dof_b: float,
                        white_part: np.ndarray, cofactors,
                        quantile: float) -> tuple[np.ndarray, np.ndarray]:
    """The unevenness's share of a row's σ² beyond the white formula (m², may be negative) and
    its degrees of freedom: ρ²·Q/ḡ − (ρ²/s̄²)·``white_part`` (module docstring; with s_a ≈ s_b,
    ρ²·(Q/ḡ − Σw²)). s̄² the two sides' scatter variances (m²) weighted by their degrees of
    freedom ``dof_a``, ``dof_b``, ρ² = max(0, s̄² − s_q²) with s_q² its ``quantile`` over the pair's
    rows (the noise level), ḡ the sides' g likewise weighted; ``white_part`` s_a²/n_a + s_b²·h',
    the white formula's σ², of which the rough fraction ρ²/s̄² is taken out (σ² never below the
    noise level's white formula). ``cofactors``: the rows' indices → their (Q, g_a, g_b)
    (:func:`sampling_cofactors`), asked only of the rows with ρ² > 0 (the others' share is 0)."""
    da, db = np.broadcast_to(np.asarray(dof_a, float), var_a.shape), float(dof_b)
    mean = (da * var_a + db * var_b) / (da + db)
    if mean.size == 0:
        return mean, mean.copy()
    rho2 = np.maximum(mean - float(np.quantile(mean, quantile)), 0.0)
    rough = np.flatnonzero(rho2 > 0)
    extra = np.zeros(mean.size)
    if rough.size:
        q, g_a, g_b = cofactors(rough)
        g = np.maximum((da[rough] * g_a + db * g_b) / (da[rough] + db), 1e-12)
        extra[rough] = (rho2[rough] * q / g
                        - rho2[rough] / np.maximum(mean[rough], 1e-300) * white_part[rough])
    return extra, np.where(rho2 > 0, da + db, np.inf)
