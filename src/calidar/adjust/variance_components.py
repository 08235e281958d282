"""Variance components: how wide the a-priori σ of groups of pseudo-observations (priors on
parameters) really are, estimated from the adjustment itself.

The model is a linear(ised) Gauss–Markov model with observations r (weights W, their own
variance factor σ²_obs) and K groups of priors on parameters, group k of precision Pₖ/σ²ₖ
(Pₖ the stated precision, σ²ₖ its unknown variance factor). The iterated estimator of Förstner
(1979) and Koch (1999, "Parameter Estimation and Hypothesis Testing in Linear Models", §3.6.3–4;
at convergence the best invariant quadratic unbiased estimate, the REML one under normality):

    σ²ₖ ← vₖᵀPₖvₖ / rₖ,   rₖ = nₖ − tr(Pₖ Q)/σ²ₖ,   Q = N⁻¹ = (JᵀWJ/σ²_obs + Σₖ Pₖ/σ²ₖ)⁻¹

where vₖ = x̂ₖ − centreₖ are the priors' residuals and rₖ their redundancy (how many of the nₖ
priors the data check; Σ r = observations + priors − parameters). A group whose priors the data
cannot check (rₖ ≈ 0: the parameters are known only through their priors) has no estimate:
:func:`estimate_components` reports its redundancy so the caller can keep its stated σ.

Components whose truth is zero are approached geometrically (a known weakness of the iterated
estimator): each is held at ``floor`` at least, which the caller chooses as "as good as exact".
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from calidar.adjust.normals import normal_matrix
from calidar.adjust.solution import cholesky_inverse
from calidar.errors import CalibrationError

OBSERVATIONS = "observations"  #: the name of the observations' own component


@dataclass(frozen=True)
class PriorBlock:
    """Priors on the parameters ``index`` (positions in x) with ``center`` and the stated
    precision ``precision`` (the inverse of their covariance at variance factor 1), in ``group``."""

    index: np.ndarray
    center: np.ndarray
    precision: np.ndarray
    group: str


@dataclass
class Components:
    """The estimated variance factors (1: the stated σ hold) and what they rest on."""

    variance: dict[str, float]  #: per group (and :data:`OBSERVATIONS`) the factor σ²
    redundancy: dict[str, float]  #: per group rₖ at the estimate
    size: dict[str, int]  #: per group nₖ (observations: their effective number Σ w σ²)
    x: np.ndarray  #: the parameters at the estimated components
    iterations: int
    converged: bool
    fixed: tuple[str, ...] = field(default=())  #: groups held at 1 (not estimated)
    #: per group rₖ at the start (the stated σ, or ``start``): how many priors the data check at
    #: that level
    redundancy_start: dict[str, float] = field(default_factory=dict)
    #: per group tr(Rₖ²) at the estimate, Rₖ = I − PₖQₖₖ/σ²ₖ its redundancy matrix (rₖ = tr Rₖ):
    #: twice the restricted likelihood's information on log σ²ₖ, so the σ factor's relative σ is
    #: 1/√(2 tr Rₖ²) (Koch 1999, §3.6.4; ≤ rₖ: many priors each checked a little count less than
    #: their redundancy says)
    information: dict[str, float] = field(default_factory=dict)

    def sigma_factor(self, group: str) -> float:
        """√σ²ₖ: the factor on the group's stated σ."""
        return float(np.sqrt(self.variance[group]))

    def relative_sigma(self, group: str) -> float:
        """The σ of the estimated σ factor relative to it, 1/√(2 rₖ) (χ² with rₖ degrees of
        freedom)."""
        r = self.redundancy[group]
        return float("inf") if r <= 0 else float(1.0 / np.sqrt(2.0 * r))


def estimate_components(JtWJ: np.ndarray, JtWr: np.ndarray, rWr: float, n_obs: float,
                        x0: np.ndarray, blocks: Sequence[PriorBlock], *, fixed: Sequence[str] = (),
                        estimate_observations: bool = True,
                        start: Mapping[str, float] | None = None, max_iter: int = 60,
                        tol: float = 1e-3, floor: float = 1e-6,
                        marginal: bool = False) -> Components:
    """The variance components of the observations and of each group of ``blocks`` (see the
    module docstring) for the linearised problem r(x) = r₀ + J(x − x0): ``JtWJ`` = JᵀWJ,
    ``JtWr`` = JᵀWr₀, ``rWr`` = r₀ᵀWr₀, ``n_obs`` the observations' effective number (Σ of the
    relative weights). ``fixed``: groups held at 1 (or at ``start``); ``estimate_observations``
    False holds σ²_obs at 1 too. Iterates until no factor changes by more than ``tol`` (relative)
    or ``max_iter`` times; each factor ≥ ``floor``.

    ``marginal``: estimate the priors' factors from their marginal variances instead,
    σ²ₖ ← Σᵢ (vᵢ²/Σᵢᵢ) / (nₖ − Σᵢ Qᵢᵢ/(σ²ₖΣᵢᵢ)) with Σ = Pₖ⁻¹ the stated covariance: the fixed
    point of E[vᵢ²] = σ²ₖΣᵢᵢ − Qᵢᵢ (that of the EM update of Dempster, Laird & Rubin 1977 with
    the identity in place of Σ⁻¹), iterated as Förstner's (the priors the data cannot check drop
    out of numerator and denominator alike). The same estimate when the stated correlations are
    right; the level of the stated σ themselves when they are not (an error smoother than the
    stated correlation is seen by vᵀPv mostly through its small increments: its level comes out
    low)."""
    u = JtWJ.shape[0]
    groups = sorted({b.group for b in blocks})
    var = {g: 1.0 for g in [OBSERVATIONS, *groups]} | dict(start or {})
    frozen = set(fixed) | (set() if estimate_observations else {OBSERVATIONS})
    size = {OBSERVATIONS: float(n_obs)}
    size |= {g: sum(b.index.size for b in blocks if b.group == g) for g in groups}
    converged, it, x, red, red_start = False, 0, x0, {}, {}
    stated = [np.diag(np.linalg.inv(b.precision)) if marginal else None for b in blocks]  # Σᵢᵢ
    for it in range(1, max_iter + 1):
        N, b = JtWJ / var[OBSERVATIONS], -JtWr / var[OBSERVATIONS]
        for blk in blocks:
            N[np.ix_(blk.index, blk.index)] += blk.precision / var[blk.group]
            b[blk.index] -= blk.precision @ (x0[blk.index] - blk.center) / var[blk.group]
        Q = cholesky_inverse(N)
        if Q is None:
            raise CalibrationError("variance components: the normal matrix is not positive "
                                   "definite")
        dx = Q @ b
        x = x0 + dx
        quad = {g: 0.0 for g in groups}
        trace = {g: 0.0 for g in groups}
        spread = {g: 0.0 for g in groups}
        trace_marginal = {g: 0.0 for g in groups}
        for blk, sii in zip(blocks, stated):
            v = x[blk.index] - blk.center
            quad[blk.group] += float(v @ blk.precision @ v)
            trace[blk.group] += float(np.sum(blk.precision * Q[np.ix_(blk.index, blk.index)]))
            if marginal:
                spread[blk.group] += float(np.sum(v**2 / sii))
                trace_marginal[blk.group] += float(np.sum(Q[blk.index, blk.index] / sii))
        quad[OBSERVATIONS] = float(rWr + 2.0 * dx @ JtWr + dx @ JtWJ @ dx)
        red = {g: size[g] - trace[g] / var[g] for g in groups}
        red[OBSERVATIONS] = n_obs - (u - sum(trace[g] / var[g] for g in groups))
        red_start = red_start or dict(red)
        new = {g: (var[g] if g in frozen or red[g] <= 1e-9 else max(quad[g] / red[g], floor))
               for g in var}
        if marginal:  # σ²ₖ ← Σ vᵢ²/Σᵢᵢ / (nₖ − Σ Qᵢᵢ/(σ²ₖΣᵢᵢ)): the redundancy's diagonal analogue
            new |= {g: max(spread[g] / max(size[g] - trace_marginal[g] / var[g], 1e-9), floor)
                    for g in groups if g not in frozen and red[g] > 1e-9}
        change = max(abs(np.log(new[g] / var[g])) for g in var)
        var, used = new, var
        if change < tol:
            converged = True
            break
    sizes = {g: int(round(s)) if g != OBSERVATIONS else s for g, s in size.items()}
    info = {g: size[g] - 2.0 * trace[g] / used[g] + _trace_squared(Q, blocks, g) / used[g] ** 2
            for g in groups}
    return Components(var, red, sizes, x, it, converged, tuple(sorted(frozen - {OBSERVATIONS})),
                      red_start, info)


def _trace_squared(Q: np.ndarray, blocks: Sequence[PriorBlock], group: str) -> float:
    """tr((PₖQₖₖ)²) of one group (Pₖ block-diagonal over its blocks)."""
    mine = [b for b in blocks if b.group == group]
    idx = np.concatenate([b.index for b in mine])
    M = np.empty((idx.size, idx.size))
    row = 0
    for b in mine:
        M[row:row + b.index.size] = b.precision @ Q[np.ix_(b.index, idx)]
        row += b.index.size
    return float(np.sum(M * M.T))


def split_blocks(priors: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
                 group_of: Sequence[str | None]) -> list[PriorBlock]:
    """The engine's prior groups (free-parameter positions, centres, precision) cut by the group
    each parameter belongs to (``group_of[position]``; None: not in any component, its priors
    kept as stated under the group "other"). A prior group whose precision couples two groups
    is an error (its parameters' components could not be told apart)."""
    out = []
    for idx, center, P in priors:
        labels = np.array([group_of[i] or "other" for i in idx], dtype=object)
        for g in dict.fromkeys(labels.tolist()):
            sel = labels == g
            if np.any(P[np.ix_(sel, ~sel)] != 0):
                raise ValueError(f"variance components: a prior group couples {g!r} with "
                                 "another group")
            out.append(PriorBlock(idx[sel], center[sel], P[np.ix_(sel, sel)], g))
    return out


def upper_end(terms: tuple, blocks: Sequence[PriorBlock], variance: Mapping[str, float],
              group: str, *, marginal: bool = True, ceiling: float = 1e4, tol: float = 0.02,
              level: float = 0.025) -> float:
    """The largest variance factor of ``group`` the data do not reject, the others held at
    ``variance`` (``terms``: :func:`estimate_components`' first five arguments): at a trial σ²
    the estimator's own update (``marginal`` as there) over σ² is a χ²ᵣ/r, r the group's
    redundancy at σ², and σ² is rejected as too wide when it falls below that's ``level``
    quantile (one-sided; r degrees of freedom, fewer than Satterthwaite's r²/tr R²: the wider
    end). The ratio falls as σ² grows: the end is found by bisection from
    ``variance[group]`` (not rejected: the estimate, where the ratio is 1), to ``tol`` in log σ²,
    ``ceiling`` at most."""
    from scipy.special import gammaincinv  # χ²ᵣ's quantile 2·P⁻¹(r/2, q), as scipy.stats.chi2.ppf

    update = _update(terms, blocks, variance, group, marginal)

    def accepted(v: float) -> bool:
        ratio, r = update(v)
        return r <= 0 or ratio >= 2.0 * gammaincinv(r / 2.0, level) / r

    inside = max(float(variance[group]), 1e-12)
    outside = inside
    while outside < ceiling and accepted(outside):
        inside, outside = outside, min(outside * 4.0, ceiling)
    if outside == inside:
        return inside
    while abs(np.log(outside / inside)) > tol:
        mid = float(np.sqrt(inside * outside))
        inside, outside = (mid, outside) if accepted(mid) else (inside, mid)
    return inside


def _update(terms: tuple, blocks: Sequence[PriorBlock], variance: Mapping[str, float],
            group: str, marginal: bool):
    """v ↦ (the estimator's update of ``group``'s factor over v, the group's redundancy at v), the
    others held at ``variance``."""
    others = [g for g in {b.group for b in blocks} if g != group]

    def update(v: float) -> tuple[float, float]:
        c = estimate_components(*terms, blocks, fixed=others, estimate_observations=False,
                                start=dict(variance) | {group: v}, max_iter=1, floor=0.0,
                                marginal=marginal)
        return c.variance[group] / v, c.redundancy[group]

    return update


def confidence_nodes(terms: tuple, blocks: Sequence[PriorBlock], variance: Mapping[str, float],
                     group: str, probabilities: Sequence[float], low: float, high: float, *,
                     points: int = 10, marginal: bool = True) -> np.ndarray:
    """``group``'s variance factor at the ``probabilities`` of its confidence distribution over
    [``low``, ``high``], the others held at ``variance``: at p the largest σ² whose update
    (:func:`upper_end`'s test) is not rejected at one-sided level 1 − p — p = 0.975 is
    :func:`upper_end` itself. The test's p-value F(r·ratio; χ²ᵣ) is taken on ``points``
    log-spaced σ² and interpolated in log σ² (below ``low``: ``low``). Where the data check the
    group well this is the scaled inverse χ² σ̂²·r/χ²ᵣ that :mod:`calidar.adjust.variance_carry`
    averages over; for a bounded group it is what the data say of its factor, flat or not, down
    to ``low`` (a confidence distribution: Schweder & Hjort 2016, "Confidence, Likelihood,
    Probability", ch. 3)."""
    from scipy.special import gammainc  # χ²ᵣ's distribution function P(r/2, x/2)

    update = _update(terms, blocks, variance, group, marginal)
    grid = np.exp(np.linspace(np.log(low), np.log(high), points))
    pvalue = np.empty(points)
    for i, v in enumerate(grid):
        ratio, r = update(float(v))
        pvalue[i] = 1.0 if r <= 0 else float(gammainc(r / 2.0, r * ratio / 2.0))
    nodes = []
    for p in probabilities:
        ok = np.flatnonzero(pvalue >= 1.0 - p)  # not rejected at level 1 − p
        if ok.size == 0:
            nodes.append(low)
            continue
        i = ok[-1]
        if i + 1 == points:
            nodes.append(high)
            continue
        t = (pvalue[i] - (1.0 - p)) / (pvalue[i] - pvalue[i + 1])  # p falls between i and i + 1
        nodes.append(float(np.exp(np.log(grid[i]) + t * np.log(grid[i + 1] / grid[i]))))
    return np.array(nodes)


def normal_terms(est) -> tuple[np.ndarray, np.ndarray, float, float, np.ndarray]:
    """(JᵀWJ, JᵀWr, rᵀWr, Σ relative weights, x) of a :class:`calidar.adjust.solver.Estimate` at
    its values, robust weights as they stand: the first arguments of :func:`estimate_components`."""
    fit, w, r = est.fit, est.w, est.r
    J = fit.jacobian(est.x)
    return normal_matrix(J, w), np.asarray(J.T @ (w * r)).ravel(), float(np.sum(w * r * r)), \
        float(np.sum(w * fit.sig**2)), np.asarray(est.x, float)
