"""The σ0 a robust adjustment's global test and variance factor take (calidar.adjust.unit_weight; issue 26)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.adjust import Parameter, ParameterSet, SolverOptions, solve
from calidar.adjust.residuals import FunctionProblem
from calidar.adjust.unit_weight import GROSS_Z, skipped_sigma0


def _heavy(rng, n: int) -> np.ndarray:
    """Standardised residuals of rows whose σ are right in the mean but not row by row, as VGICP's at the truth: a
    normal scale mixture with E[z²] = 1 (90 % of the rows' σ 1/0.87 too wide, 10 % 1/1.80 too narrow; kurtosis 4.7)
    times Student t with the rows' own degrees of freedom (9, 12 or 30), scaled to unit variance."""
    v = np.where(rng.random(n) < 0.9, 0.75, 3.25)
    nu = rng.choice([9.0, 12.0, 30.0], n)
    return np.sqrt(v) * rng.standard_t(nu) * np.sqrt((nu - 2) / nu)


def _with_gross(rng, z: np.ndarray, fraction: float = 0.01) -> np.ndarray:
    """``z`` with ``fraction`` of its rows given 10σ errors of either sign."""
    z = z.copy()
    i = rng.choice(z.size, int(fraction * z.size), replace=False)
    z[i] += 10.0 * rng.choice([-1.0, 1.0], i.size)
    return z


def test_sigma0_reads_heavy_tailed_rows_with_right_sigma_as_one_where_the_weighted_one_reads_low():
    """200 000 heavy-tailed rows with E[z²] = 1: the skipped RMS reads 1 ± 2 %; the robustly weighted σ0 made
    consistent for the rows' t mixture (what the global test took before) reads it more than 3 % low."""
    from calidar.strips.row_variance import consistency, dof_summary

    rng = np.random.default_rng(11)
    z = _heavy(rng, 200_000)
    s0, skipped = skipped_sigma0(z)
    assert s0 == pytest.approx(1.0, abs=0.02)
    assert skipped < 100  # 0.05 %: the tail of the mixture itself
    sol = solve(FunctionProblem(lambda v: 0.01 * z - v["mean"], ParameterSet([Parameter("mean", 0.0, "m")]),
                                sigma=0.01), SolverOptions(robust="cauchy"))
    assert sol.extra["unit_weight"]["sigma0"] == pytest.approx(s0, rel=1e-3)  # the solver reads the same
    weighted = sol.sigma0 / np.sqrt(consistency("cauchy", dof_summary(np.full(z.size, 12.0))))
    assert weighted < 0.97


def test_sigma0_is_robust_to_one_percent_of_ten_sigma_errors():
    """1 % of the rows with 10σ errors move the skipped RMS by less than 2 % (the plain RMS: +40 %), on normal rows
    and on the heavy-tailed ones; the rows skipped are those, near enough."""
    rng = np.random.default_rng(12)
    for z in (rng.standard_normal(50_000), _heavy(rng, 50_000)):
        clean, bad = skipped_sigma0(z)[0], _with_gross(rng, z)
        s0, skipped = skipped_sigma0(bad)
        assert abs(s0 / clean - 1.0) < 0.02
        assert 0.9 * 500 <= skipped <= 1.1 * 500
        assert np.sqrt(np.mean(bad**2)) / clean > 1.3


def test_sigma0_counts_the_redundancy_and_the_priors():
    """Without rows skipped: √((Σ z² + the priors' terms) / (n + priors − parameters)), the least-squares σ0."""
    z = np.random.default_rng(13).standard_normal(40)
    assert skipped_sigma0(z, 3.0, 2, 5, gross_z=None) == (pytest.approx(np.sqrt((np.sum(z**2) + 3.0) / 37)), 0)
    assert skipped_sigma0(z, 3.0, 2, 5)[0] == pytest.approx(np.sqrt((np.sum(z**2) + 3.0) / 37))  # none beyond 7σ0
    assert GROSS_Z == 7.0


def test_the_solution_records_it_beside_the_engines_sigma0():
    """Rows stated 10 % too narrow, heavy-tailed, absolute σ, Cauchy weights: the solution records σ0 ≈ 1.1 and the
    redundancy of the rows it kept; the engine's robustly weighted σ0 reads ≈ 1.0 there, and the variance factor
    stays the engine's (max(σ0², 1) of it: the skipped RMS is not taken, docs/validation.md, issue 26)."""
    z = _heavy(np.random.default_rng(14), 100_000)
    sol = solve(FunctionProblem(lambda v: 0.01 * z - v["mean"], ParameterSet([Parameter("mean", 0.0, "m")]),
                                sigma=0.01 / 1.1, absolute_sigma=True), SolverOptions(robust="cauchy"))
    u = sol.extra["unit_weight"]
    assert u["sigma0"] == pytest.approx(1.1, rel=0.02) and u["gross_z"] == GROSS_Z
    assert u["redundancy"] == z.size - u["rows_skipped"] - 1
    assert sol.sigma0 < 1.03


def test_least_squares_keeps_its_own_sigma0():
    """Without robust weights nothing is recorded, and the variance factor is the least-squares σ0²."""
    y = np.random.default_rng(15).normal(0.0, 0.02, 500)
    sol = solve(FunctionProblem(lambda v: y - v["mean"], ParameterSet([Parameter("mean", 0.0, "m")]), sigma=0.01),
                SolverOptions(robust=None))
    assert "unit_weight" not in sol.extra
    assert sol.sigma["mean"] ** 2 == pytest.approx(sol.sigma0**2 * 0.01**2 / y.size, rel=1e-9)
