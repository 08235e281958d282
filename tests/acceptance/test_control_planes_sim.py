"""Control surfaces in the strip adjustment (issue 28), end to end: the range-offset UAV survey (5 cm
range offset, seed 5) with no control point, only roof facets surveyed at their corners (σ 1 cm,
``calidar.sim.control_planes``), raised by 4 cm (a vertical trajectory bias: trajectory and points
4 cm low). ``calidar boresight --control control_planes.csv`` finds the range offset and the height
bias within 2σ, names the vertical trajectory bias determined by the planes, and writes the planes'
residuals; ``calidar simulate survey --control-planes N`` writes the file and its truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.io.control_planes import read_control_planes
from range_offset_survey import RANGE_OFFSET, simulated_survey

pytestmark = pytest.mark.slow
HEIGHT_BIAS = 0.04


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from calidar.sim.control_planes import simulate_control_planes

    res, out = simulated_survey(tmp_path_factory.mktemp("planes"))
    planes = simulate_control_planes(res, 8, 0.01, seed=5)
    planes.xyz[:, 2] += HEIGHT_BIAS
    planes.write(out)
    return out


@pytest.fixture(scope="module")
def run(sim, tmp_path_factory):
    from calidar.cli import run as calidar

    out = tmp_path_factory.mktemp("run") / "out"
    code = calidar([str(a) for a in ("boresight", *sorted((sim / "strips").glob("*.laz")), "--trajectory", sim / "sbet.out",
                                   "--sensor", sim / "sensor.toml", "--control", sim / "control_planes.csv",
                                   "--estimate", "boresight,range_offset,height_bias", "--truth", sim / "truth.json",
                                   "--out", out)])
    assert code in (0, 3), code
    return out, json.loads((out / "solution.json").read_text())


def test_planes_alone_determine_the_range_offset_and_the_height_bias(run):
    _, doc = run
    for name, truth in (("range_offset", RANGE_OFFSET), ("height_bias", HEIGHT_BIAS)):  # m
        p = doc["parameters"][name]
        err, sigma = p["value"] - truth, p["sigma"]
        assert sigma < 0.015 and abs(err) < 2 * sigma, (name, err, sigma)


def test_the_verdict_and_the_outputs_name_the_planes(run):
    out, doc = run
    control = doc["control"]
    assert control["kind"] == "surfaces" and control["n_points"] == 8 and control["n_used"] == 8
    dz = np.array([r["dz_after_m"] for r in control["points"]])
    sigma = np.array([r["sigma_m"] for r in control["points"]])
    before = np.array([r["dz_before_m"] for r in control["points"]])
    assert np.sqrt(np.mean(before**2)) > 0.05  # 5 cm range offset and 4 cm bias, both lowering the strips
    assert 0.4 < np.sqrt(np.mean((dz / sigma) ** 2)) < 2.5
    findings = {f["check"]: f for f in doc["verdict"]["findings"]}
    bias = findings["vertical trajectory bias"]
    assert bias["status"] == "pass" and "determined by 8 control planes" in bias["detail"], bias
    assert "8 of 8 control planes" in findings["ground control"]["detail"]
    assert "control plane" in (out / "report.html").read_text()


def test_simulate_survey_writes_control_planes(cli, tmp_path):
    out = tmp_path / "sim"
    code, _, err = cli("simulate", "survey", "--preset", "uav", "--seed", "5", "--density", "0.01",
                       "--control-planes", "4", "--out", out)
    assert code == 0, err
    f = read_control_planes(out / "control_planes.csv")
    truth = json.loads((out / "truth.json").read_text())["control_planes"]
    assert f.planes() == ["R001", "R002", "R003", "R004"] and truth["sigma_m"] == 0.01
    for facet in truth["facets"]:  # roof facets: a unit normal, pointing up, no steeper than 45°
        n, d = np.array(facet["normal_enu"]), facet["d_m"]
        assert np.linalg.norm(n) == pytest.approx(1.0) and n[2] > 0.7
    code, _, err = cli("simulate", "survey", "--preset", "uav", "--density", "0.01", "--control-planes", "5000",
                       "--out", tmp_path / "bad")
    assert code == 1 and "--control-planes" in err
