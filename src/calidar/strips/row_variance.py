"""A row's variance from its points' scatter, with a prior fitted to the pair's rows (issue 26).

Each side of a VGICP row estimates its points' scatter along the normal from a handful of points (a's ball:
n − 1 degrees of freedom; b's 12-point plane: 9). Moderated toward the pair's mean with a fixed weight
(:func:`calidar.strips.correspond.moderated_variance`, ν0 = 20) the rows' σ are right on average but wrong
row by row where surfaces differ in roughness: at the truth (``benchmarks/strips_vgicp_rows.py --rows``) the
quiet rows' residuals were 0.66–0.85 of their σ on the airborne survey and the rough ones' 1.23.

Here the spread of the true variances over the pair is fitted as a scaled inverse χ² prior (d0, s0²) from
the rows' log-variances (Smyth 2004, *Linear models and empirical Bayes methods for assessing differential
expression in microarray experiments*, Stat. Appl. Genet. Mol. Biol. 3:3, §6.2; limma's ``fitFDist``):
E[e] = log s0² + ψ(d0/2) − log(d0/2) and Var[e] = ψ'(d0/2) + mean ψ'(d/2) for e = log s² − ψ(d/2) + log(d/2).
Each row's variance is then the posterior mean E[τ² | s²] = ν′ s̃² / (ν′ − 2), s̃² = (d0 s0² + d s²) / ν′,
ν′ = d0 + d (the inverse-χ² posterior): a row's squared residual over it has expectation 1 under the model,
which is what the global test asks of every row (s̃² alone, the moderated-t scale, leaves ν′/(ν′ − 2) > 1).
"""

from __future__ import annotations

import numpy as np
from scipy.special import digamma, polygamma

from calidar.strips.correspond import SCATTER_PRIOR_DOF

#: fewer usable rows than this in a pair: no prior fitted, the pair's mean with :data:`SCATTER_PRIOR_DOF`
MIN_ROWS = 8
#: the fitted prior's degrees of freedom at least this: d0 + d > 2 keeps every posterior mean finite
MIN_PRIOR_DOF = 2.5


def _trigamma_inverse(y: float) -> float:
    """x with ψ'(x) = y (y > 0), by bisection on log x (ψ' falls monotonically)."""
    lo, hi = 1e-6, 1e8
    for _ in range(80):
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if polygamma(1, mid) > y else (lo, mid)
    return float(np.sqrt(lo * hi))


def fitted_prior(variance_m2: np.ndarray, dof: np.ndarray) -> tuple[float, float]:
    """(d0, s0²) of the scaled inverse χ² prior of the true variances behind ``variance_m2`` (each from ``dof``
    degrees of freedom), by the moments of the log-variances (Smyth 2004 §6.2); d0 = inf when the rows
    scatter no more than their sampling allows (one variance for all)."""
    ok = (dof > 0) & (variance_m2 > 0)
    s2, d = variance_m2[ok], dof[ok].astype(float)
    if s2.size < MIN_ROWS:
        return SCATTER_PRIOR_DOF, float(np.mean(variance_m2)) if variance_m2.size else 0.0
    e = np.log(s2) - digamma(d / 2) + np.log(d / 2)
    excess = float(np.var(e, ddof=1) - np.mean(polygamma(1, d / 2)))
    if excess <= 0:
        return np.inf, float(np.exp(np.mean(e)))
    d0 = max(2.0 * _trigamma_inverse(excess), MIN_PRIOR_DOF)
    return d0, float(np.exp(np.mean(e) + digamma(d0 / 2) - np.log(d0 / 2)))


def posterior_variance(variance_m2: np.ndarray, dof: np.ndarray | float) -> np.ndarray:
    """Each row's E[τ² | s²] (m²) under the prior fitted to all of ``variance_m2`` (see the module docstring)."""
    s2 = np.asarray(variance_m2, float)
    if s2.size == 0:
        return s2
    d = np.broadcast_to(np.asarray(dof, float), s2.shape)
    d0, s02 = fitted_prior(s2, d)
    if not np.isfinite(d0):
        return np.full(s2.shape, s02)
    nu = d0 + d
    return (d0 * s02 + d * s2) / (nu - 2.0)
