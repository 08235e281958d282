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
_ball_means`). Measured: docs/validation.md, "VGICP's rows on rough ground".
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def _padded(A: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """(M, P) column indices of each row of A (its nonzeros, left-aligned) and their mask."""
    count = np.diff(A.indptr)
    width = int(count.max()) if count.size else 0
    slot = np.arange(width)
    mask = slot[None, :] < count[:, None]
    index = np.zeros(mask.shape, np.int64)
    index[mask] = A.indices
    return index, mask


def _corr(u: np.ndarray, v: np.ndarray, length_m: float) -> np.ndarray:
    """exp(−d²/2ℓ²) between (M, P, 2) and (M, Q, 2) in-plane positions (m): (M, P, Q)."""
    d2 = np.sum((u[:, :, None, :] - v[:, None, :, :]) ** 2, axis=-1)
    return np.exp(-d2 / (2.0 * length_m**2))


def sampling_cofactors(A: sp.csr_matrix, a_points: np.ndarray, b_rows: np.ndarray,
                       centroid: np.ndarray, eigval: np.ndarray, eigvec: np.ndarray,
                       length_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row (M): Q = wᵀRw, g_a and g_b (module docstring; dimensionless) for a's points
    ``a_points`` (m) averaged by the rows of ``A`` (M, len(a_points)) and b's ``b_rows`` (M, k, 3)
    m, b's plane through ``centroid`` (M, 3) m with scatter ``eigval`` (M, 3) m² along ``eigvec``
    (M, 3, 3; column 0 the normal), R's length ``length_m`` (m)."""
    index, mask = _padded(A)
    n_a = mask.sum(axis=1).astype(float)
    k = b_rows.shape[1]
    E, lam = eigvec[:, :, 1:], np.maximum(eigval[:, 1:], 1e-300)  # b's in-plane axes
    ua = np.einsum("mpi,mij->mpj", a_points[index] - centroid[:, None, :], E)
    ua[~mask] = 0.0
    ub = np.einsum("mki,mij->mkj", b_rows - centroid[:, None, :], E)
    wa = mask / n_a[:, None]  # a's mean's weights
    mean_a = np.einsum("mp,mpj->mj", wa, ua)
    pred_a = 1.0 / k + np.einsum("mpj,mkj->mpk", ua / lam[:, None, :], ub)  # b's plane at a's pts
    pred_a[~mask] = 0.0
    pw = 1.0 / k + np.einsum("mj,mkj->mk", mean_a / lam, ub)  # … at a's mean
    hat_b = 1.0 / k + np.einsum("mkj,mlj->mkl", ub / lam[:, None, :], ub)
    Raa, Rab, Rbb = _corr(ua, ua, length_m), _corr(ua, ub, length_m), _corr(ub, ub, length_m)
    Raa *= mask[:, :, None] & mask[:, None, :]
    Rab *= mask[:, :, None]
    q = (np.einsum("mp,mpq,mq->m", wa, Raa, wa) - 2.0 * np.einsum("mp,mpk,mk->m", wa, Rab, pw)
         + np.einsum("mk,mkl,ml->m", pw, Rbb, pw))
    g_b = (k - np.einsum("mkl,mkl->m", hat_b, Rbb)) / (k - 3)
    # a's heights less b's plane there, S = (I, −P) R (I, −P)ᵀ; centred over a: tr S − 1ᵀS1/n_a
    PR = np.einsum("mpk,mkl->mpl", pred_a, Rbb)
    trace = (n_a - 2.0 * np.einsum("mpk,mpk->m", pred_a, Rab)
             + np.einsum("mpl,mpl->m", PR, pred_a))
    s = pred_a.sum(axis=1)  # Pᵀ1
    total = (Raa.sum(axis=(1, 2)) - 2.0 * np.einsum("mk,mk->m", s, Rab.sum(axis=1))
             + np.einsum("mk,mkl,ml->m", s, Rbb, s))
    g_a = (trace - total / n_a) / np.maximum(n_a - 1.0, 1.0)
    return q, g_a, g_b


def unevenness_variance(var_a: np.ndarray, dof_a: np.ndarray, var_b: np.ndarray, dof_b: float,
                        white_part: np.ndarray, cofactors: tuple,
                        quantile: float) -> tuple[np.ndarray, np.ndarray]:
    """The unevenness's share of a row's σ² beyond the white formula (m², may be negative) and
    its degrees of freedom: ρ²·Q/ḡ − (ρ²/s̄²)·``white_part`` (module docstring; with s_a ≈ s_b,
    ρ²·(Q/ḡ − Σw²)). s̄² the two sides' scatter variances (m²) weighted by their degrees of
    freedom ``dof_a``, ``dof_b``, ρ² = max(0, s̄² − s_q²) with s_q² its ``quantile`` over the pair's
    rows (the noise level), ḡ the sides' g likewise weighted; ``white_part`` s_a²/n_a + s_b²·h',
    the white formula's σ², of which the rough fraction ρ²/s̄² is taken out (σ² never below the
    noise level's white formula)."""
    q, g_a, g_b = cofactors
    da, db = np.asarray(dof_a, float), float(dof_b)
    mean = (da * var_a + db * var_b) / (da + db)
    if mean.size == 0:
        return mean, mean.copy()
    rho2 = np.maximum(mean - float(np.quantile(mean, quantile)), 0.0)
    g = np.maximum((da * g_a + db * g_b) / (da + db), 1e-12)
    extra = rho2 * q / g - rho2 / np.maximum(mean, 1e-300) * white_part
    return extra, np.where(rho2 > 0, da + db, np.inf)
