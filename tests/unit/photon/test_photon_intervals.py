"""Profile-likelihood intervals that do not depend on the curvature σ they start from, σ taken from
them, the small-sample level with few CCRs, and a verdict that says when no honest interval exists
(issue 26: 2-CCR passes covered the truth 85.7 % of the time with the former intervals)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from calidar.photon.checks import _loss_at_zero_with_few_ccrs, _precision
from calidar.photon.fit import Bounds, Layout, Problem, maximise
from calidar.photon.likelihood import Shots, count_distribution, simulate_counts
from calidar.photon.search import SearchSettings
from calidar.photon.uncertainty import (CHI2_95, ROOT_TOLERANCE, SMALL_SAMPLE_LEVEL, Interval, Uncertainty,
                                        interval_level, profile_interval, profile_nll, sigma_from_profile)

BIAS = "along_track_bias"
TRUTH = {"along_track_bias": 0.6, "cross_track_bias": -0.9, "footprint_diameter": 11.0, "ccr_peak_photons": 20.0,
         "shot_loss_rate": 0.33}


def two_ccr_problem(seed: int) -> Problem:
    """Model-drawn counts of two CCR windows (±17.5 m of 0.7 m shots, one strong beam) at ±0.7 of the
    footprint radius from its track: the layout of `calidar simulate photons --n-ccr 2`."""
    x = np.arange(-17.5, 17.5, 0.7)
    ys = TRUTH["cross_track_bias"] + np.array([-0.7, 0.7]) * 5.5
    n, m = x.size, ys.size
    s = Shots(np.tile(x, m), np.zeros(n * m), np.repeat(ys, n), np.full(n * m, 0.02), np.zeros(n * m, np.int64),
              np.zeros(n * m, np.int64), np.full(n * m, 16), np.repeat(np.arange(m), n))
    lay = Layout(("gt1l",))
    p, _ = count_distribution(lay.theta(TRUTH), s, 0.3)
    return Problem(s.with_counts(simulate_counts(p, np.random.default_rng(seed))), lay, 0.3)


def result_of(fit, prob, segments=(), profile=None):
    """The parts of a CCRResult the interval code reads."""
    return SimpleNamespace(solution=fit.solution, problem=prob, settings=SearchSettings(),
                           estimate=SimpleNamespace(fit=fit, segments=list(segments)),
                           layout=prob.layout, uncertainty=Uncertainty(fit.solution.parameters.free_names, {}, {},
                                                                       profile=profile or {}))


@pytest.fixture(scope="module")
def two_chords():
    """Model-drawn counts of two CCRs at ±0.7 of the footprint radius (the 2-CCR passes' layout)."""
    prob = two_ccr_problem(4)
    fit = maximise(prob, dict(TRUTH), Bounds(8.0, 15.0, 10.0))
    return prob, fit, profile_interval(result_of(fit, prob), BIAS)


def with_sigma_scaled(fit, factor):
    sol = fit.solution
    return replace(fit, solution=replace(sol, covariance=sol.covariance * factor**2))


@pytest.mark.parametrize("factor", [1.0, 30.0, 0.02])
def test_the_interval_ends_where_the_deviance_reaches_the_level_whatever_sigma_it_starts_from(two_chords, factor):
    prob, fit, reference = two_chords
    result = result_of(with_sigma_scaled(fit, factor), prob)
    iv = profile_interval(result, BIAS)
    assert not (iv.open_low or iv.open_high or iv.failed)
    assert iv.low < fit.solution.values[BIAS] < iv.high
    for end in (iv.low, iv.high):
        nll, _ = profile_nll(result, {BIAS: end}, fit.solution.values)
        root = np.sqrt(2 * (nll - fit.nll))
        assert abs(root - np.sqrt(CHI2_95[1])) < 2 * ROOT_TOLERANCE, (end, root)
    # the same interval from a σ 30× too wide or 50× too narrow
    np.testing.assert_allclose((iv.low, iv.high), (reference.low, reference.high), atol=0.03)


def test_sigma_is_the_profile_intervals_wider_half_with_correlations_kept(two_chords):
    prob, fit, _ = two_chords
    sol = replace(fit.solution, covariance=fit.solution.covariance.copy())
    v, s = sol.values, sol.sigma
    cross, diam = "cross_track_bias", "footprint_diameter"
    profile = {BIAS: Interval(v[BIAS] - 2.5 * s[BIAS], v[BIAS] + 3.0 * s[BIAS]),  # wider half 3σ: σ × 3/1.96
               cross: Interval(v[cross] - 1.5 * s[cross], v[cross] + s[cross]),  # a flatter curvature: σ × 1.5/1.96
               diam: Interval(v[diam] - s[diam], v[diam] + 1.2 * s[diam], open_high=True)}  # open: never narrowed
    corr = sol.correlation.copy()
    changed = sigma_from_profile(result_of(replace(fit, solution=sol), prob, profile=profile))
    assert set(changed) == {BIAS, cross}
    assert sol.sigma[BIAS] == pytest.approx(3.0 / 1.96 * s[BIAS])
    assert sol.sigma[cross] == pytest.approx(1.5 / 1.96 * s[cross])
    assert sol.sigma[diam] == pytest.approx(s[diam])
    np.testing.assert_allclose(sol.correlation, corr, atol=1e-12)
    assert changed[BIAS] == pytest.approx((s[BIAS], 3.0 / 1.96 * s[BIAS]))


def test_few_ccrs_take_the_small_sample_level(two_chords):
    prob, fit, _ = two_chords
    seg = lambda g: SimpleNamespace(window=SimpleNamespace(group=g))  # noqa: E731
    assert interval_level(result_of(fit, prob, [seg(0)] * 2), BIAS) == pytest.approx(CHI2_95[1] * SMALL_SAMPLE_LEVEL)
    assert interval_level(result_of(fit, prob, [seg(0)] * 4), BIAS) == CHI2_95[1]


def test_an_interval_without_a_profile_maximum_is_a_warning_not_a_narrow_sigma(two_chords):
    prob, fit, _ = two_chords
    v = fit.solution.values
    profile = {k: Interval(v[k] - 0.4, v[k] + 0.4) for k in ("along_track_bias", "cross_track_bias")}
    profile["footprint_diameter"] = Interval(v["footprint_diameter"] - 0.01, v["footprint_diameter"] + 0.8, failed=True)
    findings = {f.check: f for f in _precision(result_of(fit, prob, profile=profile))}
    assert findings["footprint_diameter"].status == "warn"
    assert "no honest interval" in findings["footprint_diameter"].detail
    assert findings["along_track_bias"].status == "pass"


@pytest.mark.parametrize("q, lit, warned", [(2e-6, 2, True), (0.0, 3, True), (0.3, 2, False), (0.0, 5, False)])
def test_a_loss_rate_run_to_zero_with_few_ccrs_says_no_honest_interval(two_chords, q, lit, warned):
    prob, fit, _ = two_chords
    result = result_of(fit, prob, [SimpleNamespace(window=SimpleNamespace(group=0))] * lit)
    result.solution = SimpleNamespace(values={**fit.solution.values, "shot_loss_rate": q})
    found = _loss_at_zero_with_few_ccrs(result)
    assert bool(found) == warned
    if warned:
        assert found[0].status == "warn" and "no honest interval" in found[0].detail
