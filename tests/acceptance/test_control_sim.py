"""Ground control in the strip adjustment (issue 28), end to end on a simulated survey with a
5 cm range offset: ``calidar boresight`` without control names the vertical trajectory bias
and the vertical lever arm not determined and points to --control; with 10 control points on
open ground (``simulate_checkpoints``, survey σ 1 cm) the range offset is found within 2σ, the
vertical lever arm and the vertical trajectory bias become determined, and the control
residuals are in solution.json and the report. A 4 cm vertical trajectory bias (trajectory and
delivered points 4 cm low, which to the strips is the control standing 4 cm higher) is found as
``height_bias`` within 2σ beside the range offset."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.pipelines.boresight import calibrate_strips
from calidar.pipelines.strip_config import StripConfig
from calidar.strips.config import CalibrationConfig, Estimate
from range_offset_survey import RANGE_OFFSET, range_offset_survey

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    return range_offset_survey(tmp_path_factory.mktemp("control"), 10)[0]


def _run(sim, out, estimate, control):
    run = calibrate_strips(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml",
                           StripConfig(CalibrationConfig(Estimate.of(*estimate.split(",")))), truth=sim / "truth.json",
                           control=sim / "checkpoints.csv" if control else None)
    run.write(out)
    return run


def _finding(verdict, check):
    return next(f for f in verdict.findings if f.check == check)


@pytest.fixture(scope="module")
def runs(sim, tmp_path_factory):
    estimate = "boresight,range_offset,lever_arm_z"
    return {c: _run(sim, tmp_path_factory.mktemp(f"out_{c}"), estimate, c) for c in (False, True)}


def test_without_control_the_verdict_names_what_is_not_determined(runs):
    v = runs[False].verdicts["planes"]
    lever, bias = _finding(v, "lever_arm_z"), _finding(v, "vertical trajectory bias")
    assert lever.status == "warn" and "not determined" in lever.detail and "--control" in lever.action
    assert bias.status == "warn" and "not determined" in bias.detail and "--control" in bias.action
    # range offset: a 35° scan sees it (cos θ) between crossing lines, but only relative to the trajectory's heights
    offset = _finding(v, "range_offset")
    assert "not tied to the ground" in offset.detail and "--control" in offset.action
    assert "control" not in runs[False].results["planes"].solution.extra


def test_with_control_range_offset_and_lever_arm_are_estimated_within_two_sigma(runs):
    sol, before = runs[True].results["planes"].solution, runs[False].results["planes"].solution
    err = sol.values["range_offset"] - RANGE_OFFSET
    assert sol.sigma["range_offset"] < 0.01 and abs(err) < 2 * sol.sigma["range_offset"], (err, sol.sigma)
    truth_z = runs[True].inputs.truth["lever_arm_z"]
    assert abs(sol.values["lever_arm_z"] - truth_z) < 2 * sol.sigma["lever_arm_z"] < 0.02
    assert sol.sigma["lever_arm_z"] < 0.5 * before.sigma["lever_arm_z"]  # the control fixes the heights
    v = runs[True].verdicts["planes"]
    assert _finding(v, "lever_arm_z").status == "pass" and "ground control" in _finding(v, "lever_arm_z").detail
    assert _finding(v, "ground control").status == "pass"


def test_control_residuals_are_written(runs):
    out = next(p for p in runs[True].written if p.name == "solution.json").parent
    doc = json.loads((out / "solution.json").read_text())
    control = doc["control"]
    assert control["n_points"] == 10 and control["n_used"] == 10 and control["not_covered"] == []
    dz = np.array([p["dz_after_m"] for p in control["points"]])
    sigma = np.array([p["sigma_m"] for p in control["points"]])
    before = np.array([p["dz_before_m"] for p in control["points"]])
    assert np.sqrt(np.mean(before**2)) > 0.03  # 5 cm too long ranges: the surface ≈ 5 cm low at nominal
    assert 0.5 < np.sqrt(np.mean((dz / sigma) ** 2)) < 2.0  # after: the control's σ holds
    assert doc["run"]["options"]["control"].endswith("checkpoints.csv")  # the option, recorded
    assert "Ground control" in (out / "report.html").read_text()


def test_with_control_and_no_vertical_lever_arm_the_vertical_trajectory_bias_is_determined(sim, tmp_path):
    run = _run(sim, tmp_path / "out", "boresight,range_offset", True)
    bias = _finding(run.verdicts["planes"], "vertical trajectory bias")
    assert bias.status == "pass" and "determined by 10 ground control points" in bias.detail, bias.detail


def test_a_vertical_trajectory_bias_and_the_range_offset_are_found_within_two_sigma(sim, tmp_path):
    from calidar.io.checkpoints import read_checkpoints, write_checkpoints

    cp = read_checkpoints(sim / "checkpoints.csv")
    raised = write_checkpoints(tmp_path / "control.csv", cp.ids, cp.xyz + [0.0, 0.0, 0.04], cp.vegetated, cp.sigma_m)
    config = StripConfig(CalibrationConfig(Estimate.of("boresight", "range_offset", "height_bias")))
    run = calibrate_strips(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml", config,
                           truth=sim / "truth.json", control=raised)
    sol = run.results["planes"].solution
    for name, truth in (("range_offset", RANGE_OFFSET), ("height_bias", 0.04)):  # the strips raised by 4 cm
        err = sol.values[name] - truth
        assert sol.sigma[name] < 0.015 and abs(err) < 2 * sol.sigma[name], (name, err, sol.sigma[name])
    assert _finding(run.verdicts["planes"], "height_bias").status == "pass"
