"""The linear algebra of the normal equations the engine (:mod:`calidar.adjust.solver`) solves:
the weighted Gram matrix JᵀWJ of a dense or sparse Jacobian, the Levenberg–Marquardt damped
system N + diag(λ) and its solution, diag(N⁻¹) for the stop rule, and the cluster-robust
(sandwich) σ of a solution (Cameron, Gelbach & Miller 2011 for two-way clusters)."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sl
import scipy.sparse as sp
from numba import njit

from calidar.adjust.solution import cholesky_inverse


def inverse_diagonal(N: np.ndarray) -> np.ndarray:
    """diag(N⁻¹), ≥ 0 (zeros when N is not positive definite: the stop rule then never fires on
    it)."""
    inv = cholesky_inverse(N)
    return np.zeros(N.shape[0]) if inv is None else np.clip(np.diag(inv), 0, None)


def damped(N: np.ndarray, add: np.ndarray) -> np.ndarray:
    """N + diag(add), without building the dense diagonal matrix (the same sums)."""
    A = N.copy()
    A[np.diag_indices_from(A)] += add
    return A


def solve_damped(A: np.ndarray, g: np.ndarray) -> np.ndarray:
    """A⁻¹g for the damped normal matrix (Cholesky; least squares when it is not positive
    definite)."""
    try:
        return sl.cho_solve(sl.cho_factor(A, lower=True), g)
    except (np.linalg.LinAlgError, ValueError):
        return np.linalg.lstsq(A, g, rcond=None)[0]


def normal_matrix(J, w: np.ndarray) -> np.ndarray:
    """JᵀWJ (dense) for a dense or scipy.sparse J."""
    if sp.issparse(J):
        J = J.tocsr()
        return weighted_gram(J.indptr, J.indices, J.data, np.asarray(w, float), J.shape[1])
    return J.T @ (w[:, None] * J)


@njit(cache=True)
def weighted_gram(indptr, indices, data, w, n_cols):  # pragma: no cover - numba
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


def cluster_robust(cov: np.ndarray, Ninv: np.ndarray, scores: np.ndarray,
                   clusters: np.ndarray) -> np.ndarray:
    """``cov`` with each σ raised to the cluster-robust (sandwich) σ where that is larger;
    correlations kept.

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
        entries = (np.ones(labels.size), (labels, np.arange(labels.size)))
        member = sp.csr_matrix(entries, shape=(n_groups, labels.size))
        return np.asarray((member @ scores).todense()) if sp.issparse(scores) else member @ scores

    S = sum(group_sums(g[:, col], G) for col in range(c.shape[1]))
    sand = np.sum((Ninv @ S.T) ** 2, axis=1)  # diag(N⁻¹ SᵀS N⁻¹), O(p² G) for G groups
    if c.shape[1] == 2:  # observations sharing both groups were counted twice
        _, d = np.unique(np.sort(g, axis=1), axis=0, return_inverse=True)
        sand -= np.sum((Ninv @ group_sums(d.ravel(), int(d.max()) + 1).T) ** 2, axis=1)
    sand *= G / (G - 1)
    d = np.maximum(np.diag(cov), 1e-300)
    scale = np.sqrt(np.maximum(sand, d) / d)
    return cov * np.outer(scale, scale)
