"""The model check in ``calidar boresight`` (issue 26: never pass a wrong calibration). A UAV survey
delivered with a 5 cm range offset that the run does not estimate: the tie planes close the
overlaps, σ0 is below its range, and the boresight roll comes out ≈ 14σ from its true 0. Freeing the
range offset on the same rows moves the roll back by > 2 of its σ with |z| far beyond the FAIL
threshold: the verdict FAILs with exit 3 and the roll no longer reads "determined". The same survey
without the offset passes the check; ``--model-check off`` leaves it out."""

from __future__ import annotations

import json

import pytest

from calidar.strips.model_check_verdict import SHIFT_LIMIT, Z_FAIL, Z_WARN

pytestmark = pytest.mark.slow

#: the survey of the issue: calidar simulate survey --preset uav --seed 5 --density 0.2 --directions cross
SURVEY = ("simulate", "survey", "--preset", "uav", "--seed", "5", "--density", "0.2", "--directions", "cross")


@pytest.fixture(scope="module")
def surveys(tmp_path_factory):
    from calidar.cli import run

    root = tmp_path_factory.mktemp("model_check")
    assert run([*SURVEY, "--range-offset", "0.05", "--out", str(root / "offset")]) == 0
    assert run([*SURVEY, "--out", str(root / "clean")]) == 0
    return root


def _boresight(cli, sim, out, *options):
    return cli("boresight", *sorted((sim / "strips").glob("*.laz")), "--trajectory", sim / "sbet.out", "--sensor",
               sim / "sensor.toml", "--truth", sim / "truth.json", "--out", out, *options)


def test_an_unestimated_range_offset_that_moves_the_roll_fails_with_exit_3(surveys, cli, tmp_path):
    code, out, err = _boresight(cli, surveys / "offset", tmp_path / "cal")
    assert code == 3, (out, err)
    doc = json.loads((tmp_path / "cal" / "solution.json").read_text())
    ro = doc["model_check"]["candidates"]["range_offset"]
    assert ro["separable"] and ro["z"] > Z_FAIL, ro
    roll = ro["shifts"]["boresight_roll"]
    assert roll["in_own_sigma"] < -SHIFT_LIMIT, roll  # the roll's error is +0.0057°: freeing the offset takes it back
    error = doc["parameters"]["boresight_roll"]["error"]
    assert abs(error + roll["shift"]) < 0.5 * abs(error), (error, roll)  # most of the roll's error undone
    assert 0.035 < ro["value"] < 0.055, ro  # the 5 cm offset (part of it is a height the overlaps cannot see)
    text = " ".join(out.split())
    assert "fail model check: freeing range_offset moves boresight_roll by" in text, text
    assert "--estimate boresight,range_offset" in text
    assert "fail boresight_roll" in text and "not determined — freeing range_offset" in text
    assert "Model check" in (tmp_path / "cal" / "report.html").read_text()


def test_the_same_survey_without_the_offset_passes_the_check(surveys, cli, tmp_path):
    code, out, err = _boresight(cli, surveys / "clean", tmp_path / "cal")
    assert code == 0, (out, err)
    check = json.loads((tmp_path / "cal" / "solution.json").read_text())["model_check"]
    for name, c in check["candidates"].items():
        assert not c["separable"] or abs(c["z"]) <= Z_WARN, (name, c)
    assert check["candidates"]["scan_angle_offset"] == {"separable": False, "information_share": 0.0, "unit": "deg",
                                                        "same_as": "boresight_roll"}  # a linear scanner's: the roll
    assert "pass model check" in " ".join(out.split())


def test_model_check_off_leaves_it_out(surveys, cli, tmp_path):
    code, out, err = _boresight(cli, surveys / "offset", tmp_path / "cal", "--model-check", "off")
    assert code == 0, (out, err)  # the wrong calibration the check exists for: nothing else catches it
    assert "model_check" not in json.loads((tmp_path / "cal" / "solution.json").read_text())
    assert "model_check = false" in (tmp_path / "cal" / "config.toml").read_text()


def test_both_methods_get_the_check(tmp_path):
    """Tie planes (point-to-plane rows) and VGICP (point-to-point, three rows each) on a small survey
    delivered with a 5 cm range offset: each method's own check sees it (|z| > Z_FAIL with the
    roll moved > 2σ) and fails."""
    from dataclasses import replace

    import calidar
    from calidar.pipelines.strip_config import StripConfig
    from calidar.strips.config import CalibrationConfig, matchers_named

    cfg = calidar.survey_config("uav", seed=3, density=0.1, directions="cross", errors={"range_offset": 0.05})
    sim = calidar.simulate_survey(replace(cfg, scene=replace(cfg.scene, width_m=150.0, length_m=150.0))).write(
        tmp_path / "sim")
    run = calidar.calibrate_strips(sorted((sim / "strips").glob("*.laz")), sim / "sbet.out", sim / "sensor.toml",
                                   StripConfig(CalibrationConfig(matchers=matchers_named("planes", "vgicp"))))
    for method, result in run.results.items():
        ro = result.solution.extra["model_check"]["candidates"]["range_offset"]
        assert ro["z"] > Z_FAIL and ro["shifts"]["boresight_roll"]["in_own_sigma"] < -SHIFT_LIMIT, (method, ro)
        assert abs(ro["value"] - 0.05) < 3 * ro["sigma"], (method, ro)
        (f,) = [f for f in run.verdicts[method].findings if f.check == "model check"]
        assert f.status == "fail", (method, f.detail)


def test_the_action_it_names_passes(surveys, cli, tmp_path):
    """The FAIL's action, ``--estimate boresight,range_offset``: the range offset within 2σ of 5 cm,
    the roll within 2σ of its true 0, the check passes."""
    code, out, err = _boresight(cli, surveys / "offset", tmp_path / "cal", "--estimate", "boresight,range_offset")
    assert code == 0, (out, err)
    doc = json.loads((tmp_path / "cal" / "solution.json").read_text())
    for name in ("range_offset", "boresight_roll"):
        p = doc["parameters"][name]
        assert abs(p["error"]) < 2 * p["sigma"], (name, p)
    assert "range_offset" not in doc["model_check"]["candidates"]
    assert "pass model check" in " ".join(out.split())
