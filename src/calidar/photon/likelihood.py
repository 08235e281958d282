"""The exact per-shot likelihood of the CCR photon counts, its score, and the Fisher information.

Model of one shot (distances m): the CCR at (x_c, y_c) in track coordinates sits at r from
the true footprint centre (x_shot + b_a + e_x, b_c + e_y), e ~ N(0, σ_j²) on each axis the
shot's pointing jitter. The footprint energy is Gaussian, so the mean number of CCR photons
is λ = Λ·exp(−2r²/w²) (Λ at the centre, w the 1/e² radius, set by the 50 %-detection
diameter D: :func:`calidar.photon.parameters.footprint_radius_1e2`). The return arrives
within the detector's dead time, so each of the N channels records at most one CCR photon:
k_c ~ Binomial(N, π), π = 1 − e^(−λ/N). A fraction q of the shots lose their CCR return.
Background photons in the count band are Poisson(β) and add to the count:

    P(k) = Σ_j Poisson(j; β) · [q·[k − j = 0] + (1 − q)·E_e Binomial(k − j; N, π(e))],

the expectation over the jitter by Gauss–Hermite quadrature (5 × 5 nodes; the footprint factor
is separable in e_x, e_y). ``theta`` holds
one row (b_a, b_c, D, Λ, q) — :data:`calidar.photon.parameters.NAMES` — per parameter group
(beam); each shot names its group. The kernels (numba) give log P(k) of the observed counts
with its exact gradient (the score), and the whole distribution P(0 … K) with its gradient,
for the expected (Fisher) information Σ_shots Σ_k ∂P_k ∂P_kᵀ / P_k, whose inverse bounds the
covariance of any unbiased estimate from below (Cramér–Rao).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from math import exp, expm1, lgamma, log

import numba
import numpy as np

from calidar.photon.parameters import LN2

QUADRATURE_POINTS = 5  #: Gauss–Hermite nodes per jitter axis
N_PARAMS = 5


@dataclass
class Shots:
    """Every shot of every CCR window: the observations of the likelihood (distances m)."""

    x: np.ndarray  #: reported along-track position of the shot's footprint
    x_ccr: np.ndarray  #: along-track position of the shot's CCR
    y_ccr: np.ndarray  #: cross-track position of the shot's CCR (left +)
    background: np.ndarray  #: β, mean background photons per shot in the count band
    counts: np.ndarray  #: photons recorded in the count band (int)
    group: np.ndarray  #: parameter group (beam) of the shot (int)
    channels: np.ndarray  #: detector channels of the shot's beam (int)
    window: np.ndarray  #: index of the CCR window the shot belongs to (int)

    def __len__(self) -> int:
        return int(self.x.size)

    def with_counts(self, counts: np.ndarray) -> "Shots":
        return Shots(self.x, self.x_ccr, self.y_ccr, self.background, np.asarray(counts, np.int64),
                     self.group, self.channels, self.window)


@functools.lru_cache(maxsize=8)
def jitter_nodes(jitter_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(nodes e (m), weights summing to 1) of the Gauss–Hermite rule for N(0, σ_j²) on one axis."""
    z, wz = np.polynomial.hermite_e.hermegauss(QUADRATURE_POINTS if jitter_m > 0 else 1)
    return jitter_m * z, wz / wz.sum()


#: background terms Poisson(j; β) below this fraction of Poisson(0; β) are dropped
BACKGROUND_TOLERANCE = 1e-13


@numba.njit(cache=True)
def _ccr_terms(n, dx0, dy0, th, nodes, wts, work, mlo, mhi):  # pragma: no cover - numba
    """E_jitter[Binomial(m; n, π)] for m = mlo … mhi (into work[0, m − mlo]) and its derivatives
    ∂/∂b_a, ∂/∂b_c, ∂/∂w², ∂/∂Λ|w (into work[1 … 4]); work[5], work[6]: the separable
    footprint factors of the jitter nodes. π = 1 − e^(−u), u = Λ/n·exp(−2r²/w²); binomial terms
    by the recurrence B(m + 1) = B(m)·(n − m)/(m + 1)·(e^u − 1)."""
    d, lam = th[2], th[3]
    w2 = d * d / (2.0 * log(lam / LN2))
    nm = mhi - mlo + 1
    for r in range(5):
        for m in range(nm):
            work[r, m] = 0.0
    nq = nodes.size
    for i in range(nq):
        work[5, i] = exp(-2.0 * (dx0 + nodes[i]) ** 2 / w2)
        work[6, i] = exp(-2.0 * (dy0 + nodes[i]) ** 2 / w2)
    logc = lgamma(n + 1.0) - lgamma(mlo + 1.0) - lgamma(n - mlo + 1.0)
    for i in range(nq):
        dx = dx0 + nodes[i]
        for jj in range(nq):
            dy = dy0 + nodes[jj]
            u = lam / n * work[5, i] * work[6, jj]
            wij = wts[i] * wts[jj]
            s2 = (dx * dx + dy * dy) / (w2 * w2)
            if mlo == 0:
                b = exp(-n * u)  # B(0): the common case (no photon) costs one exp
            elif u > 1e-300:
                b = exp(logc + mlo * log(-expm1(-u)) - (n - mlo) * u)
            else:
                b = 0.0
            ratio = expm1(u) if mhi > 0 else 0.0
            u_over = u / ratio if ratio > 0.0 else 1.0  # u/(e^u − 1) → 1 as u → 0
            for m in range(nm):
                mm = mlo + m
                if m > 0:
                    b *= (n - mm + 1.0) / mm * ratio
                # w·(dB/du)·u: u's derivatives are u times these
                t = wij * b * (mm * u_over - (n - mm) * u)
                work[0, m] += wij * b
                work[1, m] -= t * 4.0 * dx / w2
                work[2, m] -= t * 4.0 * dy / w2
                work[3, m] += t * 2.0 * s2
                work[4, m] += t / lam


@numba.njit(cache=True)
def _combine(k, n, pois, th, work, mlo, nm, grad):  # pragma: no cover - numba
    """P(k) = Σ_m Poisson(k − m; β)·(q·[m = 0] + (1 − q)·E[B(m)]) over the CCR terms m = mlo …
    mlo + nm − 1 of ``work`` (:func:`_ccr_terms`), and its gradient w.r.t. (b_a, b_c, D, Λ, q);
    ``pois[j]`` = Poisson(j; β)."""
    d, lam, q = th[2], th[3], th[4]
    big_l = log(lam / LN2)
    w2 = d * d / (2.0 * big_l)
    for c in range(N_PARAMS):
        grad[c] = 0.0
    p = 0.0
    one_q = 1.0 - q
    for m in range(nm):
        mm = mlo + m
        j = k - mm
        if j < 0 or mm > n or j >= pois.size:
            continue
        pj = pois[j]
        zero = 1.0 if mm == 0 else 0.0
        p += pj * (q * zero + one_q * work[0, m])
        grad[0] += pj * one_q * work[1, m]
        grad[1] += pj * one_q * work[2, m]
        grad[2] += pj * one_q * work[3, m] * 2.0 * w2 / d
        grad[3] += pj * one_q * (work[4, m] - work[3, m] * w2 / (lam * big_l))
        grad[4] += pj * (zero - work[0, m])
    return p


@numba.njit(cache=True)
def _shot_probability(k, n, beta, dx0, dy0, th, nodes, wts, grad, work):  # pragma: no cover - numba
    """P(k photons in the count band) of one shot and its gradient (into ``grad``): CCR photons
    m = k − j plus j ~ Poisson(β) background photons (the terms that matter)."""
    pois = work[7]
    jmax = _poisson(beta, k, pois)
    mlo, mhi = max(k - jmax, 0), min(k, n)
    if mhi < mlo:
        for c in range(N_PARAMS):
            grad[c] = 0.0
        return 0.0
    _ccr_terms(n, dx0, dy0, th, nodes, wts, work, mlo, mhi)
    return _combine(k, n, pois[:jmax + 1], th, work, mlo, mhi - mlo + 1, grad)


@numba.njit(cache=True)
def _poisson(beta, kmax, out):  # pragma: no cover - numba
    """Poisson(j; β) for j = 0 … jmax into ``out``, jmax ≤ kmax the last term ≥
    BACKGROUND_TOLERANCE·P(0); returns jmax."""
    out[0] = exp(-beta) if beta > 0.0 else 1.0
    if beta <= 0.0:
        return 0
    for j in range(1, min(kmax, out.size - 1) + 1):
        rel = out[j - 1] / out[0] * beta / j
        if rel < BACKGROUND_TOLERANCE:
            return j - 1
        out[j] = out[j - 1] * beta / j
    return min(kmax, out.size - 1)


@numba.njit(cache=True)
def _scratch(nch, nodes):  # pragma: no cover - numba
    return np.zeros((8, max(int(nch.max()) + 1 if nch.size else 1, nodes.size) + 64))


@numba.njit(cache=True)
def _valid(th):  # pragma: no cover - numba
    ok = th[2] > 0.0 and th[3] > LN2 * 1.000001 and 0.0 <= th[4] < 1.0
    for i in range(N_PARAMS):
        ok = ok and abs(th[i]) < 1e300
    return ok


@numba.njit(cache=True)
def log_probabilities(theta, x, xc, yc, beta, k, g, nch, nodes, wts):  # pragma: no cover - numba
    """(log P(k_s), ∂ log P(k_s)/∂θ_g(s)) of every shot s: (n,), (n, 5). −inf where P ≤ 0 or θ is
    outside the model's domain (D > 0, Λ > ln 2, 0 ≤ q < 1)."""
    n = x.size
    logp = np.empty(n)
    score = np.zeros((n, N_PARAMS))
    grad, work = np.zeros(N_PARAMS), _scratch(nch, nodes)
    for s in range(n):
        th = theta[g[s]]
        if not _valid(th):
            logp[s] = -np.inf
            continue
        dx0, dy0 = x[s] + th[0] - xc[s], th[1] - yc[s]
        p = _shot_probability(k[s], nch[s], beta[s], dx0, dy0, th, nodes, wts, grad, work)
        if not p > 0.0:
            logp[s] = -np.inf
            continue
        logp[s] = log(p)
        for i in range(N_PARAMS):
            score[s, i] = grad[i] / p
    return logp, score


@numba.njit(cache=True)
def _largest_count(n, lam, ax, by):  # pragma: no cover - numba
    """The largest CCR count m whose binomial probability can exceed 1e-15 at any jitter node."""
    u = lam / n * ax.max() * by.max()
    pi, term = -expm1(-u), 1.0
    for m in range(1, n + 1):
        term *= (n - m + 1.0) / m * pi
        if term < 1e-15:
            return m - 1
    return n


@numba.njit(cache=True)
def _shot_table(s, th, x, xc, yc, beta, nch, kmax, nodes, wts, grad, work, p,
                dp):  # pragma: no cover - numba
    """Row ``s`` of P(k), k = 0 … kmax, and its gradient (k beyond what the shot can record stay
    0)."""
    n = nch[s]
    dx0, dy0 = x[s] + th[0] - xc[s], th[1] - yc[s]
    _ccr_terms(n, dx0, dy0, th, nodes, wts, work, 0, 0)  # fills the node factors work[5], work[6]
    mmax = _largest_count(n, th[3], work[5, :nodes.size], work[6, :nodes.size])
    _ccr_terms(n, dx0, dy0, th, nodes, wts, work, 0, mmax)
    jmax = _poisson(beta[s], kmax, work[7])
    for k in range(min(kmax, mmax + jmax) + 1):
        p[s, k] = _combine(k, n, work[7, :jmax + 1], th, work, 0, mmax + 1, grad)
        for c in range(N_PARAMS):
            dp[s, k, c] = grad[c]


@numba.njit(cache=True)
def probability_table(theta, x, xc, yc, beta, g, nch, kmax, nodes, wts):  # pragma: no cover - numba
    """P(k) for k = 0 … kmax of every shot and its gradient: (n, kmax + 1), (n, kmax + 1, 5)."""
    n = x.size
    p = np.zeros((n, kmax + 1))
    dp = np.zeros((n, kmax + 1, N_PARAMS))
    grad, work = np.zeros(N_PARAMS), _scratch(nch, nodes)
    for s in range(n):
        th = theta[g[s]]
        if not _valid(th):
            p[s, :] = np.nan
            continue
        _shot_table(s, th, x, xc, yc, beta, nch, kmax, nodes, wts, grad, work, p, dp)
    return p, dp


@numba.njit(cache=True)
def information_blocks(theta, x, xc, yc, beta, g, nch, kmax, nodes,
                       wts):  # pragma: no cover - numba
    """Σ over each group's shots of Σ_k ∂P_k ∂P_kᵀ / P_k: (groups, 5, 5)."""
    n = x.size
    out = np.zeros((theta.shape[0], N_PARAMS, N_PARAMS))
    p = np.zeros((1, kmax + 1))
    dp = np.zeros((1, kmax + 1, N_PARAMS))
    grad, work = np.zeros(N_PARAMS), _scratch(nch, nodes)
    for s in range(n):
        th = theta[g[s]]
        if not _valid(th):
            continue
        p[0, :] = 0.0
        dp[0, :, :] = 0.0
        one = slice(s, s + 1)  # this shot alone, as row 0
        _shot_table(0, th, x[one], xc[one], yc[one], beta[one], nch[one], kmax, nodes, wts, grad,
                    work, p, dp)
        for k in range(kmax + 1):
            if p[0, k] > 1e-300:
                for a in range(N_PARAMS):
                    for b in range(N_PARAMS):
                        out[g[s], a, b] += dp[0, k, a] * dp[0, k, b] / p[0, k]
    return out


def _args(shots: Shots, jitter_m: float):
    return ((shots.x, shots.x_ccr, shots.y_ccr, np.maximum(shots.background, 0.0)),
            (shots.group.astype(np.int64), shots.channels.astype(np.int64)), jitter_nodes(jitter_m))


def log_likelihood(theta: np.ndarray, shots: Shots,
                   jitter_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Per shot: log P(observed count) and its gradient w.r.t. the shot's group row of ``theta``
    (G, 5)."""
    (x, xc, yc, beta), (g, nch), nodes = _args(shots, jitter_m)
    counts = shots.counts.astype(np.int64)
    return log_probabilities(np.asarray(theta, float), x, xc, yc, beta, counts, g, nch, *nodes)


def max_count(shots: Shots) -> int:
    """The largest count with a probability worth keeping: channels + background photons to
    1e-12."""
    beta = float(np.max(shots.background, initial=0.0))

    def poisson_term(j):  # Poisson(j + 1; β)
        return np.exp(-beta) * beta ** (j + 1) / np.prod(np.arange(1, j + 2, dtype=float))

    j = 0
    while beta > 0 and poisson_term(j) > 1e-12:
        j += 1
    return int(shots.channels.max()) + j


def count_distribution(theta: np.ndarray, shots: Shots, jitter_m: float, kmax: int | None = None):
    """P(k), k = 0 … kmax, of every shot and its gradient: (n, K), (n, K, 5)."""
    (x, xc, yc, beta), (g, nch), nodes = _args(shots, jitter_m)
    return probability_table(np.asarray(theta, float), x, xc, yc, beta, g, nch,
                             max_count(shots) if kmax is None else kmax, *nodes)


def fisher_information(theta: np.ndarray, shots: Shots, jitter_m: float, columns: np.ndarray,
                       n_free: int) -> np.ndarray:
    """Expected Fisher information of the shots' counts (n_free × n_free); ``columns`` (G, 5) maps
    each group's parameter to its position among the free parameters (−1: not free)."""
    (x, xc, yc, beta), (g, nch), nodes = _args(shots, jitter_m)
    blocks = information_blocks(np.asarray(theta, float), x, xc, yc, beta, g, nch,
                                max_count(shots), *nodes)
    info = np.zeros((n_free, n_free))
    for grp in range(blocks.shape[0]):
        col = columns[grp]
        use = np.flatnonzero(col >= 0)
        np.add.at(info, np.ix_(col[use], col[use]), blocks[grp][np.ix_(use, use)])
    return info


def simulate_counts(table: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Counts drawn shot by shot from the distributions P(k) of :func:`count_distribution` (n,
    K)."""
    cdf = np.cumsum(table, axis=1)
    u = rng.random(table.shape[0]) * cdf[:, -1]
    return np.minimum((cdf < u[:, None]).sum(axis=1), table.shape[1] - 1)
