"""The covariance of a robust (M-) estimate: Huber's sandwich A⁻¹BA⁻¹ (issue 26).

The engine's IRLS solves Σ w(u_i) r_i J_i/σ_i² + P(θ − c) = 0 with u_i = r_i/(σ_i s) (s the
residuals' MAD scale) and w = ψ(u)/u. Its normal matrix N = Σ w_i J_iJ_iᵀ/σ_i² + P takes a row of
weight w to vary as σ²/w; the estimate's actual covariance (Huber 1981, *Robust Statistics*, §7.6:
the third of its three estimates of the regression M-estimate's covariance,
K⁻¹ · [s²Σψ²/(n − p)] · W⁻¹(XᵀX)W⁻¹ with W = Σψ'(u_i) x_i x_iᵀ and
K = 1 + (p/n)·var(ψ')/mean(ψ')²) is the sandwich

    A⁻¹ B A⁻¹,   A = Σ ψ'(u_i) J_iJ_iᵀ/σ_i² + P,   B = c_ψ Σ J_iJ_iᵀ/σ_i² + P,

with the rows' part of B times a variance factor f and the priors' times max(f, 1): c_ψ =
E[s²ψ(z/s)²] for z ~ N(0, 1) is what a row's score varies by when its σ is right, and the level
q = (s²Σψ_i² / (c_ψ K) + Σ prior terms) / redundancy the data's own against it (Huber's
s²Σψ²/(n − p), with the priors' terms and the redundancy of the engine's σ0²; q ≈ 1 for rows with
their stated σ, < 1 for rows right in the mean but heavy-tailed, which the M-estimate weighs
down). f: :func:`variance_factor`. For least squares (ψ(u) = u, ψ' = 1, c_ψ = 1, K = 1) A = B = N
and q = σ0²: the sandwich is max(σ0², 1)·N⁻¹ (σ0²·N⁻¹ where σ are relative), the IRLS covariance,
exactly.
"""

from __future__ import annotations

import numpy as np

from calidar.adjust.solution import cholesky_inverse, unit_diagonal

#: the engine's covariance models (:attr:`calidar.adjust.residuals.SolverOptions.covariance`)
COVARIANCE_MODELS = ("irls", "sandwich")
#: the robust losses' tuning constants k (95 % efficiency at normal residuals)
ROBUST_K = {"huber": 1.345, "cauchy": 2.385}


def robust_weights(u: np.ndarray, kind: str | None, k: float | None = None) -> np.ndarray:
    """IRLS weights w = ψ(u)/u for standardised residuals u (Huber or Cauchy; None → ones)."""
    if kind is None:
        return np.ones_like(u)
    k = ROBUST_K[kind] if k is None else k
    a = np.abs(u)
    if kind == "huber":
        return np.where(a <= k, 1.0, k / np.maximum(a, 1e-300))
    if kind == "cauchy":
        return 1.0 / (1.0 + (a / k) ** 2)
    raise ValueError(f"robust must be 'huber', 'cauchy' or None, got {kind!r}")


def psi(u: np.ndarray, kind: str | None, k: float) -> tuple[np.ndarray, np.ndarray]:
    """(ψ(u), ψ'(u)) of the robust loss: ψ = u·w(u) of :func:`robust_weights` (None: least
    squares, ψ = u, ψ' = 1)."""
    u = np.asarray(u, float)
    psi_u = u * robust_weights(u, kind, k)
    if kind is None:
        return psi_u, np.ones_like(u)
    if kind == "huber":
        return psi_u, (np.abs(u) <= k).astype(float)
    t = (u / k) ** 2  # Cauchy (robust_weights refused any other kind)
    return psi_u, (1.0 - t) / (1.0 + t) ** 2


def normal_psi_square(kind: str | None, k: float, s: float) -> float:
    """c_ψ = E[s²ψ(z/s)²] for z ~ N(0, 1): the variance of a row's score when its σ is right and
    the weights use the scale s (1 for least squares)."""
    if kind is None:
        return 1.0
    from scipy import integrate  # here, not at import: 0.14 s that only the sandwich needs

    def integrand(z: float) -> float:
        return float(s * s * psi(np.array(z / s), kind, k)[0] ** 2
                     * np.exp(-0.5 * z * z) / np.sqrt(2 * np.pi))

    kink = [-k * s, k * s] if kind == "huber" else None
    return float(integrate.quad(integrand, -12.0, 12.0, points=kink, limit=200)[0])


def small_sample_factor(dpsi: np.ndarray, p: int, n: float) -> float:
    """Huber's K = 1 + (p/n)·var(ψ')/mean(ψ')² (1 for least squares)."""
    m = float(np.mean(dpsi)) if dpsi.size else 1.0
    if n <= 0 or m <= 0:
        return 1.0
    return 1.0 + (p / n) * float(np.var(dpsi)) / (m * m)


def variance_factor(level: float, rms_sq: float, relative: bool) -> float:
    """f, the rows' variance factor of the sandwich: the ψ's ``level`` q where σ are relative;
    where they are absolute (or priors hold parameters) q·max(1, 1/σ0²) with σ0 the rows' RMS
    reading ``rms_sq`` (the skipped σ0 of the global test; q for least squares), so that rows
    whose residuals come out below their σ never narrow the σ (the engine's max(σ0², 1)), while
    heavy tails, which make q < 1 at a σ0 of 1, do."""
    return level if relative else level * max(1.0, 1.0 / max(rms_sq, 1e-300))


def sandwich_covariance(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(A⁻¹BA⁻¹, A⁻¹), A inverted at a unit diagonal by Cholesky; None when A is not positive
    definite (a Cauchy ψ' < 0 on many rows: no sandwich there)."""
    As, d = unit_diagonal(A)
    inv_s = cholesky_inverse(As)
    if inv_s is None:
        return None
    Ainv = inv_s / np.outer(d, d)
    cov = Ainv @ B @ Ainv
    return 0.5 * (cov + cov.T), Ainv
