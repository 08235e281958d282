"""The robust fit's covariance from the M-estimator sandwich (calidar.adjust.m_estimator; issue 26)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from calidar.adjust import Parameter, ParameterSet, SolverOptions, estimate, solve
from calidar.adjust.m_estimator import normal_psi_square, psi, sandwich_covariance, small_sample_factor
from calidar.adjust.residuals import FunctionProblem
from calidar.adjust.solver import robust_weights


def _line(y: np.ndarray, x: np.ndarray, sigma: float, absolute: bool = False, prior: float | None = None):
    """y = a + b·x with row σ ``sigma``; ``prior``: a prior σ on both (σ then absolute too)."""
    params = ParameterSet([Parameter("a", 0.0, "m", prior_sigma=prior), Parameter("b", 0.0, "1", prior_sigma=prior)])
    return FunctionProblem(lambda v: v["a"] + v["b"] * x - y, params, sigma=sigma, absolute_sigma=absolute)


def _heavy(rng, n: int) -> np.ndarray:
    """Standardised residuals whose σ are right in the mean, not row by row (as VGICP's rows at the truth,
    tests/unit/adjust/test_unit_weight.py): a normal scale mixture with E[z²] = 1 times Student t."""
    v = np.where(rng.random(n) < 0.9, 0.75, 3.25)
    nu = rng.choice([9.0, 12.0, 30.0], n)
    return np.sqrt(v) * rng.standard_t(nu) * np.sqrt((nu - 2) / nu)


@pytest.mark.parametrize("absolute, prior, scale", [(False, None, 1.0), (True, None, 0.6), (True, None, 1.7),
                                                    (True, 0.05, 1.3), (True, 0.05, 0.8)])
def test_for_least_squares_the_sandwich_is_the_variance_factor_times_n_inverse(absolute, prior, scale):
    """ψ(u) = u, ψ' = 1: A = B = N, the level is σ0², so the sandwich is the IRLS covariance (σ0²·N⁻¹ relative,
    max(σ0², 1)·N⁻¹ absolute or with priors: rows below or above their σ) to rounding."""
    rng = np.random.default_rng(3)
    x = np.linspace(-1.0, 1.0, 40)
    y = 1.0 + 2.0 * x + 0.01 * scale * rng.standard_normal(x.size)
    irls = solve(_line(y, x, 0.01, absolute, prior), SolverOptions(robust=None))
    sand = solve(_line(y, x, 0.01, absolute, prior), SolverOptions(robust=None, covariance="sandwich"))
    assert sand.extra["covariance"]["model"] == "sandwich"
    assert sand.extra["covariance"]["normal_psi_square"] == 1.0 and sand.extra["covariance"]["huber_k"] == 1.0
    np.testing.assert_allclose(sand.covariance, irls.covariance, rtol=1e-10, atol=1e-10 * irls.covariance.max())
    assert sand.values == irls.values and sand.sigma0 == irls.sigma0  # the estimate and global test untouched


def test_the_pieces_reduce_to_least_squares():
    u = np.linspace(-5.0, 5.0, 11)
    p, dp = psi(u, None, 1.0)
    assert np.array_equal(p, u) and np.array_equal(dp, np.ones_like(u))
    assert normal_psi_square(None, 1.0, 0.7) == 1.0 and small_sample_factor(dp, 5, 100.0) == 1.0
    J = np.random.default_rng(1).standard_normal((30, 3))
    N = J.T @ J
    cov, bread = sandwich_covariance(N, N)
    np.testing.assert_allclose(cov, np.linalg.inv(N), rtol=1e-12)
    np.testing.assert_allclose(bread, np.linalg.inv(N), rtol=1e-12)


@pytest.mark.parametrize("kind, k", [("cauchy", 2.385), ("huber", 1.345)])
def test_psi_is_the_weights_times_u_and_its_derivative_is_psi_prime(kind, k):
    u = np.linspace(-6.0, 6.0, 1201) + 1e-3  # off Huber's kinks
    p, dp = psi(u, kind, k)
    np.testing.assert_allclose(p, robust_weights(u, kind, k) * u, rtol=1e-14)
    h = 1e-6
    numeric = (psi(u + h, kind, k)[0] - psi(u - h, kind, k)[0]) / (2 * h)
    np.testing.assert_allclose(dp, numeric, atol=1e-7)
    z = np.random.default_rng(2).standard_normal(400_000)  # c_ψ = E[s²ψ(z/s)²] against a sample
    for s in (0.8, 1.0, 1.3):
        assert normal_psi_square(kind, k, s) == pytest.approx(np.mean(s * s * psi(z / s, kind, k)[0] ** 2), rel=0.01)


def test_heavy_tailed_rows_the_sandwich_matches_the_spread_where_the_irls_covariance_is_too_wide():
    """A line fitted (Cauchy IRLS, absolute σ) to 200 rows whose σ are right in the mean but heavy-tailed, 300
    draws with a known truth: A⁻¹BA⁻¹ reads RMS z 1 within the draws' ±2/√(2·300) (1.01 / 1.04); the IRLS N⁻¹,
    which takes a row of weight w to vary as σ²/w, reads 0.89 / 0.92 on the same errors — its σ 1.13× the
    sandwich's (as VGICP's rows' share on UAV cross lines, 0.83–0.85). (On main, before issue 26's sandwich,
    SolverOptions has no covariance option: the test fails there.)"""
    rng = np.random.default_rng(5)
    x = np.linspace(-1.0, 1.0, 200)
    z = {"irls": [], "sandwich": []}
    n_draws = 300
    for _ in range(n_draws):
        y = 1.0 + 2.0 * x + 0.01 * _heavy(rng, x.size)
        est = estimate(_line(y, x, 0.01, absolute=True), SolverOptions(robust="cauchy", covariance="sandwich"))
        err = np.array([est.parameters["a"].value - 1.0, est.parameters["b"].value - 2.0])
        for model in z:
            sol = replace(est, options=replace(est.options, covariance=model)).solution()
            z[model].append(err / np.sqrt(np.diag(sol.covariance)))
    rms = {m: np.sqrt(np.mean(np.square(v), axis=0)) for m, v in z.items()}
    band = 2 / np.sqrt(2 * n_draws)
    assert np.all(rms["irls"] / rms["sandwich"] < 0.92) and np.all(rms["irls"] < 0.95), rms
    assert np.all(np.abs(rms["sandwich"] - 1.0) < band), rms


def test_a_misfit_still_widens_the_sigma_and_rows_below_their_sigma_do_not_narrow_them():
    """Absolute σ, 2 000 normal rows at 0.5, 1, 1.5 and 3 times their σ: the sandwich's σ are those of rows at
    their σ for 0.5 (the variance factor's floor at the global test's σ0) and grow as the rows for 1.5 and 3 (a
    wrong model is not hidden); the IRLS's grow only 1.34× for 1.5 (its weighted σ0 reads the rows low)."""
    x = np.linspace(-1.0, 1.0, 2000)
    sig = {}
    for scale in (0.5, 1.0, 1.5, 3.0):
        y = 1.0 + 2.0 * x + 0.01 * scale * np.random.default_rng(7).standard_normal(x.size)
        est = estimate(_line(y, x, 0.01, absolute=True), SolverOptions(robust="cauchy", covariance="sandwich"))
        sig[scale] = {m: replace(est, options=replace(est.options, covariance=m)).solution().sigma["b"]
                      for m in ("irls", "sandwich")}
    sand = {k: v["sandwich"] / sig[1.0]["sandwich"] for k, v in sig.items()}
    assert sand[0.5] == pytest.approx(1.0, abs=0.02)
    assert sand[1.5] == pytest.approx(1.5, rel=0.03) and sand[3.0] == pytest.approx(3.0, rel=0.05)
    assert sig[1.5]["irls"] / sig[1.0]["irls"] < 1.4
    ls = 0.01 / np.sqrt(np.sum((x - x.mean()) ** 2))  # least squares' σ_b for rows at their σ
    assert sig[1.0]["sandwich"] == pytest.approx(ls * np.sqrt(1.051), rel=0.02)  # the Cauchy's efficiency, 95 %
    assert sig[1.0]["irls"] > 1.03 * sig[1.0]["sandwich"]


def test_with_clusters_the_irls_sigma_is_recorded_beside_and_the_cluster_max_stays_on_top():
    """Rows correlated in 20 groups: the sandwich's σ are the cluster-robust max over its model part; the IRLS σ it
    records are those the IRLS covariance gives (the same clusters, bread N⁻¹)."""
    rng = np.random.default_rng(9)
    x = np.linspace(-1.0, 1.0, 400)
    groups = np.repeat(np.arange(20), 20)
    y = 1.0 + 2.0 * x + 0.01 * (_heavy(rng, x.size) + 2.0 * rng.standard_normal(20)[groups])
    opts = SolverOptions(robust="cauchy")
    irls = solve(_line(y, x, 0.01, absolute=True), opts, clusters=groups)
    sand = solve(_line(y, x, 0.01, absolute=True), replace(opts, covariance="sandwich"), clusters=groups)
    record = sand.extra["covariance"]
    for name in ("a", "b"):
        assert record["irls_sigma"][name] == pytest.approx(irls.sigma[name], rel=1e-12)
        assert sand.sigma[name] >= record["model_sigma"][name] * (1 - 1e-12)
    assert sand.sigma["a"] > 2 * record["model_sigma"]["a"]  # the groups' common errors dominate the mean
