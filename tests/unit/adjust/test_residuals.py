"""The residual protocol: a problem object and the solver's options are all the engine takes."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from calidar.adjust import (Block, FunctionProblem, Parameter, ParameterSet, ResidualProblem, SolverOptions, Values,
                            solve)
from calidar.adjust.residuals import values_of


class Line(ResidualProblem):
    """y = a + b·x with σ per row: the smallest problem implementing the protocol, its Jacobian its own."""

    def __init__(self, x, y, sigma, sparse=False):
        self.x, self.y, self.sigma, self.sparse = x, y, sigma, sparse
        self.parameters = ParameterSet([Parameter("a", 0.0, "m"), Parameter("b", 0.0, "1")])
        self.coef = Block.of(self.parameters.names, {"a": "intercept", "b": "slope"})

    def residuals(self, values):
        a, b = self.coef.take(values)
        return a + b * self.x - self.y

    def jacobian(self, values):
        J = np.stack([np.ones_like(self.x), self.x], axis=1)
        return sp.csr_matrix(J) if self.sparse else J


@pytest.mark.parametrize("sparse", [False, True])
def test_a_line_fit_equals_weighted_least_squares(sparse):
    """Values and σ of the engine equal numpy's weighted least squares (σ0²·(AᵀWA)⁻¹, σ0 from the
    residuals), with a dense or a sparse Jacobian."""
    rng = np.random.default_rng(3)
    x = np.linspace(-5.0, 5.0, 40)
    sigma = np.where(np.arange(40) % 2, 0.05, 0.2)
    y = 1.3 - 0.7 * x + rng.normal(0.0, sigma)
    sol = solve(Line(x, y, sigma, sparse), SolverOptions(robust=None))
    A = np.stack([np.ones_like(x), x], axis=1) / sigma[:, None]
    coef, rss, *_ = np.linalg.lstsq(A, y / sigma, rcond=None)
    cov = rss[0] / (x.size - 2) * np.linalg.inv(A.T @ A)
    assert np.allclose([sol.values["a"], sol.values["b"]], coef, rtol=0, atol=1e-10)
    assert np.allclose([sol.sigma["a"], sol.sigma["b"]], np.sqrt(np.diag(cov)), rtol=1e-8, atol=0)
    assert sol.converged


def test_the_function_form_is_the_same_engine():
    """solve(residual_fn, params, sigma=…, robust=…) wraps the functions in a FunctionProblem: the
    same numbers to the last bit as the protocol form (Huber weights on heavy-tailed errors)."""
    rng = np.random.default_rng(4)
    x = np.linspace(0.0, 10.0, 50)
    y = 2.0 + 0.3 * x + rng.standard_t(2, 50) * 0.1
    line = Line(x, y, 0.1)
    old = solve(lambda v: v["a"] + v["b"] * x - y, line.parameters, sigma=0.1, robust="huber", max_iter=20)
    new = solve(FunctionProblem(lambda v: v["a"] + v["b"] * x - y, line.parameters, sigma=0.1),
                SolverOptions(robust="huber", max_iter=20))
    own = solve(line, SolverOptions(robust="huber", max_iter=20))
    assert new.values == old.values and np.array_equal(new.covariance, old.covariance)
    # its own (analytic) Jacobian instead of central differences: the same to rounding
    assert np.allclose(list(own.values.values()), list(old.values.values()), rtol=0, atol=1e-9)
    assert np.allclose(own.covariance, old.covariance, rtol=1e-6, atol=0)


def test_options_are_checked_and_kept_apart_from_the_problem():
    with pytest.raises(ValueError, match="robust"):
        SolverOptions(robust="tukey")
    with pytest.raises(ValueError, match="max_iter"):
        SolverOptions(max_iter=-1)
    line = Line(np.arange(5.0), np.arange(5.0), 0.1)
    with pytest.raises(TypeError, match="sigma"):
        solve(line, SolverOptions(), sigma=0.1)  # σ belongs to the problem, not the options
    with pytest.raises(TypeError, match="wobble"):
        solve(line.residuals, line.parameters, wobble=1)


def test_values_read_by_name_and_by_typed_block():
    params = ParameterSet([Parameter("a", 1.0, "m"), Parameter("k", 5.0, "1", free=False), Parameter("b", 2.0, "m")])
    v = values_of(params, np.array([10.0, 20.0]))
    assert isinstance(v, Values) and dict(v) == {"a": 10.0, "k": 5.0, "b": 20.0}
    assert v.get("zzz", -1.0) == -1.0 and "k" in v and len(v) == 3
    block = Block.of(params.names, {"b": ("knot", 1), "a": ("knot", 0), "q": ("knot", 2)})  # q: not a parameter
    assert block.names == ("b", "a") and block.keys == (("knot", 1), ("knot", 0))
    assert block.take(v).tolist() == [20.0, 10.0]  # gathered from the vector
    assert block.take({"a": 1.5, "b": 2.5}).tolist() == [2.5, 1.5]  # a plain mapping: by name


def test_a_block_is_resolved_once_when_the_problem_is_built():
    """Block.of(a ParameterSet, ...) resolves the block's positions in the engine's vector when it is
    made: the engine's Values of that set are gathered by them; Values of another layout by name."""
    params = ParameterSet([Parameter("a", 1.0, "m"), Parameter("k", 5.0, "1", free=False), Parameter("b", 2.0, "m")])
    block = Block.of(params, {"b": ("knot", 1), "a": ("knot", 0)})
    assert block.over is params.layout()[0] and block.positions.tolist() == [2, 0]
    assert block.take(values_of(params, np.array([10.0, 20.0]))).tolist() == [20.0, 10.0]
    other = ParameterSet([Parameter("b", 7.0, "m"), Parameter("a", 8.0, "m")])  # the same names, another order
    assert block.take(values_of(other, np.array([7.0, 8.0]))).tolist() == [7.0, 8.0]
    with pytest.raises(KeyError):
        block.take(values_of(ParameterSet([Parameter("a", 0.0, "m")]), np.array([0.0])))


def test_the_library_calls_the_engine_with_problems_only():
    """No call of solve/estimate under src/calidar uses the function form (a residual function or
    lambda plus keyword settings): each passes a ResidualProblem and SolverOptions."""
    import ast
    from pathlib import Path

    src = Path(__file__).resolve().parents[3] / "src" / "calidar"
    found, bad = 0, []
    for path in src.rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        engine = {a.asname or a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                  and (node.module or "").startswith("calidar.adjust") for a in node.names if a.name in ("solve", "estimate")}
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in engine:
                found += 1
                if (node.args and isinstance(node.args[0], ast.Lambda)) or len(node.args) > 2 or any(
                        k.arg in ("sigma", "jacobian_fn", "normal_fn", "prior_correlation", "robust") for k in node.keywords):
                    bad.append(f"{path.relative_to(src)}:{node.lineno}")
    assert found >= 4, found  # strips, range calibration, CCR, scanner separability
    assert not bad, f"the function form of the engine is called at {bad}"


@pytest.mark.parametrize("module", ["calidar.adjust", "calidar.adjust.residuals"])
def test_the_examples_run(module):
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(module), report=True)
    assert result.attempted > 0 and result.failed == 0
