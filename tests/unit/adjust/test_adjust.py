import json
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from calidar.adjust import Parameter, ParameterSet, solve
from calidar.adjust.normals import normal_matrix
from calidar.errors import CalibrationError


def _line(seed, outliers=0):
    rng = np.random.default_rng(seed)
    x = np.linspace(0, 10, 400)
    y = 2.0 + 0.5 * x + rng.normal(0, 0.1, x.size)
    if outliers:
        y[rng.choice(x.size, outliers, replace=False)] += rng.uniform(2, 5, outliers)
    return x, y


def _params():
    return ParameterSet([Parameter("a", 0.0, "m"), Parameter("b", 0.0, "1")])


def test_recovers_line_and_sigma_is_honest():
    z = []
    for seed in range(100):
        x, y = _line(seed)
        sol = solve(lambda v: v["a"] + v["b"] * x - y, _params(), sigma=0.1, robust=None)
        z.append((sol.values["a"] - 2.0) / sol.sigma["a"])
    z = np.array(z)
    # standardized errors ~ N(0, 1): their spread must be close to one
    assert 0.8 < z.std() < 1.2
    assert abs(z.mean()) < 0.35


def test_robust_weighting_resists_outliers():
    x, y = _line(3, outliers=60)
    plain = solve(lambda v: v["a"] + v["b"] * x - y, _params(), sigma=0.1, robust=None)
    robust = solve(lambda v: v["a"] + v["b"] * x - y, _params(), sigma=0.1, robust="cauchy")
    assert abs(plain.values["a"] - 2.0) > 0.2
    assert abs(robust.values["a"] - 2.0) < 0.05
    assert robust.residuals_after["downweighted_fraction"] > 0.1


def test_fixed_parameter_and_prior():
    x, y = _line(4)
    ps = ParameterSet([Parameter("a", 2.5, "m", free=False), Parameter("b", 0.0, "1")])
    sol = solve(lambda v: v["a"] + v["b"] * x - y, ps, sigma=0.1)
    assert sol.values["a"] == 2.5 and "a" not in sol.sigma
    # a tight prior holds a parameter at its prior value
    ps = ParameterSet([Parameter("a", 1.0, "m", prior_sigma=1e-6), Parameter("b", 0.0, "1")])
    sol = solve(lambda v: v["a"] + v["b"] * x - y, ps, sigma=0.1)
    assert sol.values["a"] == pytest.approx(1.0, abs=1e-5)


def test_unobservable_and_correlated_parameters_are_named():
    x, y = _line(5)
    ps = ParameterSet([Parameter("a", 0.0, "m"), Parameter("b", 0.0, "1"), Parameter("c", 0.0, "m"),
                       Parameter("d", 0.0, "m")])
    sol = solve(lambda v: v["a"] + v["c"] + v["b"] * x - y, ps, sigma=0.1)
    text = " ".join(sol.warnings)
    assert "d is not observable" in text
    assert "cannot separate" in text and "a" in text and "c" in text
    assert sol.values["a"] + sol.values["c"] == pytest.approx(2.0, abs=0.05)


def test_solution_json_schema():
    x, y = _line(6)
    sol = solve(lambda v: v["a"] + v["b"] * x - y, _params(), sigma=0.1)
    doc = json.loads(json.dumps(sol.to_dict({"a": 2.0, "b": 0.5})))
    assert set(doc) >= {"parameters", "correlation", "residuals", "history"}
    assert doc["parameters"]["a"]["unit"] == "m" and doc["parameters"]["a"]["sigma"] > 0
    assert abs(doc["parameters"]["a"]["error"]) < 4 * doc["parameters"]["a"]["sigma"]
    assert doc["residuals"]["after"]["rms"] < doc["residuals"]["before"]["rms"]


def test_angles_display_in_degrees():
    p = Parameter("boresight_roll", np.radians(0.5), "rad")
    assert p.display_unit == "deg" and p.to_display(p.value) == pytest.approx(0.5)


def test_no_free_parameters_is_an_error():
    with pytest.raises(CalibrationError):
        solve(lambda v: np.zeros(3), ParameterSet([Parameter("a", 0.0, "m", free=False)]))


def test_correlated_priors_and_a_sparse_jacobian_give_the_closed_form():
    """Linear model y = H x + e with a joint Gaussian prior x ~ N(μ, D R D): the solution is the
    textbook posterior mean (HᵀWH + Σp⁻¹)⁻¹ (HᵀWy + Σp⁻¹ μ), with a dense or a sparse Jacobian."""
    import scipy.sparse as sp

    rng = np.random.default_rng(1)
    H = np.zeros((60, 4))
    H[np.arange(60), rng.integers(0, 4, 60)] = rng.uniform(0.5, 2.0, 60)  # one parameter per row
    H[:, 3] = 1.0
    y = H @ [0.3, -0.2, 0.1, 1.0] + rng.normal(0, 0.05, 60)
    R = np.array([[1.0, 0.8, 0.64], [0.8, 1.0, 0.8], [0.64, 0.8, 1.0]])
    prior = np.array([0.1, 0.1, 0.1])
    names = ["x0", "x1", "x2"]
    ps = ParameterSet([Parameter(n, 0.0, "m", prior_sigma=0.1) for n in names] + [Parameter("c", 0.0, "m")])
    Sp_inv = np.zeros((4, 4))
    Sp_inv[:3, :3] = np.linalg.inv(np.outer(prior, prior) * R)
    N = H.T @ H / 0.05**2 + Sp_inv
    expect = np.linalg.solve(N, H.T @ y / 0.05**2)

    def residuals(v):
        return H @ [v["x0"], v["x1"], v["x2"], v["c"]] - y

    for jac in (lambda v: H, lambda v: sp.csr_matrix(H)):
        sol = solve(residuals, ps, sigma=0.05, robust=None, jacobian_fn=jac, prior_correlation=[(names, R)])
        assert [sol.values[n] for n in [*names, "c"]] == pytest.approx(expect, abs=1e-9)
        assert sol.covariance / max(sol.sigma0**2, 1.0) == pytest.approx(np.linalg.inv(N), rel=1e-6)
    independent = solve(residuals, ps, sigma=0.05, robust=None, jacobian_fn=lambda v: H)
    assert abs(independent.values["x0"] - expect[0]) > 1e-4  # the correlation matters
    with pytest.raises(ValueError, match="needs a prior_sigma"):
        solve(residuals, ps, sigma=0.05, prior_correlation=[(["x0", "c"], np.eye(2))])


def test_priors_are_absolute_sigma0_below_one_does_not_shrink_them():
    """Observations stated 4× noisier than they are give σ0 ≈ 0.25: without priors the
    covariance is σ0²·N⁻¹ (σ relative, rescaled both ways); with priors it stays N⁻¹, as the
    priors hold absolute σ that a generous statement of the data must not tighten."""
    x, y = _line(6)  # noise 0.1

    def residuals(v):
        return v["a"] + v["b"] * x - y

    free = solve(residuals, _params(), sigma=0.4, robust=None)
    assert free.sigma0 == pytest.approx(0.25, rel=0.15)
    N = np.array([[x.size, x.sum()], [x.sum(), x @ x]]) / 0.4**2
    assert free.covariance == pytest.approx(free.sigma0**2 * np.linalg.inv(N), rel=1e-6)
    held = solve(residuals, ParameterSet([Parameter("a", 2.0, "m", prior_sigma=0.05), Parameter("b", 0.0, "1")]),
                 sigma=0.4, robust=None)
    assert held.sigma0 < 0.5
    assert held.covariance == pytest.approx(np.linalg.inv(N + np.diag([1 / 0.05**2, 0.0])), rel=1e-6)


def test_absolute_sigma_keeps_the_stated_sigma_without_priors_too():
    """With absolute observation σ (each row's own noise, as the strips' from their points' scatter) a
    σ0 below 1 does not shrink the covariance even without priors (issue 26: the strip adjustment
    with the trajectory model off shrank roll's σ by σ0 ≈ 0.7 to 1/1.45 of its error); σ0 above 1
    still raises it."""
    from calidar.adjust import SolverOptions
    from calidar.adjust.residuals import FunctionProblem

    x, y = _line(6)  # noise 0.1

    def residuals(v):
        return v["a"] + v["b"] * x - y

    for stated in (0.4, 0.05):  # 4× too generous (σ0 ≈ 0.25), 2× too tight (σ0 ≈ 2)
        N = np.array([[x.size, x.sum()], [x.sum(), x @ x]]) / stated**2
        sol = solve(FunctionProblem(residuals, _params(), sigma=stated, absolute_sigma=True), SolverOptions(robust=None))
        assert sol.sigma0 == pytest.approx(0.1 / stated, rel=0.15)
        np.testing.assert_allclose(sol.covariance, max(sol.sigma0**2, 1.0) * np.linalg.inv(N), rtol=1e-6)
    relative = solve(FunctionProblem(residuals, _params(), sigma=0.4), SolverOptions(robust=None))
    np.testing.assert_allclose(relative.covariance, relative.sigma0**2 * np.linalg.inv(N * (0.05 / 0.4) ** 2), rtol=1e-6)


def test_normal_matrix_of_a_sparse_jacobian_equals_the_dense_product():
    """JᵀWJ from CSR rows (repeated column indices within a row included) equals the dense product."""
    rng = np.random.default_rng(4)
    indptr = np.array([0, 3, 3, 7, 9])
    indices = np.array([0, 4, 0, 1, 2, 1, 3, 4, 2])  # row 0 repeats column 0, row 2 column 1
    J = sp.csr_matrix((rng.normal(size=indices.size), indices, indptr), shape=(4, 5))
    w = rng.uniform(0.5, 2.0, 4)
    D = J.toarray()
    assert np.allclose(normal_matrix(J, w), D.T @ (w[:, None] * D), rtol=1e-12, atol=1e-12)


def test_a_loose_estimate_refined_equals_the_full_solve():
    """What the strip calibration's outer loop does: stop each adjustment at 0.1 σ, refine the last."""
    from calidar.adjust.solver import estimate

    x, y = _line(7, outliers=30)
    fn = lambda v: v["a"] + v["b"] * x - y  # noqa: E731
    groups = np.repeat(np.arange(20), 20)  # 20 clusters of 20 observations
    full = solve(fn, _params(), sigma=0.1, clusters=groups)
    loose = estimate(fn, _params(), sigma=0.1, step_in_sigma=0.1)
    refined = loose.refine()
    assert len(refined.history) > len(loose.history)  # it did stop early, then went on
    sol = refined.solution(groups)
    for name in ("a", "b"):
        assert abs(loose.parameters[name].value - full.values[name]) < 0.1 * full.sigma[name]
        assert abs(sol.values[name] - full.values[name]) < 1e-3 * full.sigma[name]
        assert sol.sigma[name] == pytest.approx(full.sigma[name], rel=1e-3)


def test_the_solution_and_the_model_check_share_one_jacobian_and_normal_matrix():
    """An estimate's J and N at its values are computed once (``Estimate.normals``, issue 32
    eleventh session): the solution's σ uses them, a later reader (the model check) gets the same
    arrays without another Jacobian; a refined estimate, at other values, computes its own."""
    from calidar.adjust.solver import estimate

    x, y = _line(8)
    calls = []

    def jac(v):
        calls.append(1)
        return np.column_stack([np.ones_like(x), x])

    fn = lambda v: v["a"] + v["b"] * x - y  # noqa: E731
    est = estimate(fn, _params(), sigma=0.1, jacobian_fn=jac, step_in_sigma=0.1)
    before = len(calls)
    sol = est.solution()
    J, N = est.normals
    assert len(calls) == before + 1 and est.normals[1] is N
    assert np.allclose(N, J.T @ (est.w[:, None] * J), rtol=1e-12, atol=0)
    again = replace(est).solution()  # a copy computes its own J and N: the same σ
    assert len(calls) == before + 2 and again.sigma == sol.sigma
    refined = est.refine(1e-6)
    assert refined.normals[1] is not N


@pytest.mark.parametrize("dyadic", [False, True])
def test_cluster_robust_sigma_is_the_sandwich(dyadic):
    """diag(N⁻¹ · Σ_g S_g S_gᵀ · N⁻¹) · G/(G−1), computed the long way (the meat formed explicitly)."""
    from calidar.adjust.normals import cluster_robust

    rng = np.random.default_rng(2)
    n, p = 300, 4
    J = rng.normal(size=(n, p))
    scores = J * rng.normal(size=(n, 1))
    groups = rng.integers(0, 12, n)
    if dyadic:  # two different groups per observation (a pair of strips' time clusters)
        groups = np.c_[groups, (groups + rng.integers(1, 12, n)) % 12]
    N = J.T @ J
    Ninv = np.linalg.inv(N)
    cov = 1e-6 * Ninv  # small: the sandwich raises every σ
    labels = groups if dyadic else groups[:, None]
    G = np.unique(labels).size
    meat = np.zeros((p, p))
    for i in range(n):
        for j in range(n):
            shared = set(labels[i]) & set(labels[j])
            if shared:
                meat += np.outer(scores[i], scores[j])
    want = np.diag(Ninv @ meat @ Ninv) * G / (G - 1)
    got = cluster_robust(cov, Ninv, scores, groups)
    assert np.allclose(np.diag(got), want, rtol=1e-9)
    corr = lambda c: c / np.sqrt(np.outer(np.diag(c), np.diag(c)))  # noqa: E731
    assert np.allclose(corr(got), corr(cov))  # correlations kept
