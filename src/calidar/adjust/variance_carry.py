"""Estimated variance components' own uncertainty carried into the parameters' covariance.

A parameter's covariance computed with estimated variance factors σ̂²ₖ in place of the true ones
(the "plug-in" Q(σ̂²)) is too small on average: Q(σ̂²) treats the factors as known, and where a
factor rests on few independent priors (m of them) it is itself uncertain by a large fraction
(its relative variance 2/m). Kackar & Harville (1984) and Kenward & Roger (1997) add the
factors' sampling variance to the plug-in; here in its Bayesian form, the law of total variance
over the factor's posterior:

    Var(x | data) = E_σ²[ Q(σ²) ] + Var_σ²( x̂(σ²) ),

σ²ₖ | σ̂²ₖ ~ σ̂²ₖ · mₖ / χ²_{mₖ} (the scaled inverse χ² of a variance estimated with mₖ degrees
of freedom under Jeffreys' prior; Gelman et al., "Bayesian Data Analysis", §3.2). The expectation
is taken per component with the others at their estimates (their cross terms neglected) by
equal-weight quadrature at :data:`QUANTILES` of χ²_m. In the simplest case (a parameter whose
variance is proportional to one factor estimated with m degrees of freedom) this multiplies
its variance by ≈ m/(m − 2), which turns the plug-in's t-distributed error back into one of the
stated σ; where m is large it changes nothing.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.linalg as sl
from scipy.special import gammaincinv

from calidar.adjust.variance_elements import scaled_normals
from calidar.errors import CalibrationError

#: the quadrature's nodes: the midpoints of five equal-probability slices of χ²_m
QUANTILES = (0.1, 0.3, 0.5, 0.7, 0.9)
#: below this many independent priors a factor's posterior has no usable mean (m/(m − 2)): held here
MIN_EFFECTIVE = 2.5


def posterior_multipliers(m: float) -> np.ndarray:
    """The multipliers of σ̂² at the quadrature nodes of its posterior σ̂²·m/χ²_m (equal
    weights)."""
    m = max(float(m), MIN_EFFECTIVE)
    # χ²_m's quantiles 2·P⁻¹(m/2, q) (P the regularised lower incomplete gamma function): what
    # scipy.stats.chi2.ppf computes, bit for bit, without scipy.stats' ≈ 0.5 s import
    return m / (2.0 * gammaincinv(m / 2, np.array(QUANTILES)))


def solve_scaled(JtWJ: np.ndarray, JtWr: np.ndarray, x0: np.ndarray,
                 priors: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], scale: np.ndarray,
                 keep: np.ndarray, observations: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(x̂[keep], Q[keep, keep]) of the linearised problem (the arguments of
    :func:`calidar.adjust.variance_elements.estimate_elements`) with each free parameter's prior σ
    multiplied by ``scale[i]``: one Cholesky factor and solves for the ``keep`` columns only."""
    N, b = scaled_normals(JtWJ, JtWr, x0, priors, scale, observations)
    try:
        c = sl.cho_factor(N, lower=True)
    except (np.linalg.LinAlgError, ValueError):
        raise CalibrationError("variance components: the normal matrix is not positive definite") \
            from None
    rhs = np.zeros((N.shape[0], keep.size + 1))
    rhs[:, 0] = b
    rhs[keep, np.arange(1, keep.size + 1)] = 1.0
    sol = sl.cho_solve(c, rhs)
    return x0[keep] + sol[keep, 0], sol[keep, 1:]


def carried_covariance(JtWJ: np.ndarray, JtWr: np.ndarray, x0: np.ndarray,
                       priors: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
                       labels: Sequence[str | None],
                       effective: Mapping[str, float], keep: np.ndarray,
                       observations: float = 1.0,
                       nodes: Mapping[str, Sequence[float]] | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(Q, ΔQ) of the free parameters ``keep`` (positions): the plug-in covariance of the
    linearised problem at the priors as they stand (their factors already applied) and what the
    factors' uncertainty adds to it (module docstring). ``labels[i]`` the component of free
    parameter i (None: not estimated), ``effective`` per component its effective number m of
    independent priors; ``nodes`` per other component its factor's distribution given otherwise,
    as multipliers of its variance as it stands at equal-probability nodes (a bounded level:
    :func:`calidar.adjust.variance_components.confidence_nodes`). Either way Q + ΔQ is the mean
    over the nodes of Q(σ²) + d dᵀ, d the estimate at σ² less the one as it stands: the expected
    squared error of the estimate as it stands."""
    labels = np.array([s or "" for s in labels], dtype=object)
    keep = np.asarray(keep, int)
    ones = np.ones(labels.size)
    x, Q = solve_scaled(JtWJ, JtWr, x0, priors, ones, keep, observations)
    delta = np.zeros_like(Q)
    given = {n: posterior_multipliers(m) for n, m in effective.items() if np.isfinite(m) and m > 0}
    for name, mult in (given | {n: np.asarray(v, float) for n, v in (nodes or {}).items()}).items():
        on = labels == name
        if not np.any(on) or mult.size == 0:
            continue
        for s2 in mult:
            scale = np.where(on, np.sqrt(s2), 1.0)
            xs, Qs = solve_scaled(JtWJ, JtWr, x0, priors, scale, keep, observations)
            d = xs - x
            delta += (Qs - Q + np.outer(d, d)) / mult.size
    return Q, delta
