"""A row's variance as the posterior mean under a prior fitted to the pair's rows (issue 26)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.strips.correspond import moderated_variance
from calidar.strips.row_variance import fitted_prior, posterior_variance


def _rows(rng, n, d0, s02, nu):
    """True variances from a scaled inverse χ²(d0, s0²), each row's own estimate from ν degrees of freedom,
    and a residual with the true variance (independent of the estimate, as for Gaussian noise)."""
    tau2 = d0 * s02 / rng.chisquare(d0, n)
    s2 = tau2 * rng.chisquare(nu, n) / nu
    return tau2, s2, np.sqrt(tau2) * rng.standard_normal(n)


def test_the_prior_of_heterogeneous_rows_is_recovered():
    rng = np.random.default_rng(3)
    _, s2, _ = _rows(rng, 40_000, 4.0, 1e-5, 9)
    d0, s02 = fitted_prior(s2, np.full(s2.size, 9.0))
    assert d0 == pytest.approx(4.0, rel=0.1)
    assert s02 == pytest.approx(1e-5, rel=0.05)


def test_rows_of_one_variance_pool_fully():
    rng = np.random.default_rng(4)
    s2 = 4e-6 * rng.chisquare(9, 5000) / 9
    v = posterior_variance(s2, 9)
    assert np.ptp(v) == 0.0 and v[0] == pytest.approx(4e-6, rel=0.03)


@pytest.mark.parametrize("d0", [3.0, 8.0])
def test_residuals_scatter_as_the_rows_variance_says_quiet_or_rough(d0):
    """Every quartile of the stated variance: mean r²/variance ≈ 1. Moderated toward the pair's mean
    (ν0 = 20) the quiet rows' residuals fall well short of their σ and the rough ones' exceed them."""
    rng = np.random.default_rng(int(d0))
    _, s2, r = _rows(rng, 200_000, d0, 1e-5, 9)
    for var, honest in ((posterior_variance(s2, 9), True), (moderated_variance(s2, 9), False)):
        q = np.digitize(var, np.quantile(var, [0.25, 0.5, 0.75]))
        ratio = np.array([np.mean(r[q == k] ** 2 / var[q == k]) for k in range(4)])
        if honest:
            assert np.all(np.abs(ratio - 1) < 0.06), ratio
        else:
            assert ratio[0] < 0.85 and ratio[3] > 1.1, ratio


def test_few_rows_fall_back_to_the_pair_mean():
    v = posterior_variance(np.array([1e-6, 4e-6, 9e-6]), 9)
    assert np.all(np.isfinite(v)) and np.all(v > 0)
    assert posterior_variance(np.zeros(0), 9).size == 0


def test_satterthwaite_degrees_of_freedom():
    from calidar.strips.row_variance import satterthwaite

    v, nu = np.array([1.0, 1.0]), np.array([10.0, 10.0])
    assert satterthwaite([v, v], [nu, nu]) == pytest.approx([20.0, 20.0])
    assert satterthwaite([v, v], [nu, np.full(2, np.inf)]) == pytest.approx([40.0, 40.0])  # a known term dilutes
    assert np.all(np.isinf(satterthwaite([v], [np.full(2, np.inf)])))


@pytest.mark.parametrize("nu", [6.0, 12.0, 40.0])
def test_consistency_of_the_robust_sigma0_for_student_t_rows(nu):
    """The factor equals the engine's σ0² (MAD scale, Cauchy weights) over 400 000 unit-variance t residuals."""
    from calidar.adjust.solver import robust_weights
    from calidar.strips.row_variance import consistency

    z = np.random.default_rng(int(nu)).standard_t(nu, 400_000) * np.sqrt((nu - 2) / nu)
    s = 1.4826 * np.median(np.abs(z))
    w = robust_weights(z / s, "cauchy")
    assert consistency("cauchy", [nu]) == pytest.approx(np.sum(w * z * z) / np.sum(w), rel=0.006)
    assert consistency("cauchy") == pytest.approx(0.794, abs=0.002)  # normal residuals


def test_prior_with_digamma_per_distinct_dof_is_the_same_numbers():
    """The fitted prior evaluates digamma and trigamma once per distinct degrees of freedom, the
    trigamma as ζ(2, x) (issue 32, eleventh session): d0 and s0² are bit for bit those of scipy's
    digamma and polygamma over every row and in the bisection."""
    from scipy.special import digamma, polygamma

    rng = np.random.default_rng(32)
    dof = rng.integers(1, 40, 5000)
    s2 = 1e-4 * rng.chisquare(dof) / dof * rng.lognormal(0.0, 0.5, dof.size)
    d = dof.astype(float)
    e = np.log(s2) - (digamma(d / 2) - np.log(d / 2))
    excess = float(np.var(e, ddof=1) - np.mean(polygamma(1, d / 2)))
    assert excess > 0
    from calidar.strips.row_variance import MIN_PRIOR_DOF

    lo, hi = 1e-6, 1e8  # the bisection for ψ'(x) = excess with scipy's polygamma, as before
    for _ in range(80):
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if polygamma(1, mid) > excess else (lo, mid)
    d0 = max(2.0 * float(np.sqrt(lo * hi)), MIN_PRIOR_DOF)
    want = (d0, float(np.exp(np.mean(e) + digamma(d0 / 2) - np.log(d0 / 2))))
    assert fitted_prior(s2, dof) == want


def test_trigamma_is_scipys_polygamma_bit_for_bit():
    """ψ' as ζ(2, x) (issue 32, eleventh session: the prior's bisection calls it 80 times a side of
    a pair) gives scipy's ``polygamma(1, x)`` to the last bit, scalars and arrays, over the
    bisection's whole range 1e-6 … 1e8 — the rows' σ must not move."""
    from scipy.special import polygamma

    from calidar.strips.row_variance import _trigamma_inverse, trigamma

    x = np.geomspace(1e-6, 1e8, 20_001) * np.random.default_rng(4).uniform(0.5, 1.5, 20_001)
    np.testing.assert_array_equal(trigamma(x), polygamma(1, x))
    for v in x[::97]:
        assert float(trigamma(v)) == float(polygamma(1, v))
    for y in (1e-7, 0.01, 0.37, 2.0, 50.0, 1e6):  # the inverse still inverts
        assert float(polygamma(1, _trigamma_inverse(y))) == pytest.approx(y, rel=1e-9)
