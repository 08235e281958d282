"""A new kind of ground control is one module and its name in the configuration (issue 29): the test
double ``SurveyedMarks`` (tests/unit/strips/control_double.py: the same ten control points, given as a
JSON file of marks) registered in :data:`calidar.strips.config.CONTROL_KINDS` and nothing else changed.
``calibrate_strips`` reads its file through its reader, adjusts with its rows, and the solution, the
verdict and the report name it in its own words; its solution equals the control points' to 1e-9."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from calidar.io.checkpoints import read_checkpoints
from calidar.pipelines.boresight import calibrate_strips
from calidar.pipelines.strip_config import StripConfig
from calidar.strips import config as strip_config
from calidar.strips.config import CalibrationConfig, Estimate
from range_offset_survey import RANGE_OFFSET, range_offset_survey

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "unit" / "strips"))
from control_double import SurveyedMarks, write_marks  # noqa: E402

pytestmark = pytest.mark.slow
ESTIMATE = "boresight,range_offset,lever_arm_z"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    sim = range_offset_survey(tmp_path_factory.mktemp("double"), 10)[0]
    cp = read_checkpoints(sim / "checkpoints.csv", cover=False)
    marks = write_marks(sim / "ground.marks", cp.ids, cp.xyz, cp.sigma_m)
    config = StripConfig(CalibrationConfig(Estimate.of(*ESTIMATE.split(","))))
    common = (sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml", config)
    out = {"points": calibrate_strips(*common, truth=sim / "truth.json", control=sim / "checkpoints.csv")}
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(strip_config.CONTROL_KINDS, SurveyedMarks.kind, SurveyedMarks)  # the configuration's one change
        out["marks"] = calibrate_strips(*common, truth=sim / "truth.json", control=marks)
        out["marks"].write(tmp_path_factory.mktemp("out_marks"))
    return out


def test_the_double_kind_gives_the_control_points_solution(runs):
    a, b = runs["points"].results["planes"].solution, runs["marks"].results["planes"].solution
    assert list(a.values) == list(b.values) and a.sigma.keys() == b.sigma.keys() and len(a.sigma) > 100
    for name in a.values:
        assert abs(a.values[name] - b.values[name]) <= 1e-9, name
    for name in a.sigma:
        assert abs(a.sigma[name] - b.sigma[name]) <= 1e-9, name
    err = b.values["range_offset"] - RANGE_OFFSET
    assert abs(err) < 2 * b.sigma["range_offset"] < 0.02, (err, b.sigma["range_offset"])


def test_the_solution_verdict_and_report_name_the_double_in_its_own_words(runs):
    run = runs["marks"]
    control = run.results["planes"].solution.extra["control"]
    assert control["kind"] == "marks" and control["label"] == "surveyed marks" and control["n_used"] == 10
    v = run.verdicts["planes"]
    ground = next(f for f in v.findings if f.check == "ground control")
    lever = next(f for f in v.findings if f.check == "lever_arm_z")
    assert ground.status == "pass" and "10 of 10 surveyed marks" in ground.detail
    assert "surveyed marks (the test double)" in lever.detail
    assert "10 surveyed marks read from ground.marks" in run.inputs.notes
    html = next(p for p in run.written if p.name == "report.html").read_text()
    assert "the test double&#x27;s words" in html and ">mark</th>" in html
    assert np.isfinite(control["rms_dz_after_m"])
