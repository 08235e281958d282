"""The model check's arithmetic (calidar.strips.model_check): one freed parameter by one linear solve
against an independent full least-squares fit, Hausman's covariance difference, the cluster-robust
variance against the solver's sandwich, and the verdict finding it makes."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.adjust import Parameter, ParameterSet, Solution
from calidar.adjust.normals import cluster_robust
from calidar.strips.model_check import FreedFit, Groups, hausman
from calidar.strips.model_check_verdict import SHIFT_LIMIT, Z_FAIL, Z_WARN, model_check_finding


def _problem(seed: int, phi_true: float, n: int = 400):
    """y = Xθ + jφ + noise with σ per row, and a prior on θ₂ (as the trajectory corrections have)."""
    rng = np.random.default_rng(seed)
    X = np.column_stack([np.ones(n), rng.normal(size=n), rng.normal(size=n)])
    j = 0.6 * X[:, 1] + rng.normal(size=n)  # correlated with θ₁: freeing it moves θ₁
    sigma = rng.uniform(0.5, 2.0, n)
    theta = np.array([1.0, -2.0, 0.5])
    y = X @ theta + j * phi_true + sigma * rng.normal(size=n)
    prior_c, prior_s = 0.4, 0.3  # θ₂ ~ N(0.4, 0.3²)
    return X, j, y, 1.0 / sigma**2, (2, prior_c, prior_s)


def _lstsq(A, y, w, prior):
    """Weighted least squares with the prior as a pseudo-observation: estimate, covariance (σ known)."""
    k, c, s = prior
    row = np.zeros(A.shape[1])
    row[k] = 1.0
    Aw = np.vstack([A * np.sqrt(w)[:, None], row / s])
    yw = np.concatenate([y * np.sqrt(w), [c / s]])
    est = np.linalg.lstsq(Aw, yw, rcond=None)[0]
    return est, np.linalg.inv(Aw.T @ Aw)


def _freed(X, j, y, w, prior, x):
    """FreedFit at restricted values x (residual r = Xx − y, as the engine's r(θ) with J = X)."""
    k, c, s = prior
    r = X @ x - y
    P = np.zeros((3, 3))
    P[k, k] = 1.0 / s**2
    N = X.T @ (w[:, None] * X) + P
    g = X.T @ (w * r) + P @ (x - np.where(np.arange(3) == k, c, 0.0))
    return FreedFit(X, w, r, N, g, 1.0).free(j)


@pytest.mark.parametrize("start_offset", [0.0, 0.05])  # at the restricted optimum, and a little off it
def test_one_freed_parameter_equals_the_full_fit_and_hausman_is_the_covariance_difference(start_offset):
    X, j, y, w, prior = _problem(3, phi_true=0.8)
    theta_r, C_r = _lstsq(X, y, w, prior)
    full, C_f = _lstsq(np.column_stack([X, j]), y, w, prior)
    f = _freed(X, j, y, w, prior, theta_r + start_offset)
    assert f["value"] == pytest.approx(full[3], rel=1e-9)
    np.testing.assert_allclose(f["shift"], full[:3] - theta_r, rtol=1e-8, atol=1e-12)
    assert f["sigma_model"] == pytest.approx(np.sqrt(C_f[3, 3]), rel=1e-9)
    # Hausman (1978): cov(θ_full − θ_restricted) = C_full − C_restricted on the shared parameters
    np.testing.assert_allclose(hausman(f["b"], f["sigma"]), C_f[:3, :3] - C_r, rtol=1e-8, atol=1e-14)
    np.testing.assert_allclose(f["shift_sigma"], np.sqrt(np.diag(C_f[:3, :3] - C_r)), rtol=1e-8)
    # with one parameter freed, each shift's z is the freed parameter's Wald z
    moved = np.abs(f["shift"]) > 1e-12
    np.testing.assert_allclose(np.abs(f["shift"][moved] / f["shift_sigma"][moved]), abs(f["z"]), rtol=1e-9)
    assert abs(f["z"]) > 10  # φ = 0.8 with σ ≈ 0.05: seen


def test_without_the_omitted_parameter_z_is_standard_normal():
    z = np.array([_freed(*(p := _problem(seed, 0.0))[:4], p[4], _lstsq(p[0], p[2], p[3], p[4])[0])["z"]
                  for seed in range(300)])
    assert abs(np.mean(z)) < 0.2 and 0.88 < np.std(z) < 1.12  # ±3 sampling σ of 300 draws
    assert np.mean(np.abs(z) > 1.96) < 0.09


def test_a_column_the_others_explain_is_not_separable():
    X, _, y, w, prior = _problem(4, 0.0)
    f = _freed(X, X @ [0.3, -1.0, 0.0], y, w, prior, _lstsq(X, y, w, prior)[0])  # (θ₂ has a prior)
    assert f["separable"] is False and f["information_share"] < 1e-9


@pytest.mark.parametrize("two", [False, True])
def test_cluster_variance_is_the_solvers_sandwich_and_the_brute_force_sum(two):
    rng = np.random.default_rng(7)
    n = 60
    e = rng.normal(size=n)
    grouping = rng.integers(0, 7, size=n)
    if two:  # two different segments per row (its a and b strips)
        grouping = np.column_stack([grouping, (grouping + rng.integers(1, 7, size=n)) % 7])
    got = Groups(grouping).variance(e)
    labels = grouping.reshape(n, -1)
    share = np.array([[bool(set(labels[a]) & set(labels[b])) for b in range(n)] for a in range(n)])
    G = np.unique(labels).size
    brute = float(e @ share @ e) * G / (G - 1)  # Σ over pairs sharing a group (each pair once, with itself)
    assert got == pytest.approx(brute, rel=1e-12)
    solver = cluster_robust(np.array([[1e-30]]), np.array([[1.0]]), e[:, None], grouping)
    assert got == pytest.approx(float(solver[0, 0]), rel=1e-12)


def _solution():
    params = ParameterSet([Parameter("boresight_roll", 1e-4, "rad"), Parameter("boresight_pitch", 0.0, "rad")])
    return Solution.from_normal_matrix(params, np.diag([1 / 7e-6**2, 1 / 4e-5**2]), 1.0, 5000.0, residuals=np.zeros(3),
                                       weights=np.ones(3), before={}, history=[], converged=True, variance_factor=1.0)


def _check(z: float, shift_in_sigma: float) -> dict:
    sigma = 0.0015
    own = np.degrees(7e-6)
    return {"candidates": {
        "range_offset": {"separable": True, "information_share": 0.06, "unit": "m", "value": z * sigma,
                         "sigma": sigma, "sigma_model": sigma, "sigma_cluster": 0.0, "z": z,
                         "shifts": {"boresight_roll": {"shift": -shift_in_sigma * own, "sigma": 1e-4, "own_sigma": own,
                                                       "unit": "deg", "in_own_sigma": -shift_in_sigma},
                                    "boresight_pitch": {"shift": 0.0, "sigma": 0.0, "own_sigma": 0.002, "unit": "deg",
                                                        "in_own_sigma": 0.0}}},
        "scan_angle_offset": {"separable": False, "information_share": 0.0, "unit": "deg", "same_as": "boresight_roll"},
        "lever_arm_y": {"separable": False, "information_share": 1e-14, "unit": "m"}}, "seconds": 1.0}


@pytest.mark.parametrize("z, shift, status", [
    (1.2, 0.4, "pass"), (-Z_WARN + 0.1, 5.0, "pass"),        # not seen by the overlaps
    (Z_WARN + 0.5, SHIFT_LIMIT - 0.1, "note"),                 # seen, but the angles do not depend on it
    (Z_WARN + 0.1, SHIFT_LIMIT + 0.5, "warn"),                 # seen, moves the angles
    (Z_FAIL + 1.0, 12.5, "fail"), (-Z_FAIL - 1.0, 3.0, "fail"),
])
def test_the_finding_weighs_z_and_the_shift_in_the_angles_own_sigma(z, shift, status):
    f = model_check_finding(_check(z, shift), _solution())
    assert f.status == status, f.detail
    assert "(not tested: scan_angle_offset is boresight_roll; lever_arm_y: not separable from the estimated" in f.detail
    if status in ("warn", "fail"):
        assert f"freeing range_offset moves boresight_roll by" in f.detail and f"({shift:.1f}× its σ)" in f.detail
        assert "a range offset of" in f.detail and "mm ±" in f.detail
        assert "--estimate boresight_roll,boresight_pitch,range_offset" in f.action and "--control" in f.action


def test_an_angle_a_flagged_parameter_moves_is_no_longer_determined():
    from calidar.strips.model_check_verdict import moved_parameters
    from calidar.verdict import Finding

    sol = _solution()
    given = [Finding("pass", "boresight_roll", "+0.00573° ± 0.00040° (1.4″): determined to this σ"),
             Finding("pass", "boresight_pitch", "+0.0024° ± 0.0026° (9.4″): determined to this σ")]
    sol.extra["model_check"] = _check(Z_FAIL + 20.0, 12.5)
    roll, pitch = moved_parameters(given, sol)
    assert roll.status == "fail" and roll.detail.startswith("+0.00573° ± 0.00040° (1.4″): not determined — freeing "
                                                           "range_offset moves it by") and "12.5× this σ" in roll.detail
    assert pitch == given[1]  # not moved
    sol.extra["model_check"] = _check(Z_WARN - 1.0, 12.5)  # the overlaps do not see it: nothing changes
    assert moved_parameters(given, sol) == given


def test_a_linear_scanners_scan_angle_offset_is_the_boresight_roll():
    """Why the check does not free it while the roll is estimated (model_check.ALIASES)."""
    from calidar.sensor import Sensor
    from calidar.strips.model_check import ALIASES, candidates

    angles = np.column_stack([np.linspace(-0.6, 0.6, 7), np.linspace(-0.1, 0.1, 7)])
    s = Sensor(boresight_roll=0.01, boresight_pitch=-0.02, boresight_yaw=0.3)
    offset = s.r_bs @ s.with_parameters(scan_angle_offset=0.004).scanner.directions(angles).T
    roll = s.with_parameters(boresight_roll=0.01 - 0.004).r_bs @ s.scanner.directions(angles).T
    np.testing.assert_allclose(offset, roll, atol=1e-15)
    assert ALIASES["scan_angle_offset"] == "boresight_roll"
    names = candidates(s.parameters(), ["boresight_roll", "boresight_pitch", "boresight_yaw"])
    assert "scan_angle_offset" not in names and "range_offset" in names and "lever_arm_z" not in names
    assert "scan_angle_offset" in candidates(s.parameters(), ["boresight_pitch"])


def test_a_singular_adjustment_is_not_checked_and_says_why():
    from types import SimpleNamespace

    from calidar.strips.model_check import check

    X, j, y, w, _ = _problem(5, 0.0)
    X = np.column_stack([X, X[:, 1]])  # two identical columns: N singular
    params = ParameterSet([Parameter(f"p{k}", 0.0, "1") for k in range(4)])
    fit = SimpleNamespace(params=params, variance_factor=lambda r, w, x: 1.0,
                          gradient=lambda J, w, r, x: J.T @ (w * r))
    est = SimpleNamespace(fit=fit, x=np.zeros(4), r=-y, w=w, normals=(X, X.T @ (w[:, None] * X)))
    out = check(est, None, {"range_offset": 0.0}, [], [], [], {})
    assert out["candidates"] == {} and "singular" in out["not_run"]
    f = model_check_finding(out, _solution())
    assert f.status == "note" and f.detail.startswith("not run: the adjustment's normal matrix is singular")
