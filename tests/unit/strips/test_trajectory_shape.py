"""The trajectory prior's correlation shape: first- or second-order Gauss–Markov
(calidar.strips.trajectory_errors.gauss_markov, [trajectory_model] shape)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import quad

from calidar.errors import InputError
from calidar.pipelines.strip_config import StripConfig, from_document
from calidar.strips.config import CalibrationConfig, TrajectorySettings
from calidar.strips.trajectory_errors import TrajectoryModel, gauss_markov


def test_the_shapes_and_their_power_at_zero_frequency():
    """GM1 exp(−|Δt|/T); GM2 (1 + |Δt|/τ)·exp(−|Δt|/τ) with τ = T/2, smooth at lag 0 (no cusp);
    both integrate to 2T over all lags: the same S(0) = 2σ²T for the same correlation_s."""
    T = 3.5
    dt = np.array([-7.0, -1.0, 0.0, 0.5, 1.0, 3.5, 20.0])
    assert np.allclose(gauss_markov(dt, T, "gm1"), np.exp(-np.abs(dt) / T), rtol=0, atol=1e-15)
    tau = T / 2
    assert np.allclose(gauss_markov(dt, T, "gm2"), (1 + np.abs(dt) / tau) * np.exp(-np.abs(dt) / tau),
                       rtol=0, atol=1e-15)
    for shape in ("gm1", "gm2"):
        integral, _ = quad(lambda u: float(gauss_markov(u, T, shape)), 0.0, np.inf)
        assert integral == pytest.approx(T, rel=1e-9)
    # the slope at lag 0: −1/T for GM1, 0 for GM2 (ρ(ε) = 1 − ε²/(2τ²) + …)
    eps = 1e-4
    assert (1 - gauss_markov(eps, T, "gm1")) / eps == pytest.approx(1 / T, rel=1e-3)
    assert (1 - gauss_markov(eps, T, "gm2")) / eps == pytest.approx(0.0, abs=1e-3)
    assert np.array_equal(gauss_markov(dt, None, "gm2"), (dt == 0).astype(float))
    with pytest.raises(InputError, match="gm3"):
        gauss_markov(dt, T, "gm3")


def test_a_long_strips_mean_is_as_uncertain_for_either_shape():
    """Matched at zero frequency: the variance of the mean of n knots 1 s apart, 1ᵀR1/n², tends to
    2T/n for both shapes (within 1 % at 2000 knots), while the knot-to-knot correlation differs
    (exp(−1/3.5) = 0.75 against (1 + 1/1.75)·exp(−1/1.75) = 0.89)."""
    n, T = 2000, 3.5
    means = {}
    for shape in ("gm1", "gm2"):
        R = TrajectoryModel(1.0, 0.03, 3e-5, 20.0, T, shape=("gm1", shape)).correlation(n, "tilt")
        means[shape] = R.sum() / n**2
        assert means[shape] == pytest.approx(2 * T / n, rel=0.01)
        assert R[0, 1] == pytest.approx({"gm1": 0.7515, "gm2": 0.8874}[shape], abs=1e-4)
    assert means["gm2"] == pytest.approx(means["gm1"], rel=0.01)


@pytest.mark.parametrize("block_s", [0.5, 1.0, 2.0])
def test_the_second_order_priors_are_positive_definite(block_s):
    """The strips' rotation knots and the flight's shift knots (two strips flown at one time
    included) under GM2: Cholesky succeeds, the smallest eigenvalue above 0."""
    m = TrajectoryModel(block_s, 0.03, 3e-5, 20.0, 3.5, shape=("gm2", "gm2"))
    R = m.correlation(int(200 / block_s), "tilt")
    np.linalg.cholesky(R)
    assert np.linalg.eigvalsh(R).min() > 0
    spans = {1: (0.0, 120.0), 2: (0.0, 120.0), 3: (150.0, 300.0)}
    F = m.flight_correlation(spans)
    np.linalg.cholesky(F)
    assert np.linalg.eigvalsh(F).min() > 0
    assert np.allclose(np.diag(F), 1.0) and np.allclose(F, F.T)


def test_first_order_when_chosen_is_the_former_prior():
    """shape gm1 (the default) gives the φ^|k−l| and exp(−|Δt|/T) of the first-order model."""
    m = TrajectoryModel(1.0, 0.03, 3e-5, 20.0, 3.5)
    assert m.shape == ("gm1", "gm1")
    k = np.arange(12)
    assert np.allclose(m.correlation(12, "tilt"), np.exp(-1 / 3.5) ** np.abs(k[:, None] - k),
                       rtol=1e-13, atol=0)
    assert np.allclose(m.correlation(12, "bias"), np.exp(-1 / 20) ** np.abs(k[:, None] - k),
                       rtol=1e-13, atol=0)
    spans = {1: (0.0, 5.0), 2: (8.0, 12.0)}
    t = np.concatenate([np.arange(6.0), 8.0 + np.arange(5.0)])
    same = np.repeat([0, 1], [6, 5])
    R = np.exp(-np.abs(t[:, None] - t) / 20.0)
    R = np.where(same[:, None] == same, R, 0.95 * R)
    assert np.allclose(m.flight_correlation(spans), R, rtol=1e-13, atol=0)
    # the attitude's shape changes the rotations only
    m2 = TrajectoryModel(1.0, 0.03, 3e-5, 20.0, 3.5, shape=("gm1", "gm2"))
    assert np.array_equal(m2.flight_correlation(spans), m.flight_correlation(spans))
    assert not np.allclose(m2.correlation(12, "tilt"), m.correlation(12, "tilt"))


def test_the_shape_is_a_setting_of_the_configuration_file():
    doc = {"trajectory_model": {"shape": ["gm1", "gm2"]}}
    settings = from_document(doc).calibration.trajectory
    assert settings.shape == ("gm1", "gm2")
    assert replace(settings, sigma=(0.03, 3e-5)).model().shape == ("gm1", "gm2")
    again = StripConfig(CalibrationConfig(trajectory=settings)).to_dict()["trajectory_model"]
    assert again["shape"] == ["gm1", "gm2"]
    assert TrajectorySettings().shape == ("gm1", "gm1")
    with pytest.raises(InputError, match=r"config\.toml: trajectory_model.*gm1, gm2.*'gm3'"):
        from_document({"trajectory_model": {"shape": ["gm3", "gm2"]}}, "config.toml")
    with pytest.raises(InputError, match=r"trajectory_model\.shape: expected a list of 2"):
        from_document({"trajectory_model": {"shape": "gm2"}}, "config.toml")


def test_the_engine_gets_the_chosen_shape():
    """prior_correlation (what the adjustment inverts): the rotations' groups and the shifts' flight
    group built with the model's shapes."""
    spans = {1: (0.0, 6.0), 2: (10.0, 14.0)}
    m = TrajectoryModel(1.0, 0.03, 3e-5, 20.0, 3.5, shape=("gm2", "gm2"))
    groups = dict((names[0], R) for names, R in m.prior_correlation(spans))
    k = np.arange(7.0)
    assert np.allclose(groups["trajectory_tilt_up_1_0"], gauss_markov(k[:, None] - k, 3.5, "gm2"),
                       rtol=1e-13, atol=0)
    t = np.concatenate([k, 10.0 + np.arange(5.0)])
    flight = gauss_markov(t[:, None] - t, 20.0, "gm2")
    same = np.repeat([0, 1], [7, 5])
    assert np.allclose(groups["trajectory_bias_east_1_0"],
                       np.where(same[:, None] == same, flight, 0.95 * flight), rtol=1e-13, atol=0)
