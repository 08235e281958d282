"""The exact count likelihood: a distribution, its score, its Fisher information, its sampler."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.photon.likelihood import (Shots, count_distribution, fisher_information, log_likelihood,
                                       simulate_counts)

THETA = np.array([[0.7, -1.0, 11.0, 20.0, 0.3], [-0.4, 0.5, 9.0, 6.0, 0.05]])  # b_a, b_c, D, Λ, q per beam


def shots(n=400, seed=0, background=0.05):
    rng = np.random.default_rng(seed)
    g = rng.integers(0, 2, n)
    channels = np.where(g == 0, 16, 4)
    beta = np.where(rng.random(n) < 0.3, 0.0, background)
    counts = np.minimum(rng.integers(0, 22, n), channels + np.where(beta > 0, 5, 0))  # possible counts only
    return Shots(rng.uniform(-17, 17, n), np.zeros(n), rng.choice([-4.0, 2.0], n), beta, counts, g, channels,
                 np.zeros(n, np.int64))


def test_count_distribution_sums_to_one_and_its_gradient_to_zero():
    p, dp = count_distribution(THETA, shots(), 0.3, 30)
    np.testing.assert_allclose(p.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(dp.sum(axis=1), 0.0, atol=1e-10)
    assert p.min() >= 0.0


@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_score_equals_finite_differences(jitter):
    """Including counts above the channels (background) and windows without background (β = 0)."""
    s = shots()
    logp, score = log_likelihood(THETA, s, jitter)
    assert np.isfinite(logp).all()
    for g in (0, 1):
        for i in range(5):
            h = 1e-6 * max(1.0, abs(THETA[g, i]))
            hi, lo = THETA.copy(), THETA.copy()
            hi[g, i] += h
            lo[g, i] -= h
            fd = (log_likelihood(hi, s, jitter)[0] - log_likelihood(lo, s, jitter)[0]) / (2 * h)
            mine = s.group == g
            np.testing.assert_allclose(score[mine, i], fd[mine], atol=2e-6 * max(1.0, np.abs(fd).max()))


def test_log_likelihood_matches_the_distribution_and_the_domain():
    s = shots()
    p, _ = count_distribution(THETA, s, 0.3, 40)  # (the table drops terms below 1e-15)
    pk = p[np.arange(len(s)), s.counts]
    kept = pk > 1e-12
    np.testing.assert_allclose(log_likelihood(THETA, s, 0.3)[0][kept], np.log(pk[kept]), rtol=1e-10)
    bad = THETA.copy()
    bad[0, 4] = -0.01  # q < 0 is outside the model
    assert np.all(np.isneginf(log_likelihood(bad, s, 0.3)[0][s.group == 0]))


def test_fisher_information_is_the_expected_score_outer_product():
    s = shots(200, seed=3)
    columns = np.array([[0, 1, 2, 3, 4], [5, 6, 7, 8, 9]])
    info = fisher_information(THETA, s, 0.3, columns, 10)
    p, dp = count_distribution(THETA, s, 0.3, 40)
    ref = np.zeros((10, 10))
    for g in (0, 1):
        m = s.group == g
        blk = np.einsum("ski,skj->ij", dp[m], dp[m] / np.clip(p[m], 1e-300, None)[:, :, None])
        ref[np.ix_(columns[g], columns[g])] += blk
    np.testing.assert_allclose(info, ref, rtol=1e-8, atol=1e-10)
    assert np.all(np.linalg.eigvalsh(info) > 0)


def test_simulated_counts_follow_the_distribution():
    s = shots(50, seed=1)
    p, _ = count_distribution(THETA, s, 0.3)
    rng = np.random.default_rng(2)
    draws = np.stack([simulate_counts(p, rng) for _ in range(4000)])
    freq = np.stack([(draws == k).mean(axis=0) for k in range(p.shape[1])], axis=1)
    assert np.abs(freq - p).max() < 5 * np.sqrt(0.25 / 4000)  # every shot, every count: within 5σ of a frequency
