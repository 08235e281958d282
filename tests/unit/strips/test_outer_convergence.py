"""The outer loop's stop rule and its extrapolation (issue 26, seventh session;
calidar.strips.convergence), on a loop whose every iteration removes a fixed share of the pitch's
error (the 10⁹ run's kept cells: ≈ 20 %) while the mean correspondence distance has settled."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import calidar.strips.outer_loop as loop
from calidar.adjust import Parameter, ParameterSet
from calidar.strips.convergence import extrapolated, moving
from calidar.strips.verdict import convergence_finding

SIGMA = 1e-5  #: the pitch's σ (rad)
TRUTH = -7e-4


class _Estimate:
    """An adjustment whose pitch goes ``1 − rho`` of the way from where it was matched to TRUTH."""

    def __init__(self, params: ParameterSet, rho: float):
        p = params["boresight_pitch"]
        moved = TRUTH + rho * (p.value - TRUTH)
        self.parameters = ParameterSet([Parameter("boresight_pitch", moved, "rad",
                                                  prior_value=p.prior_center)])
        self.r, self.w, self.x = np.zeros(3), np.ones(3), np.array([moved])
        self.history, self.step_scale = [{}, {}], np.array([SIGMA**2])
        self.fit = SimpleNamespace(variance_factor=lambda r, w, x: 1.0)


class _Run:
    """The outer loop's view of a run: matching costs nothing, each solve crawls by ``rho``."""

    def __init__(self, rho: float, max_outer: int):
        self.settings = SimpleNamespace(max_outer=max_outer)
        self.warnings: list[str] = []
        self.rho, self.matched_at = rho, []

    def match(self, values, k, client, say, log=None, pool=None):
        self.matched_at.append(values["boresight_pitch"])
        return [], [], {}

    def solve(self, corrs, params, step_in_sigma, step_scale):
        return _Estimate(params, self.rho), _Problem()


class _Problem:
    sigma = np.zeros(3)

    def __call__(self, values):
        return np.zeros(3)


@pytest.fixture
def settled_distance(monkeypatch):
    """The mean correspondence distance settled from the first iteration on (as on the kept
    cells: 5.4 → 5.2 mm while the pitch moved 1.8σ)."""
    monkeypatch.setattr(loop, "mean_distance", lambda problem, r: 0.005)
    monkeypatch.setattr(loop, "control_rows", lambda problem, r: [])


def _run(rho: float, max_outer: int):
    run = _Run(rho, max_outer)
    start = ParameterSet([Parameter("boresight_pitch", 0.0, "rad")])
    outer, est, *_ = loop.outer_loop(run, start, None, lambda *a: None, None, None, 2e-4)
    sol = SimpleNamespace(sigma={"boresight_pitch": SIGMA}, converged=True)
    return run, outer, est, SimpleNamespace(outer=outer, solution=sol, warnings=run.warnings)


def test_a_crawling_loop_goes_on_until_the_pitch_has_arrived(settled_distance):
    """Before: the loop stopped after 2 iterations (the distance settled) 35σ off. Now it goes on
    while the pitch moves, jumps along its steady steps and stops within 1σ, well below the cap."""
    run, outer, est, result = _run(rho=0.8, max_outer=40)
    error = (est.parameters["boresight_pitch"].value - TRUTH) / SIGMA
    assert abs(error) < 1.0, (error, len(outer))
    assert len(outer) < 20, len(outer)
    assert any(o.get("extrapolated") for o in outer)
    assert convergence_finding(result).status == "pass"
    # the prior stays centred where it was (the jump moves the value only)
    assert est.parameters["boresight_pitch"].prior_center == 0.0


def test_a_loop_stopped_by_its_cap_while_moving_fails_the_verdict(settled_distance):
    run, outer, est, result = _run(rho=0.97, max_outer=4)
    assert len(outer) == 4
    assert any("outer loop stopped after 4 iterations" in w for w in run.warnings)
    f = convergence_finding(result)
    assert f.status == "fail" and "boresight_pitch" in f.detail


def test_extrapolation_lands_on_a_geometric_series_limit_and_skips_turns():
    """x_k = x* + c·ρᵏ: the jump lands on x*; steps at an angle (here 90°) give no jump."""
    names = ["a", "b"]
    vals = [{"a": 1.0 + 3.0 * 0.7**k, "b": 2.0 - 1.0 * 0.7**k} for k in range(3)]
    ahead = extrapolated(vals, {"a": 0.01, "b": 0.01}, names)
    assert ahead == pytest.approx({"a": 1.0, "b": 2.0})
    turn = [{"a": 0.0, "b": 0.0}, {"a": 1.0, "b": 0.0}, {"a": 1.0, "b": 0.5}]
    assert extrapolated(turn, {"a": 0.01, "b": 0.01}, names) is None
    assert moving(vals, {"a": 0.01, "b": 0.01}) is not None
    assert moving(vals, {"a": 10.0, "b": 10.0}) is None  # steps far below 0.2σ
