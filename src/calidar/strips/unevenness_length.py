"""The unevenness's correlation length ℓ read from b's neighbourhoods (issue 26, 13th session).

:mod:`calidar.strips.row_sampling` counts a surface's unevenness u (covariance σ_u²·R_ℓ(d),
R_ℓ(d) = exp(−d²/2ℓ²) over the in-plane distance) as a VGICP row's two sides sample it. ℓ is
read here from the points VGICP already holds: b's k points about their fitted plane. With
heights z = u + e (e white, σ_e²) and H the hat matrix of the plane [1, x, y] in b's plane, the
residuals r = (I − H)z have E[r rᵀ] = σ_e²(I − H) + σ_u²(I − H)R_ℓ(I − H) (a plane cancels:
Matheron 1973's authorised increments). In an orthonormal basis N (k × (k − 3)) of the
residuals' space, v = Nᵀz has covariance s·(I + τ·NᵀR_ℓN), s = σ_e², τ = σ_u²/σ_e²: the
restricted (REML) likelihood of the row (Patterson & Thompson 1971). Each row keeps its own
scale s (rough and quiet ground differ by orders of magnitude); profiled out, what is left is the
likelihood of v's direction, the angular central Gaussian (Tyler 1987, Biometrika 74), with no
bias from the per-row scales:

    log L(ℓ, τ) = Σ_rows [−½ Σ_i log(1 + τλ_i) − (n/2)·log Σ_i c_i/(1 + τλ_i)],

λ_i, U the eigenpairs of NᵀR_ℓN, c = (Uᵀv)², n = k − 3. (ℓ, τ) is the maximum over a grid
(ℓ log-spaced, ``LENGTHS_M``; τ log-spaced with 0), its range the ℓ whose profile log L lies
within χ²₁(0.95)/2 = 1.92 of the maximum (Cressie 1993, "Statistics for Spatial Data", §2.6:
likelihood fits of a covariance model; a variogram fit, §2.4, would need the raw heights'
pairs, which the planes' residuals are not). Rows: those of b's scatter above the pair's
``quantile`` (where :func:`calidar.strips.row_sampling.unevenness_variance` acts), at most
``max_rows`` of them evenly taken. τ = 0 (no correlated part) or the fit at the grid's lower end
(ℓ below the points' spacing: unevenness the points sample as white) give ℓ = 0, the white
formula. Measured: docs/validation.md, "ℓ estimated from the data".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LENGTHS_M = np.geomspace(0.25, 16.0, 13)  #: ℓ's grid, m (2^(1/2) apart)
RATIOS = np.concatenate([[0.0], np.geomspace(1e-3, 1e5, 65)])  #: τ = σ_u²/σ_e²'s grid
HALF_CHI2 = 1.92  #: χ²₁(0.95)/2, the profile likelihood's 95 % range


@dataclass(frozen=True)
class UnevennessFit:
    """ℓ (m; 0: white), its 95 % range (m), the median row's σ_u and σ_e (m), rows used."""

    length_m: float
    length_range_m: tuple[float, float]
    sigma_u_m: float
    sigma_e_m: float
    rows: int

    def to_dict(self) -> dict:
        return {"length_m": self.length_m, "length_range_m": list(self.length_range_m),
                "sigma_u_m": self.sigma_u_m, "sigma_e_m": self.sigma_e_m, "rows": self.rows}


def residual_basis(b_rows: np.ndarray, centroid: np.ndarray,
                   eigvec: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """b's points' in-plane positions (M, k, 2) m, N (M, k, k − 3) and v = Nᵀz (M, k − 3)
    m, N an orthonormal basis of the residuals' space, for b's ``b_rows`` (M, k, 3) m about
    their plane through ``centroid`` (M, 3) m along ``eigvec`` (M, 3, 3; column 0 the normal)."""
    local = np.einsum("mki,mij->mkj", b_rows - centroid[:, None, :], eigvec)
    xy, z = local[:, :, 1:], local[:, :, 0]
    X = np.concatenate([np.ones(z.shape + (1,)), xy], axis=2)
    Q = np.linalg.qr(X, mode="complete")[0]
    N = Q[:, :, 3:]
    return xy, N, np.einsum("mki,mk->mi", N, z)


def _profile(xy: np.ndarray, N: np.ndarray, v: np.ndarray, length_m: float) -> tuple:
    """log L over ``RATIOS`` at ℓ = ``length_m`` (module docstring), and the rows' ŝ (M, T)."""
    d2 = np.sum((xy[:, :, None, :] - xy[:, None, :, :]) ** 2, axis=-1)
    S = np.swapaxes(N, 1, 2) @ np.exp(-d2 / (2.0 * length_m**2)) @ N
    lam, U = np.linalg.eigh(S)
    c = (np.swapaxes(U, 1, 2) @ v[:, :, None])[:, :, 0] ** 2
    scale = 1.0 + RATIOS[None, None, :] * np.maximum(lam, 0.0)[:, :, None]  # (M, n, T)
    s = np.sum(c[:, :, None] / scale, axis=1) / v.shape[1]
    loglik = -0.5 * np.log(scale).sum(axis=1) - 0.5 * v.shape[1] * np.log(np.maximum(s, 1e-300))
    return loglik.sum(axis=0), s


def estimate_length(b_rows: np.ndarray, centroid: np.ndarray, eigvec: np.ndarray,
                    quantile: float = 0.5, max_rows: int = 500) -> UnevennessFit:
    """ℓ (m) and σ_u, σ_e (m) of the surface under b's neighbourhoods ``b_rows`` (M, k, 3) m,
    their planes through ``centroid`` (M, 3) m along ``eigvec`` (M, 3, 3; column 0 the normal):
    the module docstring's profile likelihood over the rows of scatter above ``quantile``."""
    xy, N, v = residual_basis(b_rows, centroid, eigvec)
    scatter = np.sum(v**2, axis=1)
    rows = np.flatnonzero(scatter > np.quantile(scatter, quantile)) if len(v) else scatter
    if rows.size > max_rows:
        rows = rows[np.linspace(0, rows.size - 1, max_rows).round().astype(int)]
    if rows.size < 10:
        return UnevennessFit(0.0, (0.0, 0.0), 0.0, 0.0, int(rows.size))
    fits = [_profile(xy[rows], N[rows], v[rows], ell) for ell in LENGTHS_M]
    table = np.array([f[0] for f in fits])  # (L, T)
    i, j = np.unravel_index(np.argmax(table), table.shape)
    s = float(np.median(fits[i][1][:, j]))
    profile = table.max(axis=1)
    inside = LENGTHS_M[profile >= table[i, j] - HALF_CHI2]
    tau = float(RATIOS[j])
    white = tau == 0.0 or i == 0
    return UnevennessFit(0.0 if white else float(LENGTHS_M[i]),
                         (float(inside.min()), float(inside.max())),
                         float(np.sqrt(tau * s)), float(np.sqrt(s)), int(rows.size))
