"""The strip calibration's verdict: findings in plain words, with numbers and actions."""

from __future__ import annotations

import doctest
from types import SimpleNamespace

import numpy as np
import pytest

import calidar.trajectory_accuracy
import calidar.verdict
from calidar.adjust import Parameter, ParameterSet, Solution
from calidar.strips.quality import PairQuality
from calidar.strips.report import QualityStage
from calidar.strips.verdict import (correlation_findings, overlap_finding, parameter_findings, sigma0_finding,
                                    strip_verdict)


def _solution(sigmas: dict[str, float], rho: float = 0.0, sigma0: float = 1.0, dof: float = 5000.0) -> Solution:
    """A solution whose free parameters have these σ (SI) and the first two correlation ρ."""
    params = ParameterSet([Parameter(n, 0.01, "rad" if n.startswith("boresight") else "m") for n in sigmas])
    s = np.array(list(sigmas.values()))
    R = np.eye(len(s))
    if len(s) > 1:
        R[0, 1] = R[1, 0] = rho
    cov = R * np.outer(s, s)
    return Solution.from_normal_matrix(params, np.linalg.inv(cov), sigma0**2, dof, residuals=np.zeros(3),
                                       weights=np.ones(3), before={}, history=[], converged=True, variance_factor=1.0)


def test_doctests_of_the_verdict_and_accuracy_modules():
    for module in (calidar.verdict, calidar.trajectory_accuracy):
        assert doctest.testmod(module).failed == 0


def test_undetermined_lever_arm_says_what_to_do():
    sol = _solution({"boresight_pitch": np.radians(0.0005), "lever_arm_z": 0.12})
    found = {f.check: f for f in parameter_findings(SimpleNamespace(solution=sol), 1000.0)}
    assert found["boresight_pitch"].status == "pass" and "″" in found["boresight_pitch"].detail
    z = found["lever_arm_z"]
    assert z.status == "warn" and "not determined by these strips (σ 12 cm)" in z.detail
    assert z.action == "hold it at the measured value or add a flight line at a second height"
    # an angle whose σ moves points by more than 2 cm at the median range is weakly determined
    weak = parameter_findings(SimpleNamespace(solution=_solution({"boresight_yaw": np.radians(0.005)})), 1000.0)[0]
    assert weak.status == "warn" and "8.7 cm on the ground at the 1,000 m median range" in weak.detail


def test_strong_correlation_is_named_with_the_parameter_to_hold():
    sol = _solution({"boresight_pitch": 1e-4, "lever_arm_x": 0.01}, rho=-0.996)
    (f,) = correlation_findings(sol)
    assert f.status == "warn" and f.check == "boresight_pitch and lever_arm_x" and "ρ = -0.996" in f.detail
    assert f.action.startswith("lever_arm_x: hold it at the measured value, or fly lines at two heights")
    assert correlation_findings(_solution({"boresight_pitch": 1e-4, "lever_arm_x": 0.01}, rho=0.5)) == []


@pytest.mark.parametrize("sigma0, status", [(1.0, "pass"), (0.75, "pass"), (0.5, "pass"), (1.6, "warn"), (2.5, "fail")])
def test_global_test_of_sigma0(sigma0, status):
    f = sigma0_finding(_solution({"boresight_roll": 1e-5}, sigma0=sigma0))
    assert f.status == status and f"σ0 = {sigma0:.2f}" in f.detail and "range for 5,000 degrees of freedom is 0.98–1.02" in f.detail
    assert bool(f.action) == (status != "pass")


def _pq(a, b, median, rms, cells=100):
    return PairQuality(a, b, cells, median, rms, 2 * rms, median)


def test_overlaps_worse_after_are_named():
    before = QualityStage("as delivered", "calidar quality …", [_pq(1, 2, 0.05, 0.08), _pq(2, 3, 0.0, 0.010)])
    after = QualityStage("new mounting + trajectory corrections", "…", [_pq(1, 2, 0.001, 0.02), _pq(2, 3, 0.001, 0.015)])
    f = overlap_finding([before, after])
    assert f.status == "warn" and "worse after: 2–3 10.0 → 15.0 mm" in f.detail
    good = overlap_finding([before, QualityStage("x", "…", [_pq(1, 2, 0.0, 0.02), _pq(2, 3, 0.0, 0.011)])])
    assert good.status == "pass" and "median RMSDz over 2 pairs 45.0 → 15.5 mm" in good.detail


class _Strip:
    obs = SimpleNamespace(range_m=np.full(10, 500.0))

    def __len__(self):
        return 10


def test_a_default_accuracy_makes_the_verdict_a_warning():
    result = SimpleNamespace(solution=_solution({"boresight_roll": 1e-6}), strips=[_Strip()], pairs=[{}],
                             method="planes", residuals_after=np.zeros(3), row_sigma=np.ones(3), warnings=[],
                             outer=[{"n_obs": 10, "mean_distance_m": 0.01}, {"n_obs": 10, "mean_distance_m": 0.01}])
    stages = [QualityStage("as delivered", "", [_pq(1, 2, 0.05, 0.08)]), QualityStage("after", "", [_pq(1, 2, 0.0, 0.01)])]
    assert strip_verdict(result, stages, []).status == "pass"
    v = strip_verdict(result, stages, ["no trajectory accuracy found (…): assumed a survey-grade GNSS/INS"])
    assert v.status == "warn" and v.summary.endswith("trajectory taken as exact")
    f = next(f for f in v.findings if f.check == "trajectory accuracy")
    assert "--trajectory-accuracy" in f.action and "smrmsg" in f.action


def _level(heading_estimated: bool) -> dict:
    """A TrajectoryLevel's dict (calidar.strips.trajectory_level) as solution.extra holds it."""
    group = lambda ok, f, r: {"estimated": ok, "sigma_factor": f, "sigma_factor_relative_sigma": 0.1 if ok else None,  # noqa: E731
                              "redundancy": r, "redundancy_at_stated_sigma": r, "priors": 100}
    return {"source": "data", "min_redundancy": 10.0,
            "headline": "position 2.9/3.1 cm (horizontal/vertical), attitude 0.0019/0.0081° (roll·pitch/heading)",
            "groups": {"position_horizontal": group(True, 0.58, 40.0), "position_vertical": group(True, 0.39, 90.0),
                       "attitude_horizontal": group(True, 0.63, 120.0),
                       "heading": group(heading_estimated, 1.0 if not heading_estimated else 1.01,
                                        3.0 if not heading_estimated else 30.0)}}


@pytest.mark.parametrize("heading_estimated", [True, False])
def test_an_accuracy_estimated_from_the_overlaps_is_stated(heading_estimated):
    """No accuracy file, its level estimated: the accuracy line gives the level and its source
    (data), a pass; a group the data cannot tell is named with its redundancy and the criterion
    (a warning: the survey-grade default kept there). The "none found" note is not repeated."""
    sol = _solution({"boresight_roll": 1e-6})
    sol.extra["trajectory_accuracy_estimate"] = _level(heading_estimated)
    result = SimpleNamespace(solution=sol, strips=[_Strip()], pairs=[{}], method="planes", residuals_after=np.zeros(3),
                             row_sigma=np.ones(3), warnings=[],
                             outer=[{"n_obs": 10, "mean_distance_m": 0.01}, {"n_obs": 10, "mean_distance_m": 0.01}])
    stages = [QualityStage("as delivered", "", [_pq(1, 2, 0.05, 0.08)]), QualityStage("after", "", [_pq(1, 2, 0.0, 0.01)])]
    v = strip_verdict(result, stages, ["no trajectory accuracy found (…): its level is estimated from the overlaps"])
    found = [f for f in v.findings if f.check == "trajectory accuracy"]
    assert len(found) == 1
    f = found[0]
    assert "trajectory accuracy estimated from the overlaps: position 2.9/3.1 cm" in f.detail
    assert "source: data" in f.detail
    if heading_estimated:
        assert f.status == "pass" and v.status == "pass" and not f.action
    else:
        assert f.status == "warn" and "heading (redundancy 3.0 < 10)" in f.detail and "default kept" in f.detail
        assert "--trajectory-accuracy" in f.action
