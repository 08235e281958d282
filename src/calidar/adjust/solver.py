"""Gauss–Newton / Levenberg–Marquardt with robust (IRLS) reweighting.

Model: residual functions r(θ) over arrays, observations with a-priori σ, optional priors
on parameters as pseudo-observations. The covariance of the free parameters is
σ0² · (JᵀWJ + P)⁻¹ with σ0² the a-posteriori variance factor.

Robust weights (Huber, Cauchy) act on standardised residuals u = r / (σ · s), where s is
a robust scale (1.4826 · MAD of r/σ) re-estimated every iteration, so that clutter
(vegetation, moving objects) loses weight while well-modelled observations keep it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import scipy.linalg as sl
import scipy.sparse as sp
from numba import njit

from calidar.adjust.parameters import ParameterSet
from calidar.adjust.solution import Solution, cholesky_inverse, residual_stats
from calidar.errors import CalibrationError

ResidualFn = Callable[[dict[str, float]], np.ndarray]
JacobianFn = Callable[[dict[str, float]], np.ndarray]

ROBUST_K = {"huber": 1.345, "cauchy": 2.385}
#: stop when every step is below this fraction of its parameter's σ (changes no one can see)
STEP_IN_SIGMA = 1e-3


def robust_weights(u: np.ndarray, kind: str | None, k: float | None = None) -> np.ndarray:
    """IRLS weights for standardised residuals u (Huber or Cauchy; None → ones)."""
    if kind is None:
        return np.ones_like(u)
    k = ROBUST_K[kind] if k is None else k
    a = np.abs(u)
    if kind == "huber":
        return np.where(a <= k, 1.0, k / np.maximum(a, 1e-300))
    if kind == "cauchy":
        return 1.0 / (1.0 + (a / k) ** 2)
    raise ValueError(f"robust must be 'huber', 'cauchy' or None, got {kind!r}")


def numerical_jacobian(fn: ResidualFn, params: ParameterSet, x: np.ndarray) -> np.ndarray:
    """Central differences of fn w.r.t. the free parameters, (n_obs, n_free)."""
    cols = []
    for j, p in enumerate(params.free):
        h = p.diff_step
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        cols.append((fn(params.values_with(xp)) - fn(params.values_with(xm))) / (2.0 * h))
    return np.stack(cols, axis=1) if cols else np.zeros((0, 0))


def solve(
    residual_fn: ResidualFn,
    params: ParameterSet,
    *,
    sigma: float | np.ndarray = 1.0,
    jacobian_fn: JacobianFn | None = None,
    robust: str | None = "cauchy",
    robust_k: float | None = None,
    max_iter: int = 30,
    tol: float = 1e-10,
    robust_scale: bool = True,
    progress: Callable[[int, float], None] | None = None,
    clusters: np.ndarray | list[np.ndarray] | None = None,
    prior_correlation: Sequence[tuple[Sequence[str], np.ndarray]] = (),
    normal_fn: Callable[[dict[str, float]], np.ndarray] | None = None,
) -> Solution:
    """Least-squares estimate of the free parameters of ``params``.

    residual_fn(values) → residuals (n,) in observation units for all parameter values (SI);
    sigma: a-priori σ of the observations (scalar or (n,)); jacobian_fn: analytic Jacobian
    (n, n_free) or None for central differences; robust: "cauchy" (default, for clutter), "huber" or None;
    robust_scale: re-estimate the residual scale by MAD for the robust weights (set False
    when σ is trusted); progress(iteration, cost) is called after every iteration;
    clusters: optional group id per observation (n,) for observations whose errors are
    correlated within groups (e.g. by a smooth trajectory error), or two ids per observation
    (n, 2) when each observation joins two groups (dyadic: correlated when sharing either):
    σ then come from the cluster-robust sandwich N⁻¹ (Σ_g J_gᵀW_g r_g r_gᵀW_g J_g) N⁻¹ ·
    G/(G−1) (Liang & Zeger 1986; dyadic form of Cameron & Miller 2014) where it exceeds the
    usual σ0²·N⁻¹ (σ raised, correlations kept); a list of such groupings raises each σ to
    the largest of their estimates (sandwich estimates from few groups run low);
    prior_correlation: groups (names, correlation matrix R) of free parameters whose priors
    (each its own prior_sigma) are jointly Gaussian with covariance D·R·D instead of
    independent. ``jacobian_fn`` may return a scipy.sparse matrix (many parameters, few per row).
    normal_fn(values): the normal matrix (n_free × n_free) to use instead of JᵀWJ — for a cost
    that is a negative log-likelihood (residuals whose squares sum to it), its expected
    information (Fisher scoring); the gradient stays Jᵀ·W·r.
    The covariance is σ0²·N⁻¹ without priors (σ relative) and max(σ0², 1)·N⁻¹ with them (σ
    absolute: the priors are never tightened by an a-posteriori σ0 below 1).
    """
    free = params.free
    if not free:
        raise CalibrationError("no free parameters to estimate")
    x = params.x()
    priors = _prior_groups(free, prior_correlation)
    n_prior = sum(idx.size for idx, _, _ in priors)

    def evaluate(xv):
        r = np.asarray(residual_fn(params.values_with(xv)), dtype=float)
        if r.ndim != 1:
            raise CalibrationError(f"residual function returned shape {r.shape}, expected (n,)")
        return r

    def jac(xv):
        return jacobian_fn(params.values_with(xv)) if jacobian_fn else numerical_jacobian(residual_fn, params, xv)

    r = evaluate(x)
    n = r.size
    sig = np.broadcast_to(np.asarray(sigma, float), (n,))
    if n < len(free) - n_prior:
        raise CalibrationError(f"{n} observations cannot determine {len(free)} parameters")
    if not np.all(np.isfinite(r)):
        raise CalibrationError(f"{int(np.sum(~np.isfinite(r)))} residuals are not finite at the start")

    def weights(rv):
        """Relative robust weights (0..1) times 1/σ²."""
        z = rv / sig
        s = 1.0
        if robust and robust_scale:
            mad = 1.4826 * np.median(np.abs(z - np.median(z)))
            s = mad if mad > 0 else 1.0
        return robust_weights(z / s, robust, robust_k) / sig**2

    def cost(rv, w, xv):
        with np.errstate(over="ignore"):  # a wild trial step costs inf and is rejected
            c = 0.5 * np.sum(w * rv * rv)
        for idx, center, P in priors:
            d = xv[idx] - center
            c += 0.5 * d @ P @ d
        return float(c)

    before = residual_stats(r)
    history = []
    lam = 1e-3
    w = weights(r)
    c = cost(r, w, x)
    history.append({"iteration": 0, "cost": c, "rms": before["rms"], "values": params.values_with(x)})
    converged = False
    n_inv_diag = None  # diag(N⁻¹) of the first step: the stop rule's σ scale (N hardly changes after)
    for it in range(1, max_iter + 1):
        J = jac(x)
        N = _normal_matrix(J, w) if normal_fn is None else np.array(normal_fn(params.values_with(x)), float)
        g = J.T @ (w * r)
        for idx, center, P in priors:
            N[np.ix_(idx, idx)] += P
            g[idx] += P @ (x[idx] - center)
        if n_inv_diag is None:
            n_inv_diag = _inverse_diagonal(N)
        dN = np.diag(N).copy()
        dN[dN <= 0] = 1.0
        for _ in range(12):
            dx = -_solve_damped(N + lam * np.diag(dN), g)
            r_new = evaluate(x + dx)
            c_new = cost(r_new, w, x + dx)
            if np.isfinite(c_new) and c_new <= c:
                break
            lam *= 10.0
        else:
            break  # no descent possible: at the minimum to machine precision
        x, r = x + dx, r_new
        lam = max(lam / 10.0, 1e-12)
        w = weights(r)
        c_prev, c = c, cost(r, w, x)
        history.append({"iteration": it, "cost": c, "rms": residual_stats(r)["rms"], "lambda": lam, "values": params.values_with(x)})
        if progress:
            progress(it, c)
        steps = np.array([p.diff_step for p in free])
        if (np.all(np.abs(dx) < tol + 1e-4 * steps) or abs(c_prev - c) <= tol * max(c, 1e-300)
                or np.all(np.abs(dx) <= STEP_IN_SIGMA * np.sqrt(n_inv_diag * 2.0 * c / max(n + n_prior - len(free), 1)))):
            converged = True
            break

    J = jac(x)
    N = _normal_matrix(J, w) if normal_fn is None else np.array(normal_fn(params.values_with(x)), float)
    for idx, _, P in priors:
        N[np.ix_(idx, idx)] += P
    # effective redundancy: down-weighted observations count by their relative weight
    dof = max(float(np.sum(w * sig**2)) + n_prior - len(free), 1.0)
    sigma0_sq = 2.0 * cost(r, w, x) / dof
    # the covariance is N⁻¹ scaled by σ0²; with priors (absolute σ) only upwards: σ0 < 1 there
    # says the priors were generous (a smooth trajectory error under a rough Gauss–Markov
    # prior), not that the parameters are better known than the priors allow
    factor = sigma0_sq if n_prior == 0 else max(sigma0_sq, 1.0)
    sol = Solution.from_normal_matrix(
        params.updated(x), N, sigma0_sq, dof, variance_factor=factor,
        residuals=r, weights=w * sig**2, before=before, history=history, converged=converged,
        jacobian=J,
    )
    groupings = [] if clusters is None else clusters if isinstance(clusters, list) else [clusters]
    if groupings:
        scores = sp.diags(w * r) @ J  # per observation ∂cost/∂θ (dense or sparse like J)
        Ninv = sol.covariance / factor if factor > 0 and np.all(np.isfinite(sol.covariance)) else np.linalg.pinv(N)
        for grouping in groupings:
            sol.covariance = _cluster_robust(sol.covariance, Ninv, scores, np.asarray(grouping))
    return sol


def _inverse_diagonal(N: np.ndarray) -> np.ndarray:
    """diag(N⁻¹), ≥ 0 (zeros when N is not positive definite: the stop rule then never fires on it)."""
    inv = cholesky_inverse(N)
    return np.zeros(N.shape[0]) if inv is None else np.clip(np.diag(inv), 0, None)


def _solve_damped(A: np.ndarray, g: np.ndarray) -> np.ndarray:
    """A⁻¹g for the damped normal matrix (Cholesky; least squares when it is not positive definite)."""
    try:
        return sl.cho_solve(sl.cho_factor(A, lower=True), g)
    except (np.linalg.LinAlgError, ValueError):
        return np.linalg.lstsq(A, g, rcond=None)[0]


def _prior_groups(free, prior_correlation) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Priors as (free-parameter positions, centres, precision matrix) groups: the correlated
    groups given, and the other parameters with a prior_sigma as one diagonal group."""
    pos = {p.name: i for i, p in enumerate(free)}
    out, joint = [], set()
    for names, R in prior_correlation:
        idx = np.array([pos[nm] for nm in names], dtype=int)
        if any(free[i].prior_sigma is None for i in idx):
            raise ValueError("prior_correlation: every parameter of a group needs a prior_sigma")
        d = np.array([free[i].prior_sigma for i in idx])
        out.append((idx, np.array([free[i].prior_center for i in idx]), np.linalg.inv(np.asarray(R, float)) / np.outer(d, d)))
        joint.update(idx.tolist())
    idx = np.array([i for i, p in enumerate(free) if p.prior_sigma is not None and i not in joint], dtype=int)
    if idx.size:
        out.append((idx, np.array([free[i].prior_center for i in idx]),
                    np.diag([1.0 / free[i].prior_sigma ** 2 for i in idx])))
    return out


def _normal_matrix(J, w: np.ndarray) -> np.ndarray:
    """JᵀWJ (dense) for a dense or scipy.sparse J."""
    if sp.issparse(J):
        J = J.tocsr()
        return _weighted_gram(J.indptr, J.indices, J.data, np.asarray(w, float), J.shape[1])
    return J.T @ (w[:, None] * J)


@njit(cache=True)
def _weighted_gram(indptr, indices, data, w, n_cols):  # pragma: no cover - numba
    """Σ_rows w_i · j_i j_iᵀ of a CSR matrix into a dense (n_cols, n_cols) array: O(Σ nnz_row²)
    over each row's pairs of entries once (upper triangle, then mirrored), without the sparse
    product's intermediate matrices. Repeated column indices within a row count as their sum."""
    N = np.zeros((n_cols, n_cols))
    for i in range(indptr.size - 1):
        for a in range(indptr[i], indptr[i + 1]):
            ja, va = indices[a], w[i] * data[a]
            N[ja, ja] += va * data[a]
            for b in range(a + 1, indptr[i + 1]):
                jb, v = indices[b], va * data[b]
                if ja < jb:
                    N[ja, jb] += v
                elif jb < ja:
                    N[jb, ja] += v
                else:  # the same column twice: (a, b) and (b, a)
                    N[ja, ja] += 2.0 * v
    for j in range(n_cols):
        for k in range(j + 1, n_cols):
            N[k, j] = N[j, k]
    return N


def _cluster_robust(cov: np.ndarray, Ninv: np.ndarray, scores: np.ndarray, clusters: np.ndarray) -> np.ndarray:
    """``cov`` with each σ raised to the cluster-robust (sandwich) σ where that is larger; correlations kept.

    clusters (n,) one group per observation, or (n, 2) two groups (dyadic): the "meat" sums
    s_i s_jᵀ over observation pairs sharing a group = Σ_groups S_g S_gᵀ − Σ_dyads S_d S_dᵀ.
    """
    c = np.asarray(clusters).reshape(scores.shape[0], -1)
    nodes, g = np.unique(c, return_inverse=True)
    g = g.reshape(c.shape)
    G = nodes.size
    if G < 2 or not np.all(np.isfinite(cov)):
        return cov

    def group_sums(labels, n_groups):  # Σ of the scores per group, (n_groups, p) dense
        member = sp.csr_matrix((np.ones(labels.size), (labels, np.arange(labels.size))), shape=(n_groups, labels.size))
        return np.asarray((member @ scores).todense()) if sp.issparse(scores) else member @ scores

    S = sum(group_sums(g[:, col], G) for col in range(c.shape[1]))
    meat = S.T @ S
    if c.shape[1] == 2:  # observations sharing both groups were counted twice
        _, d = np.unique(np.sort(g, axis=1), axis=0, return_inverse=True)
        D = group_sums(d.ravel(), int(d.max()) + 1)
        meat -= D.T @ D
    sand = np.sum((Ninv @ meat) * Ninv.T, axis=1) * G / (G - 1)  # diag(N⁻¹ · meat · N⁻¹)
    d = np.maximum(np.diag(cov), 1e-300)
    scale = np.sqrt(np.maximum(sand, d) / d)
    return cov * np.outer(scale, scale)
