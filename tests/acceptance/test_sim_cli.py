"""`calidar simulate survey` and `calidar demo`: determinism, refusal to overwrite, clear errors."""

import json

import numpy as np
import pytest

from calidar.io.las import read_las


def _files(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_same_seed_same_bytes(cli, tmp_path):
    args = ["simulate", "survey", "--preset", "uav", "--density", "0.01", "--boresight-error", "0.05,-0.02,0.1"]
    for name, seed in (("a", 7), ("b", 7), ("c", 8)):
        code, out, err = cli(*args, "--seed", seed, "--out", tmp_path / name)
        assert code == 0, err
    a, b, c = (_files(tmp_path / n) for n in "abc")
    assert set(a) == {"sbet.out", "smrmsg.out", "sensor.toml", "truth.json"} | {f"strips/line_{k:03d}.laz" for k in range(1, 5)}
    assert a == b
    assert a["strips/line_001.laz"] != c["strips/line_001.laz"] and a["sbet.out"] != c["sbet.out"]
    # the header date is fixed, so the bytes do not change from one day to the next either
    from calidar.io.las import las_header
    from calidar.sim.survey import SIMULATION_DATE

    assert las_header(tmp_path / "a" / "strips" / "line_001.laz").creation_date == SIMULATION_DATE


def test_cli_options_reach_the_simulation(cli, tmp_path):
    code, out, err = cli("simulate", "survey", "--out", tmp_path, "--density", "0.01", "--directions", "cross",
                         "--lever-arm-error", "0.1,0,-0.2", "--range-offset", "0.07", "--range-noise", "0.004",
                         "--vegetation", "0", "--strip-errors", "0.05,0.001,0.01,0.0005", "--beam-divergence", "0.5")
    assert code == 0, err
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert truth["parameters"]["lever_arm_x"]["value"] - truth["parameters"]["lever_arm_x"]["nominal"] == pytest.approx(0.1)
    assert truth["parameters"]["range_offset"]["value"] == pytest.approx(0.07)
    assert truth["noise"]["range_m"] == 0.004 and truth["simulation"]["directions"] == "cross"
    assert truth["noise"]["beam_divergence_mrad"] == pytest.approx(0.5)
    assert len(truth["strips"]) == 6 and all(abs(s["attitude_bias_deg"][0]) > 0 for s in truth["strips"])
    strips = sorted((tmp_path / "strips").iterdir())
    assert len(strips) == 6  # four parallel lines and two cross lines
    las = read_las(strips[-1])
    assert not np.any(las.classification == 5)  # no vegetation asked for
    assert np.ptp(las.xyz[:, 0]) > 1.8 * np.ptp(las.xyz[:, 1])  # 270 m east–west, 130 m swath


def test_refuses_non_empty_folder_without_force(cli, tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    code, out, err = cli("simulate", "survey", "--out", tmp_path, "--density", "0.01")
    assert code == 1 and "not empty" in err and "--force" in err
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]
    code, out, err = cli("simulate", "survey", "--out", tmp_path, "--density", "0.01", "--force")
    # --force replaces the folder whole (issue 27): exactly the new run's files, none of before
    assert code == 0 and (tmp_path / "truth.json").exists() and not (tmp_path / "keep.txt").exists()


@pytest.mark.parametrize("args, message", [
    (["--preset", "satellite"], "preset: expected one of uav, airborne"),
    (["--density", "0"], "density: expected a number > 0"),
    (["--density", "-2"], "density: expected a number > 0"),
    (["--directions", "sideways"], "directions: expected one of same, opposite, cross"),
    (["--boresight-error", "0.1,0.2"], "--boresight-error: expected 3 comma-separated finite numbers"),
    (["--lever-arm-error", "a,b,c"], "--lever-arm-error: expected 3 comma-separated finite numbers"),
    (["--range-noise", "-0.01"], "range_noise_m: expected a noise level >= 0"),
    (["--vegetation", "1.5"], "vegetation: expected a fraction of the area in [0, 0.8]"),
    (["--strip-errors", "0.1,0,0"], "--strip-errors: expected 4 comma-separated finite numbers"),
    (["--strip-errors", "0.1,0,-1,0"], "strip_errors: expected 4 σ values >= 0"),
])
def test_bad_inputs_are_clear_errors(cli, tmp_path, args, message):
    code, out, err = cli("simulate", "survey", "--out", tmp_path / "o", *args)
    assert code == 1 and message in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_unknown_option_is_an_error(cli, tmp_path):
    code, out, err = cli("simulate", "survey", "--out", tmp_path / "o", "--altitude", "50")
    assert code != 0 and "--altitude" in err


def test_impossible_flight_plans_are_clear_errors():
    from calidar.errors import InputError
    from calidar.sim.survey import simulate_survey, survey_config

    for kw, message in [(dict(height_agl_m=-80.0), "height_agl_m: expected a height above ground > 0 m"),
                        (dict(side_overlap=0.0), "side_overlap: expected a fraction strictly between 0 and 1"),
                        (dict(height_agl_m=2000.0), "wider than the scene"),
                        (dict(errors={"boresight_spin": 0.1}), "unknown sensor parameter 'boresight_spin'")]:
        with pytest.raises(InputError, match=message):
            simulate_survey(survey_config("uav", density=0.01, **kw))
    with pytest.raises(InputError, match="unknown survey setting"):
        survey_config("uav", altitude=3)


def small_demo_config(seed):
    """The demo's survey made small (150 m × 150 m at a tenth of the pulse rate): this test checks
    the command and the report's make-up; the demo's own survey and its accuracy are checked by
    tests/acceptance/test_strips_sim.py::test_demo_shows_a_pass_and_a_warning."""
    from dataclasses import replace

    from calidar.sim.survey import survey_config

    cfg = survey_config("uav", seed=seed, density=0.1, directions="cross")
    return replace(cfg, scene=replace(cfg.scene, width_m=150.0, length_m=150.0))


def test_demo_writes_report_and_survey(cli, tmp_path, monkeypatch):
    import calidar.demo as demo
    import calidar.demo.survey as demo_survey

    monkeypatch.setattr(demo_survey, "demo_config", small_demo_config)
    code, out, err = cli("demo", "--out", tmp_path)
    assert code == 0, err
    html = (tmp_path / "report.html").read_text()
    assert "Simulated survey" in html and html.count("data:image/png;base64,") >= 4
    assert html.count("<section") >= len(demo.DEMO_STEPS)  # every step adds its section
    assert (tmp_path / "survey" / "truth.json").exists()
    code, out, err = cli("demo", "--out", tmp_path)
    assert code == 1 and "--force" in err
