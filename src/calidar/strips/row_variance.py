"""A row's variance from its points' scatter, with a prior fitted to the pair's rows (issue 26).

Each side of a VGICP row estimates its points' scatter along the normal from a handful of points
(a's ball: n − 1 degrees of freedom; b's 12-point plane: 9). Moderated toward the pair's mean with
a fixed weight (:func:`calidar.strips.correspond.moderated_variance`, ν0 = 20) the rows' σ are
right on average but wrong row by row where surfaces differ in roughness: at the truth
(``benchmarks/strips_vgicp_rows.py --rows``) the quiet rows' residuals were 0.66–0.85 of their σ
on the airborne survey and the rough ones' 1.23.

Here the spread of the true variances over the pair is fitted as a scaled inverse χ² prior
(d0, s0²) from the rows' log-variances (Smyth 2004, *Linear models and empirical Bayes methods for
assessing differential expression in microarray experiments*, Stat. Appl. Genet. Mol. Biol. 3:3,
§6.2; limma's ``fitFDist``):

    E[e] = log s0² + ψ(d0/2) − log(d0/2),   Var[e] = ψ'(d0/2) + mean ψ'(d/2)

for e = log s² − ψ(d/2) + log(d/2). Each row's variance is then the posterior mean

    E[τ² | s²] = ν′ s̃² / (ν′ − 2),   s̃² = (d0 s0² + d s²) / ν′,   ν′ = d0 + d

(the inverse-χ² posterior): a row's squared residual over it has expectation 1 under the model,
which is what the global test asks of every row (s̃² alone, the moderated-t scale, leaves
ν′/(ν′ − 2) > 1).
"""

from __future__ import annotations

import numpy as np

from calidar.strips.correspond import SCATTER_PRIOR_DOF

#: fewer usable rows than this in a pair: no prior fitted, the pair's mean with
#: :data:`SCATTER_PRIOR_DOF`
MIN_ROWS = 8
#: the fitted prior's degrees of freedom at least this: d0 + d > 2 keeps every posterior mean finite
MIN_PRIOR_DOF = 2.5


def trigamma(x):
    """ψ'(x) = ζ(2, x), the Hurwitz zeta function: scipy's ``polygamma(1, x)`` computes it as
    (−1)²·Γ(2)·ζ(2, x), the same bits (both factors exactly 1), at ≈ 1/7 of the call's cost."""
    from scipy.special import zeta  # here, not at import: `calidar quality` needs no scipy

    return zeta(2, x)


def _trigamma_inverse(y: float) -> float:
    """x with ψ'(x) = y (y > 0), by bisection on log x (ψ' falls monotonically)."""
    lo, hi = 1e-6, 1e8
    for _ in range(80):
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if trigamma(mid) > y else (lo, mid)
    return float(np.sqrt(lo * hi))


def fitted_prior(variance_m2: np.ndarray, dof: np.ndarray,
                 sampled: bool = True) -> tuple[float, float]:
    """(d0, s0²) of the scaled inverse χ² prior of the true variances behind ``variance_m2`` (each
    from ``dof`` degrees of freedom), by the moments of the log-variances (Smyth 2004 §6.2);
    d0 = inf when the rows scatter no more than their sampling allows (one variance for all).
    ``sampled`` False: the variances are expected values (a plan's, mirroring the calibrator),
    their whole spread the prior's."""
    from scipy.special import digamma

    ok = (dof > 0) & (variance_m2 > 0)
    s2, d = variance_m2[ok], dof[ok].astype(float)
    if s2.size < MIN_ROWS:
        return SCATTER_PRIOR_DOF, float(np.mean(variance_m2)) if variance_m2.size else 0.0
    e = np.log(s2) - (_per_value(digamma, d / 2) - np.log(d / 2) if sampled else 0.0)
    excess = float(np.var(e, ddof=1) - (np.mean(_per_value(trigamma, d / 2)) if sampled else 0.0))
    if excess <= 0:
        return np.inf, float(np.exp(np.mean(e)))
    d0 = max(2.0 * _trigamma_inverse(excess), MIN_PRIOR_DOF)
    return d0, float(np.exp(np.mean(e) + digamma(d0 / 2) - np.log(d0 / 2)))


def _per_value(f, x: np.ndarray) -> np.ndarray:
    """``f(x)`` of an elementwise ``f``, evaluated once per distinct value of ``x`` (the rows'
    degrees of freedom take a few integer values: scipy's polygamma over every row was 4 % of the
    calibration stage's samples); the same numbers."""
    values, inverse = np.unique(x, return_inverse=True)
    return np.asarray(f(values), float)[inverse.reshape(x.shape)]


def posterior(variance_m2: np.ndarray, dof: np.ndarray | float, sampled: bool = True
              ) -> tuple[np.ndarray, np.ndarray]:
    """Each row's E[τ² | s²] (m²) under the prior fitted to all of ``variance_m2`` (see the
    module docstring) and its posterior degrees of freedom ν′ = d0 + d (inf when the rows pool
    fully); ``sampled``: see :func:`fitted_prior`."""
    s2 = np.asarray(variance_m2, float)
    d = np.broadcast_to(np.asarray(dof, float), s2.shape)
    if s2.size == 0:
        return s2, s2.copy()
    d0, s02 = fitted_prior(s2, d, sampled)
    if not np.isfinite(d0):
        return np.full(s2.shape, s02), np.full(s2.shape, np.inf)
    nu = d0 + d
    return (d0 * s02 + d * s2) / (nu - 2.0), nu


def posterior_variance(variance_m2: np.ndarray, dof: np.ndarray | float) -> np.ndarray:
    """Each row's E[τ² | s²] (m²): :func:`posterior` without the degrees of freedom."""
    return posterior(variance_m2, dof)[0]


def satterthwaite(parts: list[np.ndarray], dofs: list[np.ndarray]) -> np.ndarray:
    """Degrees of freedom of a sum of variance estimates (each (R,) m² with its own degrees of
    freedom; inf for a known term): (Σ v)² / Σ v²/ν (Welch 1947, Satterthwaite 1946); inf when
    every term is known."""
    total = np.sum(parts, axis=0)
    spread = np.sum([np.where(np.isfinite(d), v**2 / np.where(np.isfinite(d), d, 1.0), 0.0)
                     for v, d in zip(parts, dofs)], axis=0)
    with np.errstate(divide="ignore"):
        return np.where(spread > 0, total**2 / np.maximum(spread, 1e-300), np.inf)


def roughness_excess(var_a_m2: np.ndarray, var_b_m2: np.ndarray, quantile: float) -> np.ndarray:
    """Each row's roughness beyond the pair's quiet rows (m²): ρ² = max(0, s̄² − s_q²), s̄² the
    mean of the two sides' scatter variances along the normal (m²) and s_q² its ``quantile`` over
    the pair's rows — the part of a row's scatter that is the surface's own unevenness rather than
    the range noise every row shares (issue 26, ninth session: see :func:`rough_rows_variance`)."""
    mean = 0.5 * (np.asarray(var_a_m2, float) + np.asarray(var_b_m2, float))
    if mean.size == 0:
        return mean
    return np.maximum(mean - float(np.quantile(mean, quantile)), 0.0)


def rough_rows_variance(var_a_m2: np.ndarray, dof_a: np.ndarray, var_b_m2: np.ndarray,
                        dof_b: np.ndarray | float, kappa: float, quantile: float
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The model error of rough rows, κ·ρ² (m², :func:`roughness_excess`), and its degrees of
    freedom, for rows whose two sides' scatter variances (m²) have ``dof_a`` and ``dof_b``.

    A row's white-noise variance s_a²/n_a + s_b²·h falls with its points' count; a surface's own
    unevenness at the ball's scale does not: a's ball mean and b's fitted plane average it over
    different points, and their difference keeps a share κ of it whatever the count. It enters
    the row's σ² as a variance component with cofactor ρ² (Koch 1999, *Parameter Estimation and
    Hypothesis Testing in Linear Models*, §3.6; Förstner 1979), κ estimated once, offline, from
    simulated surveys (``benchmarks/strips_vgicp_row_model.py``) — not refitted from each
    calibration's residuals, which would pull σ0 toward 1 whatever the calibration. Its degrees of
    freedom are taken as those of s̄² (Satterthwaite over the two sides; inf where ρ² = 0): the
    delta method's 2κ²s̄⁴/ν for the variance of κ·(s̄² − s_q²) holds far above the threshold only,
    and left rows just above it with σ² of one or two degrees of freedom."""
    shape = np.broadcast_shapes(np.shape(var_a_m2), np.shape(var_b_m2))
    if kappa == 0.0:  # no model error (the default): nothing to estimate
        return np.zeros(shape), np.full(shape, np.inf)
    rho2 = roughness_excess(var_a_m2, var_b_m2, quantile)
    nu_mean = satterthwaite([0.5 * np.broadcast_to(np.asarray(var_a_m2, float), shape),
                             0.5 * np.broadcast_to(np.asarray(var_b_m2, float), shape)],
                            [np.broadcast_to(np.asarray(dof_a, float), shape),
                             np.broadcast_to(np.asarray(dof_b, float), shape)])
    return kappa * rho2, np.where(rho2 > 0, nu_mean, np.inf)


def variance_components(residual_m: np.ndarray, base_m2: np.ndarray, cofactors: np.ndarray,
                        max_z: float = 7.0, iterations: int = 50) -> np.ndarray:
    """θ ≥ 0 (one per row of ``cofactors`` (K, R)) with E[r²] = base + Σ θ_k V_k for residuals
    ``residual_m`` (R,) whose known variance part is ``base_m2`` (m²): the iterated estimate of
    Förstner 1979 / Koch 1999 §3.6.2 for diagonal cofactors and redundancy numbers ≈ 1 (many rows,
    few parameters), S θ = q with S_kl = Σ V_k V_l / σ⁴ and q_k = Σ (r² − base) V_k / σ⁴, σ² the
    last iteration's; rows beyond ``max_z`` σ left out (gross errors), a negative θ set to 0.
    Offline only (a rows' σ model's factor from simulated surveys): fitted to one calibration's own
    residuals it would take σ0 to 1 whatever the calibration."""
    r2, base, V = np.asarray(residual_m, float) ** 2, np.asarray(base_m2, float), np.atleast_2d(
        np.asarray(cofactors, float))
    theta = np.zeros(V.shape[0])
    for _ in range(iterations):
        var = base + theta @ V
        keep = r2 <= max_z**2 * var
        w = 1.0 / var[keep] ** 2
        Vk = V[:, keep]
        new = np.maximum(np.linalg.lstsq((Vk * w) @ Vk.T, (Vk * w) @ (r2[keep] - base[keep]),
                                         rcond=None)[0], 0.0)
        if np.allclose(new, theta, rtol=1e-7, atol=1e-15):
            return new
        theta = new
    return theta


#: representative degrees of freedom kept of a solution's rows (the means of this many quantile
#: bins)
DOF_BINS = 20
#: stands for an infinite number of degrees of freedom in solution.json (JSON has no inf)
KNOWN_DOF = 1e9


def dof_summary(dof: np.ndarray) -> list[float]:
    """The rows' degrees of freedom as :data:`DOF_BINS` representative values (each the mean of
    1/ν over a quantile bin, inverted; :data:`KNOWN_DOF` for known σ) — what :func:`consistency`
    needs, small enough for solution.json."""
    inv = np.sort(1.0 / np.clip(np.asarray(dof, float).ravel(), 2.05, KNOWN_DOF))
    if inv.size == 0 or inv[-1] <= 1.0 / KNOWN_DOF:  # no row, or every σ known
        return []
    return [float(1.0 / np.mean(b)) for b in np.array_split(inv, min(DOF_BINS, inv.size))]


def consistency(kind: str | None, dofs: list[float] | None = None) -> float:
    """The engine's robust σ0² (IRLS weights of ``kind`` on z / s, s = 1.4826 · MAD of z;
    σ0² = Σ w z² / Σ w) for rows whose z = residual/σ follow Student's t with ``dofs`` degrees of
    freedom, scaled to unit variance (σ² = E[τ² | s²]: a row's σ estimated from its scatter,
    Smyth 2004 §3; equal shares of the rows), relative to 1: the factor the global test divides
    out. None or [] → normal z (Cauchy: 0.794, Huber: 0.92…).

    The mixture's MAD scale is found by bisection on its CDF, the expectations by the trapezoid
    rule on a sinh-spaced grid (the t's tails fall as |x|^−(ν+1); w·u² stays bounded)."""
    from scipy.special import gammaln, stdtr

    from calidar.adjust.solver import robust_weights

    if kind is None:
        return 1.0
    nu = np.clip(np.asarray(dofs if dofs else [KNOWN_DOF], float), 2.05, KNOWN_DOF)
    unit = np.sqrt((nu - 2.0) / nu)  # t_ν times this has variance 1
    lo, hi = 0.0, 10.0
    for _ in range(60):  # median of |z| over the mixture
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.mean(2.0 * stdtr(nu, mid / unit) - 1.0) < 0.5 else (lo, mid)
    s = 1.4826 * 0.5 * (lo + hi)
    x = np.sinh(np.linspace(-9.0, 9.0, 6001))  # z / unit for each ν
    dx = np.gradient(x)
    log_c = gammaln((nu + 1) / 2) - gammaln(nu / 2) - 0.5 * np.log(nu * np.pi)
    dens = np.exp(log_c[:, None] - (nu[:, None] + 1) / 2 * np.log1p(x[None, :] ** 2 / nu[:, None]))
    u = unit[:, None] * x[None, :] / s
    w = robust_weights(u, kind)
    num = np.mean(np.sum(dens * dx * w * u * u, axis=1))
    return float(s * s * num / np.mean(np.sum(dens * dx * w, axis=1)))


def rows_dof(c) -> np.ndarray:
    """The degrees of freedom of each residual of correspondences ``c`` (inf where unknown: σ taken
    as known, or a matcher that picked rows without carrying ``dof`` along)."""
    n = c.n_obs * (3 if c.normal is None else 1)
    dof = np.asarray(c.dof, float).ravel()
    if dof.size == c.n_obs and n == c.n_obs:
        return dof
    return np.full(n, float(dof[0]) if dof.size == 1 else np.inf)
