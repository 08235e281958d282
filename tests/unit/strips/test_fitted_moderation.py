"""The tie planes' scatter moderated toward a prior fitted to the pair's rows (Smyth 2004, section 6.2):
the prior is recovered from simulated variances, rows of one variance pool fully, and rows on two kinds
of surface keep their own (the fixed-weight moderation toward the mean over-states the quiet ones)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.strips.correspond import fitted_moderated_variance, fitted_prior, moderated_variance


def test_prior_recovered_from_scaled_inverse_chi2_variances():
    """True variances from a scaled inverse-χ² (d0 = 6, s0² = 1e-4), each row's s² from ν = 9 degrees
    of freedom: the fitted d0 within 25 %, s0² within 10 % (20 000 rows)."""
    rng = np.random.default_rng(3)
    n, nu, d0, s02 = 20_000, 9.0, 6.0, 1e-4
    true = d0 * s02 / rng.chisquare(d0, n)
    s2 = true * rng.chisquare(nu, n) / nu
    fit_d0, fit_s02 = fitted_prior(s2, np.full(n, nu))
    assert fit_d0 == pytest.approx(d0, rel=0.25)
    assert fit_s02 == pytest.approx(s02, rel=0.10)


def test_rows_of_one_variance_pool():
    """Every row with σ² = 1e-4: the spread of the s² is sampling only, the prior's d0 large (or
    infinite) and each moderated variance within 15 % of the truth."""
    rng = np.random.default_rng(4)
    s2 = 1e-4 * rng.chisquare(9, 3000) / 9
    d0, s02 = fitted_prior(s2, 9.0)
    assert d0 > 50 and s02 == pytest.approx(1e-4, rel=0.05)
    assert np.all(np.abs(fitted_moderated_variance(s2, 9.0) / 1e-4 - 1) < 0.15)


def test_two_surfaces_keep_their_own_variance():
    """Half the rows on roofs (σ 5 mm), half on a rough band (σ 30 mm): moderated toward the fitted prior
    each kind's mean variance is within 35 % of its own; toward the mean with ν0 = 20 the roofs' is over
    10× theirs (their σ over-stated > 3×: the calibrator's σ for what roofs determine, conservative)."""
    rng = np.random.default_rng(5)
    n, nu = 2000, 9.0
    true = np.where(np.arange(n) < n // 2, 0.005**2, 0.03**2)
    s2 = true * rng.chisquare(nu, n) / nu
    roofs = np.arange(n) < n // 2
    fitted = fitted_moderated_variance(s2, nu)
    for kind in (roofs, ~roofs):
        assert np.mean(fitted[kind]) / true[kind][0] == pytest.approx(1.0, abs=0.35)
    assert np.mean(moderated_variance(s2, nu)[roofs]) / 0.005**2 > 10


def test_expected_variances_of_a_plan():
    """A plan's rows hold expected variances (no sampling spread): ``sampled=False`` takes all their
    spread as true, so two kinds stay apart; one kind pools to itself."""
    v = np.r_[np.full(100, 0.005**2), np.full(100, 0.03**2)]
    out = fitted_moderated_variance(v, 9.0, sampled=False)
    assert out[0] < 0.5 * out[-1]
    assert fitted_moderated_variance(np.full(50, 1e-4), 9.0, sampled=False) == pytest.approx(1e-4)
