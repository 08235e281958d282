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
``max_rows`` of them evenly taken (300: ≈ 25 ms a fit). A survey's ℓ pools its pairs: the sum
of their log L over ℓ, each pair's τ profiled out (:func:`pooled_fit`). τ = 0 (no correlated
part) gives ℓ = 0, the white formula; ℓ below the points' spacing needs no such rule (R → I
there: the sampling cofactors fall to the white formula's by themselves). ℓ beyond the
neighbourhoods' radius is read long (the points see the unevenness's curvature σ_u²/ℓ⁴ mostly;
5 m on 3 m discs reads 8–16 m), where the rows' Q/ḡ tends to a limit. Measured:
docs/validation.md, "ℓ estimated from the data" and "ℓ pooled over the survey".
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

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
    #: the log L surface it was read from (:class:`Surface`; one pair's, for :func:`pooled_fit`)
    surface: Surface | None = field(default=None, compare=False, repr=False)

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


@dataclass(frozen=True)
class Surface:
    """One pair's log L over ``LENGTHS_M`` (module docstring), each node's τ profiled out: the
    maximum over ``RATIOS`` (L,), its τ's index (L,), the rows' median ŝ there (L,) m², log L at
    τ = 0 (white: the same at every ℓ) and the rows used."""

    profile: np.ndarray
    ratio: np.ndarray
    scale: np.ndarray
    white: float
    rows: int


def pair_surface(b_rows: np.ndarray, centroid: np.ndarray, eigvec: np.ndarray,
                 quantile: float = 0.5, max_rows: int = 300,
                 kernel: str = "gaussian") -> Surface | None:
    """log L over the whole grid of b's neighbourhoods ``b_rows`` (M, k, 3) m, their planes through
    ``centroid`` (M, 3) m along ``eigvec`` (M, 3, 3; column 0 the normal), the rows of scatter
    above ``quantile`` (module docstring); None with fewer than 10 such rows."""
    xy, z = _rough_rows(b_rows, centroid, eigvec, quantile, max_rows)
    if len(z) < 10:
        return None
    N, v = residual_basis(xy, z)
    d2 = np.sum((xy[:, :, None, :] - xy[:, None, :, :]) ** 2, axis=-1)
    fits = [_profile(d2, N, v, length, kernel) for length in LENGTHS_M]
    best = np.array([int(np.argmax(loglik)) for loglik, _ in fits])
    return Surface(np.array([loglik[j] for (loglik, _), j in zip(fits, best)]), best,
                   np.array([float(np.median(s[:, j])) for (_, s), j in zip(fits, best)]),
                   float(fits[0][0][0]), len(z))


def pooled_fit(surfaces: list[Surface | None]) -> UnevennessFit:
    """ℓ (m) of several pairs' rows at once: the maximum of the sum of their log L over ℓ (τ per
    pair, profiled out); ℓ = 0 (white) when no pair's rows are better with a correlated part; the
    95 % range where the sum lies within ``HALF_CHI2`` of it; σ_u, σ_e the pairs' medians at that
    ℓ. One pair: its own fit."""
    surfaces = [s for s in surfaces if s is not None]
    if not surfaces:
        return UnevennessFit(0.0, (0.0, 0.0), 0.0, 0.0, 0)
    total = np.sum([s.profile for s in surfaces], axis=0)
    i = int(np.argmax(total))
    inside = LENGTHS_M[total >= total[i] - HALF_CHI2]
    tau = np.array([RATIOS[s.ratio[i]] for s in surfaces])
    scale = np.array([s.scale[i] for s in surfaces])
    white = total[i] <= sum(s.white for s in surfaces)
    return UnevennessFit(0.0 if white else float(LENGTHS_M[i]),
                         (float(inside.min()), float(inside.max())),
                         float(np.median(np.sqrt(tau * scale))), float(np.median(np.sqrt(scale))),
                         sum(s.rows for s in surfaces), float(total[i]))


def estimate_length(b_rows: np.ndarray, centroid: np.ndarray, eigvec: np.ndarray,
                    quantile: float = 0.5, max_rows: int = 300,
                    kernel: str = "gaussian") -> UnevennessFit:
    """ℓ (m) and σ_u, σ_e (m) of one set of b's neighbourhoods (:func:`pair_surface`'s
    arguments): :func:`pooled_fit` of its one surface."""
    surface = pair_surface(b_rows, centroid, eigvec, quantile, max_rows, kernel)
    return replace(pooled_fit([surface]), surface=surface)
