"""The trajectory's level over the flight (calidar.strips.trajectory_level_time) and the
per-element variance components under it (calidar.adjust.variance_elements), against a
simulated truth: priors whose real σ changes in time, observed through noisy data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calidar.adjust.variance_components import estimate_components, split_blocks
from calidar.adjust.variance_elements import estimate_elements
from calidar.strips.trajectory_errors import Knot
from calidar.strips.trajectory_level_time import (LevelOverTime, estimate_over_time, over_time_accuracy, pool_in_time,
                                                 segment_index, segments_of)
from calidar.trajectory_accuracy import SURVEY_GRADE

STRIPS, KNOTS, GAP_S, TAU_S, NOISE = 6, 30, 28.0, 3.5, 0.3


def _flight():
    """Six strips of 30 knots 1 s apart, 28 s between strips: knot times by strip."""
    return {s: s * (KNOTS + GAP_S) + np.arange(KNOTS, dtype=float) for s in range(STRIPS)}


def _problem(rng, factor_of_time):
    """Heading knots with stated σ 1 (a Gauss–Markov prior, τ 3.5 s, per strip) whose real σ is
    ``factor_of_time(t)``, each observed directly with noise 0.3: the normal terms, priors, knots."""
    times = _flight()
    R = np.exp(-np.abs(np.arange(KNOTS)[:, None] - np.arange(KNOTS)[None, :]) / TAU_S)
    L = np.linalg.cholesky(R)
    x = np.concatenate([factor_of_time(times[s]) * (L @ rng.standard_normal(KNOTS)) for s in range(STRIPS)])
    y = x + NOISE * rng.standard_normal(x.size)
    n = x.size
    terms = (np.eye(n) / NOISE**2, -y / NOISE**2, float(y @ y) / NOISE**2, float(n), np.zeros(n))
    P = np.linalg.inv(R)
    priors = [(np.arange(s * KNOTS, (s + 1) * KNOTS), np.zeros(KNOTS), P) for s in range(STRIPS)]
    knots = [Knot("tilt", 2, s, k) for s in range(STRIPS) for k in range(KNOTS)]
    return times, terms, priors, knots


def _varying(t):
    """A level that changes over the flight: ×0.5 at the start to ×2 at the end, smoothly."""
    return np.exp(math.log(2.0) * np.tanh((t - 170.0) / 80.0))


def test_segments_cut_each_strip_into_stretches_of_about_the_segment_length():
    times = {1: np.arange(0.0, 25.0), 2: 100.0 + np.arange(0.0, 38.0)}
    segs = segments_of(times, 30.0)
    assert [(s.strip, s.first, s.last) for s in segs] == [(1, 0, 24), (2, 0, 18), (2, 19, 37)]
    where = segment_index(segs)
    assert where[(2, 19)] == 2 and where[(1, 24)] == 0


def test_without_pooling_the_elements_reproduce_the_grouped_marginal_estimator():
    """Labels that coincide with uncoupled prior groups: the per-element estimator is the
    marginal variance-component estimator of calidar.adjust.variance_components, to 1e-6."""
    rng = np.random.default_rng(1)
    times, terms, priors, knots = _problem(rng, lambda t: np.where(t < 170, 0.5, 2.0))
    labels = ["a" if k.strip < 3 else "b" for k in knots]
    blocks = split_blocks(priors, labels)
    ref = estimate_components(*terms, blocks, estimate_observations=False, marginal=True, tol=1e-9, max_iter=500)
    got = estimate_elements(terms[0], terms[1], terms[4], priors, labels, {"a": 1.0, "b": 1.0}, tol=1e-9, max_iter=500)
    for g in ("a", "b"):
        assert got.variance[g] == pytest.approx(ref.variance[g], rel=1e-6)
    assert got.variance["a"] < 0.5 < 2.0 < got.variance["b"]  # the truth 0.25 and 4


def test_the_effective_number_counts_correlated_priors_less():
    """Knots 1 s apart on a 3.5 s Gauss–Markov process: a strip's 30 priors are worth far fewer
    independent ones (the update's relative variance 2/m), and its update scatters accordingly
    over draws (its standard deviation within 25 % of √(2/m))."""
    logs, eff = [], []
    for seed in range(60):
        _, terms, priors, knots = _problem(np.random.default_rng(seed), lambda t: np.ones_like(t))
        labels = [f"s{k.strip}" for k in knots]
        c = estimate_elements(terms[0], terms[1], terms[4], priors, labels, {f"s{s}": 1.0 for s in range(STRIPS)}, max_iter=1)
        logs += [math.log(c.raw[f"s{s}"]) for s in range(STRIPS)]
        eff += [c.effective[f"s{s}"] for s in range(STRIPS)]
    m = float(np.mean(eff))
    assert 3.0 < m < 20.0, m  # far fewer than the 30 priors
    assert np.std(logs) == pytest.approx(math.sqrt(2.0 / m), rel=0.25)


def test_pooling_a_constant_level_keeps_one_factor():
    """Updates that scatter no more than their noise: τ = 0 (or close) and every segment near
    the flight-wide mean."""
    rng = np.random.default_rng(5)
    t = np.arange(8) * 50.0
    m = np.full(8, 10.0)
    raw = np.exp(rng.normal(0.0, math.sqrt(2 / 10), 8))
    p = pool_in_time(t, raw, m, 1.0)
    assert np.ptp(p.log_var) < 0.3
    assert p.tau < 0.5


def test_a_segment_that_cannot_tell_takes_its_neighbours():
    t = np.arange(5) * 40.0
    raw = np.array([4.0, 4.0, 0.01, 4.0, 4.0])
    m = np.array([30.0, 30.0, 0.5, 30.0, 30.0])
    p = pool_in_time(t, raw, m, 1.0)
    assert not p.own[2] and p.own[[0, 1, 3, 4]].all()
    assert math.exp(p.log_var[2]) == pytest.approx(4.0, rel=0.2)


def test_the_level_follows_a_known_variation_within_its_stated_sigma():
    """Real σ from ×0.5 to ×2 over the flight: over 25 draws the per-segment factors' errors
    against the truth (RMS over each segment's knots), divided by their stated σ, have an RMS in
    0.6–1.4, and they are closer to the truth than one flight-wide factor."""
    z, err_time, err_flat = [], [], []
    for seed in range(25):
        times, terms, priors, knots = _problem(np.random.default_rng(100 + seed), _varying)
        groups = ["heading"] * len(knots)
        blocks = split_blocks(priors, groups)
        flat = estimate_components(*terms, blocks, estimate_observations=False, marginal=True, tol=1e-4).variance["heading"]
        lt = estimate_over_time(terms, priors, knots, groups, times, {"heading": flat}, 1.0, 1e-4)
        assert isinstance(lt, LevelOverTime) and lt.converged
        p = lt.groups["heading"]
        for i, s in enumerate(lt.segments):
            truth = math.log(float(np.sqrt(np.mean(_varying(times[s.strip][s.first:s.last + 1]) ** 2))))
            est = 0.5 * p.log_var[i]
            z.append((est - truth) / (0.5 * p.sigma[i]))
            err_time.append(est - truth)
            err_flat.append(0.5 * math.log(flat) - truth)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.6 < rms < 1.4, rms
    assert np.sqrt(np.mean(np.square(err_time))) < 0.6 * np.sqrt(np.mean(np.square(err_flat)))


def test_the_accuracy_over_time_gives_each_knot_its_segments_factor():
    times = _flight()
    segs = segments_of(times)
    from calidar.strips.trajectory_level_time import Pooled
    n = len(segs)
    log_var = np.log(np.linspace(0.25, 4.0, n))
    pooled = Pooled(log_var, np.full(n, 0.1), np.ones(n, bool), 1.0, 0.0)
    lt = LevelOverTime(segs, {"heading": pooled}, {"heading": np.full(n, 10.0)}, 3, True)
    acc = over_time_accuracy(SURVEY_GRADE, lt, times)
    pos, att = acc.at(times[5])
    assert att[:, 2] == pytest.approx(SURVEY_GRADE.attitude_rad[0, 2] * 2.0)
    assert att[:, 0] == pytest.approx(SURVEY_GRADE.attitude_rad[0, 0])  # a group not estimated keeps its σ
    assert pos == pytest.approx(np.repeat(SURVEY_GRADE.position_m[:1], KNOTS, 0))
    assert acc.at(times[0])[1][:, 2] == pytest.approx(SURVEY_GRADE.attitude_rad[0, 2] * 0.5)


def _over_time_dict():
    times = _flight()
    segs = segments_of(times)
    from calidar.strips.trajectory_level_time import Pooled
    n = len(segs)
    own = np.ones(n, bool)
    own[2] = False
    pooled = Pooled(np.log(np.linspace(0.25, 4.0, n)), np.full(n, 0.2), own, 1.0, 0.0)
    lt = LevelOverTime(segs, {"heading": pooled}, {"heading": np.full(n, 10.0)}, 3, True)
    return lt.to_dict({"heading": 0.008})


def test_the_report_table_and_the_verdict_state_the_level_over_the_flight():
    """The table: one row per segment with its strip, its time from the first and heading's σ ±
    its relative σ ("(pooled)" where the segment could not tell); groups not followed read "–".
    The accuracy finding names each group's range over the flight."""
    from calidar.strips.trajectory_level_time import level_table_rows
    from calidar.strips.verdict import accuracy_finding

    d = _over_time_dict()
    rows = level_table_rows(d)
    assert len(rows) == STRIPS
    assert rows[0][:2] == ["0", "0–29"] and rows[1][1] == "58–87"
    assert rows[0][5] == "0.004 ± 11 %" and rows[-1][5] == "0.016 ± 11 %"
    assert rows[2][5].endswith("(pooled)") and rows[0][2] == "–"
    level = {"source": "data", "min_redundancy": 10.0, "headline": "position 3/3 cm (horizontal/vertical)",
             "groups": {"heading": {"estimated": True, "sigma_factor": 1.0, "sigma_factor_relative_sigma": 0.1,
                                    "redundancy_at_stated_sigma": 30.0}}, "over_time": d}
    f = accuracy_finding(level)
    assert f.status == "pass" and "over the flight (per segment, pooled in time): heading ×0.5–×2" in f.detail
