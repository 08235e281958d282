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
``max_rows`` of them evenly taken (300: ≈ 25 ms a fit). τ = 0 (no correlated part) gives ℓ = 0,
the white formula; ℓ below the points' spacing needs no such rule (R → I there: the sampling
cofactors fall to the white formula's by themselves). ℓ beyond the neighbourhoods' radius is
read long (the points see the unevenness's curvature σ_u²/ℓ⁴ mostly; 5 m on 3 m discs reads
8–16 m), where the rows' Q/ḡ tends to a limit. Measured: docs/validation.md, "ℓ estimated
from the data".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LENGTHS_M = np.geomspace(0.25, 16.0, 13)  #: ℓ's grid, m (2^(1/2) apart)
RATIOS = np.concatenate([[0.0], np.geomspace(1e-3, 1e5, 33)])  #: τ = σ_u²/σ_e²'s grid
HALF_CHI2 = 1.92  #: χ²₁(0.95)/2, the profile likelihood's 95 % range
#: R(d) of the fit: the Gaussian one :mod:`calidar.strips.row_sampling` uses; the exponential
#: (e-folding length ℓ) only to compare the two models' likelihoods on the same rows
KERNELS = {"gaussian": lambda d2, length: np.exp(-d2 / (2.0 * length**2)),
           "exponential": lambda d2, length: np.exp(-np.sqrt(d2) / length)}


@dataclass(frozen=True)
class UnevennessFit:
    """ℓ (m; 0: white), its 95 % range (m), the median row's σ_u and σ_e (m), rows used."""

    length_m: float
    length_range_m: tuple[float, float]
    sigma_u_m: float
    sigma_e_m: float
    rows: int
    loglik: float = 0.0  #: the maximum of log L (the module docstring), to compare models

    def to_dict(self) -> dict:
        return {"length_m": self.length_m, "length_range_m": list(self.length_range_m),
                "sigma_u_m": self.sigma_u_m, "sigma_e_m": self.sigma_e_m, "rows": self.rows}


def residual_basis(xy: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """N (M, k, k − 3), an orthonormal basis of the residuals' space of the planes [1, x, y] at
    b's in-plane positions ``xy`` (M, k, 2) m, and the heights ``z`` (M, k) m in it, v = Nᵀz."""
    X = np.concatenate([np.ones(z.shape + (1,)), xy], axis=2)
    N = np.linalg.qr(X, mode="complete")[0][:, :, 3:]
    return N, (np.swapaxes(N, 1, 2) @ z[:, :, None])[:, :, 0]


def _profile(d2: np.ndarray, N: np.ndarray, v: np.ndarray, length_m: float,
             kernel: str = "gaussian") -> tuple:
    """log L over ``RATIOS`` at ℓ = ``length_m`` (module docstring) for the rows' squared
    in-plane distances ``d2`` (M, k, k) m², and the rows' ŝ (M, T) m²; R from ``KERNELS``."""
    S = np.swapaxes(N, 1, 2) @ KERNELS[kernel](d2, length_m) @ N
    lam, U = np.linalg.eigh(S)
    c = (np.swapaxes(U, 1, 2) @ v[:, :, None])[:, :, 0] ** 2
    scale = 1.0 + RATIOS[None, None, :] * np.maximum(lam, 0.0)[:, :, None]  # (M, n, T)
    s = np.sum(c[:, :, None] / scale, axis=1) / v.shape[1]
    loglik = -0.5 * np.log(scale).sum(axis=1) - 0.5 * v.shape[1] * np.log(np.maximum(s, 1e-300))
    return loglik.sum(axis=0), s


def _rough_rows(b_rows: np.ndarray, centroid: np.ndarray, eigvec: np.ndarray, quantile: float,
                max_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """In-plane positions (R, k, 2) m and heights (R, k) m about their planes of the rows of b's
    scatter above ``quantile``, at most ``max_rows`` of them evenly taken."""
    local = np.einsum("mki,mij->mkj", b_rows - centroid[:, None, :], eigvec)
    scatter = np.sum(local[:, :, 0] ** 2, axis=1)
    rows = np.flatnonzero(scatter > np.quantile(scatter, quantile)) if len(scatter) else scatter
    if rows.size > max_rows:
        rows = rows[np.linspace(0, rows.size - 1, max_rows).round().astype(int)]
    rows = rows.astype(int)
    return local[rows, :, 1:], local[rows, :, 0]


def estimate_length(b_rows: np.ndarray, centroid: np.ndarray, eigvec: np.ndarray,
                    quantile: float = 0.5, max_rows: int = 300,
                    kernel: str = "gaussian") -> UnevennessFit:
    """ℓ (m) and σ_u, σ_e (m) of the surface under b's neighbourhoods ``b_rows`` (M, k, 3) m,
    their planes through ``centroid`` (M, 3) m along ``eigvec`` (M, 3, 3; column 0 the normal):
    the module docstring's profile likelihood over the rows of scatter above ``quantile``, on
    every other node of ``LENGTHS_M`` first, then the two nodes beside the best."""
    xy, z = _rough_rows(b_rows, centroid, eigvec, quantile, max_rows)
    if len(z) < 10:
        return UnevennessFit(0.0, (0.0, 0.0), 0.0, 0.0, len(z))
    N, v = residual_basis(xy, z)
    d2 = np.sum((xy[:, :, None, :] - xy[:, None, :, :]) ** 2, axis=-1)
    fits = {i: _profile(d2, N, v, LENGTHS_M[i], kernel) for i in range(0, len(LENGTHS_M), 2)}
    best = max(fits, key=lambda i: fits[i][0].max())
    for i in (best - 1, best + 1):
        if 0 <= i < len(LENGTHS_M):
            fits[i] = _profile(d2, N, v, LENGTHS_M[i], kernel)
    i = max(fits, key=lambda i: fits[i][0].max())
    j = int(np.argmax(fits[i][0]))
    top = fits[i][0][j]
    inside = [LENGTHS_M[n] for n in fits if fits[n][0].max() >= top - HALF_CHI2]
    tau, s = float(RATIOS[j]), float(np.median(fits[i][1][:, j]))
    span = (float(min(inside)), float(max(inside)))
    return UnevennessFit(0.0 if tau == 0.0 else float(LENGTHS_M[i]), span, float(np.sqrt(tau * s)),
                         float(np.sqrt(s)), len(z), float(top))
