"""An estimated variance factor's own uncertainty carried into a parameter's σ (issue 26): on a
linear problem whose factor is known, the stated σ must match the parameter's actual errors."""

import numpy as np
import pytest

from calidar.adjust.variance_carry import carried_covariance, posterior_multipliers, solve_scaled
from calidar.adjust.variance_components import OBSERVATIONS, PriorBlock, estimate_components
from calidar.adjust.variance_elements import estimate_elements

TRUE_FACTOR = 2.0  # the priors' true σ against their stated σ of 1


def _draw(rng, n_strips, per_strip=20, noise=0.1):
    """A mounting offset b seen with each strip's own offset tⱼ (stated σ 1, true σ 2) and a tilt c
    seen across each strip: yᵢⱼ = b + c·uᵢ + tⱼ + e. b is separated from the tⱼ only by their priors:
    its σ is ≈ the factor · 1/√n_strips, known as well as the factor is. Returns per parameter (b, c)
    the error, the plug-in σ, the carried σ, and the effective number m behind the factor."""
    strip = np.repeat(np.arange(n_strips), per_strip)
    u = np.tile(np.linspace(-1.0, 1.0, per_strip), n_strips)
    truth = np.array([0.3, -0.2])
    t = rng.normal(0.0, TRUE_FACTOR, n_strips)
    y = truth[0] + truth[1] * u + t[strip] + rng.normal(0.0, noise, strip.size)
    J = np.zeros((strip.size, n_strips + 2))
    J[:, 0], J[:, 1] = 1.0, u
    J[np.arange(strip.size), strip + 2] = 1.0
    w = np.full(strip.size, noise**-2)
    x0, r0 = np.zeros(n_strips + 2), -y  # linearised at 0: r = J x − y
    JtWJ, JtWr = J.T @ (w[:, None] * J), J.T @ (w * r0)
    idx = np.arange(2, n_strips + 2)
    comps = estimate_components(JtWJ, JtWr, float(r0 @ (w * r0)), float(strip.size), x0,
                                [PriorBlock(idx, np.zeros(n_strips), np.eye(n_strips), "t")], marginal=True, tol=1e-4)
    labels = [None, None] + ["t"] * n_strips
    obs = comps.variance[OBSERVATIONS]
    m = estimate_elements(JtWJ, JtWr, x0, [(idx, np.zeros(n_strips), np.eye(n_strips))], labels,
                          {"t": comps.variance["t"]}, observations=obs, max_iter=1).effective["t"]
    priors = [(idx, np.zeros(n_strips), np.eye(n_strips) / comps.variance["t"])]  # at the estimated level
    keep = np.array([0, 1])
    x, _ = solve_scaled(JtWJ, JtWr, x0, priors, np.ones(n_strips + 2), keep, obs)
    Q, delta = carried_covariance(JtWJ, JtWr, x0, priors, labels, {"t": m}, keep, obs)
    return x - truth, np.sqrt(np.diag(Q)), np.sqrt(np.diag(Q + delta)), m


def _runs(n_strips, draws, seed):
    rng = np.random.default_rng(seed)
    out = [_draw(rng, n_strips) for _ in range(draws)]
    err, plug, carried, m = (np.array(v) for v in zip(*out))
    return err, plug, carried, m


def test_few_independent_priors_the_carried_sigma_matches_the_errors():
    # 6 strips: the factor rests on ≈ 5 independent priors (±32 %): the plug-in σ of b is too small
    err, plug, carried, m = _runs(6, 300, seed=11)
    assert 4.0 < np.median(m) < 6.0
    rms_plug = np.sqrt(np.mean((err[:, 0] / plug[:, 0]) ** 2))
    rms_carried = np.sqrt(np.mean((err[:, 0] / carried[:, 0]) ** 2))
    assert rms_plug > 1.1  # the plug-in σ: too small (RMS z 1.17 over these 300 draws, ±0.05)
    assert 0.88 < rms_carried < 1.08  # the carried σ: honest (0.97) within the 300 draws' ±0.05
    # the tilt c, which the strips' own data determine, keeps its σ
    np.testing.assert_allclose(carried[:, 1], plug[:, 1], rtol=0.01)


def test_many_independent_priors_the_sigma_is_unchanged():
    # 80 strips: m ≈ 79, the factor known to ±8 %: the σ widen by ≈ 1/(m − 2) / 2 < 2 %
    err, plug, carried, m = _runs(80, 20, seed=12)
    assert np.all(m > 60)
    widening = carried[:, 0] / plug[:, 0]
    assert np.all(widening >= 1.0) and np.all(widening < 1.03)


@pytest.mark.parametrize("m", [3.0, 10.0, 100.0])
def test_posterior_multipliers_mean(m):
    # equal-weight quadrature of σ̂²·m/χ²_m: its mean approaches m/(m − 2) (the inverse χ²'s mean)
    mean = float(np.mean(posterior_multipliers(m)))
    exact = m / (m - 2.0)
    assert mean == pytest.approx(exact, rel=0.35 if m < 5 else 0.05)
    assert mean >= 1.0


@pytest.mark.parametrize("m", [2.5, 3.0, 7.25, 100.0, 12345.6])
def test_posterior_multipliers_are_scipy_stats_quantiles_bit_for_bit(m):
    # the quantiles by scipy.special (no scipy.stats import, issue 32) equal scipy.stats.chi2.ppf's
    from scipy.stats import chi2

    from calidar.adjust.variance_carry import QUANTILES

    expected = m / chi2.ppf(np.array(QUANTILES), m)
    assert np.array_equal(posterior_multipliers(m), expected)
