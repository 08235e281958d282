"""Variance components (Förstner 1979; Koch 1999 §3.6) on a linear problem whose components are known."""

import numpy as np
import pytest

from calidar.adjust.variance_components import OBSERVATIONS, PriorBlock, estimate_components, split_blocks


def _problem(seed, s_obs=0.25, s_a=4.0, s_b=0.09, n_params=300, n_obs=1500):
    """Observations y = A x + e (σ² = s_obs at stated σ 1); priors x_a ~ N(0, s_a·Σ_a) with Σ_a a
    Gauss–Markov correlation (φ = 0.6) and x_b ~ N(0, s_b·I), both stated at variance factor 1."""
    rng = np.random.default_rng(seed)
    half = n_params // 2
    k = np.arange(half)
    R = 0.6 ** np.abs(k[:, None] - k[None, :])
    x = np.concatenate([np.linalg.cholesky(s_a * R) @ rng.standard_normal(half),
                        np.sqrt(s_b) * rng.standard_normal(n_params - half)])
    A = rng.standard_normal((n_obs, n_params)) * (rng.random((n_obs, n_params)) < 0.02)
    A[:, 0] += 1.0  # every observation sees one parameter: no column empty
    y = A @ x + np.sqrt(s_obs) * rng.standard_normal(n_obs)
    blocks = [PriorBlock(np.arange(half), np.zeros(half), np.linalg.inv(R), "a"),
              PriorBlock(np.arange(half, n_params), np.zeros(n_params - half), np.eye(n_params - half), "b")]
    # linearised at x0 = 0: r0 = A·0 − y
    return A.T @ A, A.T @ -y, float(y @ y), float(n_obs), np.zeros(n_params), blocks


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_components_recovered(seed):
    comps = estimate_components(*_problem(seed))
    assert comps.converged
    for g, truth in ((OBSERVATIONS, 0.25), ("a", 4.0), ("b", 0.09)):
        # the estimate of σ² has relative σ ≈ √(2/r): within 4 of those
        tol = 4.0 * np.sqrt(2.0 / comps.redundancy[g])
        assert abs(comps.variance[g] / truth - 1.0) < tol, (g, comps.variance[g], truth, comps.redundancy[g])
    # every redundancy counted: observations + priors − parameters
    assert sum(comps.redundancy.values()) == pytest.approx(1500 + 300 - 300, rel=1e-6)


def test_priors_the_data_do_not_check_have_no_redundancy():
    """Parameters no observation sees: their priors' redundancy is 0 and their factor stays as stated."""
    JtWJ, JtWr, rWr, n, x0, blocks = _problem(4)
    JtWJ = JtWJ.copy()
    hidden = blocks[1].index
    JtWJ[hidden, :] = 0.0
    JtWJ[:, hidden] = 0.0
    JtWr = JtWr.copy()
    JtWr[hidden] = 0.0
    comps = estimate_components(JtWJ, JtWr, rWr, n, x0, blocks)
    assert comps.redundancy["b"] == pytest.approx(0.0, abs=1e-6)
    assert comps.variance["b"] == 1.0


def test_fixed_group_and_floor():
    JtWJ, JtWr, rWr, n, x0, blocks = _problem(5, s_b=0.0)  # group b exactly at its centres
    comps = estimate_components(JtWJ, JtWr, rWr, n, x0, blocks, fixed=["a"], floor=1e-4, max_iter=400)
    assert comps.variance["a"] == 1.0 and comps.fixed == ("a",)
    assert comps.variance["b"] < 0.01  # driven down towards its floor


def test_split_blocks_by_group():
    P = np.diag([1.0, 2.0, 3.0])
    blocks = split_blocks([(np.array([0, 1, 2]), np.zeros(3), P)], ["x", None, "x"])
    assert [(b.group, b.index.tolist()) for b in blocks] == [("x", [0, 2]), ("other", [1])]
    with pytest.raises(ValueError):
        split_blocks([(np.array([0, 1]), np.zeros(2), np.ones((2, 2)) + np.eye(2))], ["x", "y"])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_marginal_form_recovers_the_components(seed):
    """The marginal form (the priors' own variances, as trajectory_level uses it) estimates the same
    components; its spread for the correlated group follows its effective number of independent
    priors, n(1 − φ)/(1 + φ) = 37.5 of 150 for φ = 0.6 (4 σ of that spread allowed)."""
    comps = estimate_components(*_problem(seed), marginal=True)
    assert comps.converged
    for g, truth, n_eff in ((OBSERVATIONS, 0.25, None), ("a", 4.0, 150 * 0.4 / 1.6), ("b", 0.09, None)):
        tol = 4.0 * np.sqrt(2.0 / (n_eff or comps.redundancy[g]))
        assert abs(comps.variance[g] / truth - 1.0) < tol, (g, comps.variance[g], truth)
