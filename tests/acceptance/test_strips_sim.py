"""Acceptance of the strip calibrator against the survey simulator's truth (issue 4)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calidar.sim.survey import simulate_survey, survey_config
from calidar.strips.calibrate import StripSettings, calibrate
from calidar.strips.trajectory_errors import TrajectoryModel

BORESIGHT_ERRORS = {"boresight_roll": np.radians(0.03), "boresight_pitch": np.radians(-0.04),
                    "boresight_yaw": np.radians(0.05)}
ANGLES = ("boresight_roll", "boresight_pitch", "boresight_yaw")


def _simulate(preset, directions, density, vegetation=0.0, seed=3, **errors):
    cfg = survey_config(preset, seed=seed, density=density, vegetation=vegetation, directions=directions,
                        errors={**BORESIGHT_ERRORS, **errors}, range_noise_m=0.03)
    return simulate_survey(cfg)


def _check_angles(sol, truth, tol_deg=0.002):
    for name in ANGLES:
        err = sol.values[name] - truth[name]
        assert abs(np.degrees(err)) < tol_deg, (name, np.degrees(err))
        assert abs(err) < 3 * sol.sigma[name], (name, err / sol.sigma[name])


@pytest.fixture(scope="module")
def airborne(tmp_path_factory):
    res = _simulate("airborne", "cross", 0.3)
    return res, res.write(tmp_path_factory.mktemp("airborne") / "sim")


def test_airborne_cross_lines_boresight_via_cli(cli, airborne, tmp_path):
    res, sim = airborne
    strips = sorted((sim / "strips").glob("*.laz"))
    out = tmp_path / "cal"
    code, stdout, err = cli("boresight", *strips, "--trajectory", sim / "sbet.out", "--sensor", sim / "sensor.toml",
                            "--method", "planes", "--truth", sim / "truth.json", "--out", out, "--write-strips")
    assert code == 0, err
    doc = json.loads((out / "solution.json").read_text())
    for name in ANGLES:
        p = doc["parameters"][name]
        assert p["unit"] == "deg" and p["free"]
        assert abs(p["error"]) < 0.002, (name, p)
        assert abs(p["error"]) < 3 * p["sigma"], (name, p)
        assert p["truth"] == pytest.approx(np.degrees(res.truth.parameters()[name]))
    assert not doc["parameters"]["lever_arm_x"]["free"]
    assert len(doc["strips"]["pairs"]) >= 10
    from calidar.sensor import Sensor

    cal = Sensor.read(out / "sensor.toml")
    assert cal.boresight_roll == pytest.approx(np.radians(doc["parameters"]["boresight_roll"]["value"]))
    assert cal.lever_arm_x == res.nominal.lever_arm_x  # not estimated: unchanged
    html = (out / "report.html").read_text()
    assert "Strip calibration (planes)" in html and "RMSDz before" in html
    # the recalibrated strips agree better than the delivered ones
    code, before, err = cli("quality", *strips, "--json")
    assert code == 0, err
    code, after, err = cli("quality", *sorted(out.glob("strip_*.laz")), "--json")
    assert code == 0, err
    rms = lambda d: np.median([p["rmsdz_m"] for p in json.loads(d)["pairs"]])  # noqa: E731
    assert rms(after) < 0.6 * rms(before)
    code, _, err = cli("boresight", *strips, "--trajectory", sim / "sbet.out", "--sensor", sim / "sensor.toml",
                       "--out", out)
    assert code == 1 and "pass --force" in err


def test_trajectory_errors_modelled_via_cli(cli, airborne, tmp_path):
    res, sim = airborne
    args = [*sorted((sim / "strips").glob("*.laz")), "--trajectory", sim / "sbet.out", "--sensor", sim / "sensor.toml",
            "--truth", sim / "truth.json"]
    code, _, err = cli("boresight", *args, "--trajectory-sigma", "0.03", "--out", tmp_path / "bad")
    assert code == 1 and "--trajectory-sigma" in err and "POSITION_M,ATTITUDE_DEG" in err and "Traceback" not in err
    out = tmp_path / "cal"
    code, stdout, err = cli("boresight", *args, "--trajectory-sigma", "0.03,0.002", "--out", out)
    assert code == 0, err
    doc = json.loads((out / "solution.json").read_text())
    n_knots = sum(name.startswith("trajectory_tilt_up_") for name in doc["parameters"])
    assert n_knots > 50  # knots every second (the default) on every strip
    for name in ANGLES:
        p = doc["parameters"][name]
        assert abs(p["error"]) < 0.002 and abs(p["error"]) < 3 * p["sigma"], (name, p)
    # nuisance parameters: value and σ listed, but not in the correlation matrix or the history
    assert doc["parameters"]["trajectory_tilt_up_1_0"]["sigma"] > 0
    assert doc["correlation"]["names"] == list(ANGLES) and len(doc["correlation"]["matrix"]) == 3
    assert set(doc["history"][-1]["values"]) == set(ANGLES)
    assert f"{6 * n_knots} trajectory corrections estimated" in " ".join(stdout.split())
    assert f"{6 * n_knots} trajectory_* parameters are estimated too" in (out / "report.html").read_text()


def test_trajectory_not_covering_strips_is_a_clear_error(cli, airborne, tmp_path):
    from calidar.io.sbet import read_sbet, write_sbet

    res, sim = airborne
    traj = read_sbet(sim / "sbet.out")
    short = write_sbet(tmp_path / "short.out", traj.subset(traj.time[0], traj.time[0] + 60.0))
    code, out, err = cli("boresight", *sorted((sim / "strips").glob("*.laz")), "--trajectory", short,
                         "--sensor", sim / "sensor.toml", "--out", tmp_path / "o")
    err = " ".join(err.split())  # the console wraps long lines
    assert code == 1
    assert "short.out: time:" in err and "outside the trajectory" in err and "Traceback" not in err


@pytest.mark.slow
def test_airborne_with_30_percent_vegetation():
    res = _simulate("airborne", "cross", 0.3, vegetation=0.3)
    sol = calibrate(res.calibration_strips(), res.nominal).solution
    _check_angles(sol, res.truth.parameters())
    assert sol.residuals_after["downweighted_fraction"] > 0.0


#: the simulator's trajectory errors as the adjustment models them: 3 cm and 0.002° at knots 1 s apart,
#: Gauss–Markov over 20 s (position) and 3.5 s (attitude), as the simulator smooths them over 10 s and 2 s
#: (the CLI's defaults; see docs/architecture.md for the attitude's 3.5 s)
AIRBORNE_TRAJECTORY = TrajectoryModel(block_s=1.0, position_sigma_m=0.03, attitude_sigma_rad=np.radians(0.002),
                                      correlation_s=20.0, attitude_correlation_s=3.5)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["planes", "vgicp"])
@pytest.mark.parametrize("seed", [3, 4, 5, 6])
def test_airborne_boresight_with_the_trajectory_errors_modelled(seed, method):
    """The trajectory's errors (3 cm, 0.002°) estimated as Gauss–Markov nuisance parameters:
    every angle within 0.002° and 3σ on four surveys, by both methods (without them pitch and
    yaw reach 0.006° at 5σ). Closest: planes, seed 5, pitch 0.00131° = 1.9σ; VGICP, seed 5,
    pitch 0.00128° = 1.9σ (with piecewise-constant corrections 0.00150° = 2.2σ and yaw
    0.00169° = 2.4σ)."""
    res = _simulate("airborne", "cross", 0.3, seed=seed)
    settings = StripSettings(threshold_m=1e-3 if method == "vgicp" else 2e-4, trajectory=AIRBORNE_TRAJECTORY)
    sol = calibrate(res.calibration_strips(), res.nominal, method=method, estimate="boresight,trajectory_bias",
                    settings=settings).solution
    _check_angles(sol, res.truth.parameters())
    assert sum(n.startswith("trajectory_tilt_") for n in sol.parameters.free_names) > 200


@pytest.mark.slow
@pytest.mark.parametrize("method", ["planes", "vgicp"])
@pytest.mark.parametrize("seed", [3, 4, 5, 6])
def test_airborne_with_30_percent_vegetation_and_the_trajectory_errors_modelled(seed, method):
    """Tree crowns over 30 % of the area: the same accuracy as without them (every angle within
    0.002° and 3σ on four surveys; largest: tie planes seed 5, pitch 0.00127° = 1.8σ; VGICP seed 5,
    pitch 0.00130° = 1.9σ; with piecewise-constant corrections VGICP seed 5 yaw was 0.00184° = 2.5σ,
    0.00207° with single-point VGICP rows). Small tie
    planes (≈ 12 points) fit between the crowns and on roof facets; with 40-point patches only
    ~1 400 tie planes were left and yaw missed by 10 % on seed 4."""
    res = _simulate("airborne", "cross", 0.3, vegetation=0.3, seed=seed)
    settings = StripSettings(threshold_m=1e-3 if method == "vgicp" else 2e-4, trajectory=AIRBORNE_TRAJECTORY)
    result = calibrate(res.calibration_strips(), res.nominal, method=method, estimate="boresight,trajectory_bias",
                       settings=settings)
    _check_angles(result.solution, res.truth.parameters())
    assert result.solution.residuals_after["downweighted_fraction"] > 0.0


def uav_lever_arm_survey():
    """The UAV survey with 5 cm lever-arm errors and 5 mm GNSS noise (see the test below)."""
    cfg = survey_config("uav", seed=3, density=0.2, vegetation=0.0, directions="cross", range_noise_m=0.03,
                        gnss_noise_m=0.005, errors={"lever_arm_x": 0.05, "lever_arm_y": -0.05})
    return simulate_survey(cfg)


@pytest.mark.slow
def test_uav_lever_arm_within_1_cm():
    """Lever-arm errors of 5 cm with the boresight known (calibrated beforehand): x, y within 1 cm.

    A smooth GNSS error shifts a whole line like a lever arm does in opposite lines, so the
    lever arm is only found to the GNSS error's level: this survey has 5 mm (the preset's 2 cm
    gives lever-arm errors of 1–3 cm). At one flying height a pitch error shifts points
    along-track nearly as lever_arm_x does: with the boresight free too the solution says so."""
    res = uav_lever_arm_survey()
    strips = res.calibration_strips()
    truth = res.truth.parameters()
    sol = calibrate(strips, res.nominal, estimate="lever_arm_x,lever_arm_y").solution
    for name in ("lever_arm_x", "lever_arm_y"):
        err = sol.values[name] - truth[name]
        assert abs(err) < 0.01 and abs(err) < 3 * sol.sigma[name], (name, err, sol.sigma[name])
    both = calibrate(strips, res.nominal, estimate="boresight,lever_arm").solution
    assert any(w.startswith("lever_arm_z is determined only through attitude changes") for w in both.warnings)
    assert any("boresight_pitch and lever_arm_x are strongly correlated" in w for w in both.warnings)
    for name in ("lever_arm_x", "lever_arm_y"):
        assert abs(both.values[name] - truth[name]) < 3 * both.sigma[name], name


#: the UAV preset's trajectory errors (2 cm, 0.002°) as the adjustment models them
UAV_TRAJECTORY = TrajectoryModel(block_s=2.0, position_sigma_m=0.02, attitude_sigma_rad=np.radians(0.002),
                                 correlation_s=20.0, attitude_correlation_s=20.0)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["planes", "vgicp"])
@pytest.mark.parametrize("seed", [3, 4, 5])
def test_uav_preset_lever_arm_within_1_cm_with_the_trajectory_errors_modelled(seed, method):
    """The UAV preset as it is (2 cm GNSS noise), 5 cm lever-arm errors, boresight known: with the
    trajectory errors modelled x and y come within 1 cm and 3σ (without: up to 1.9 cm, 3σ+).
    Largest: VGICP seed 5, x 8.5 mm = 1.6σ; tie planes seed 5, x 5.0 mm = 1.0σ (seeds 3–11: one
    miss, VGICP seed 9 y 10.3 mm = 1.8σ). The σ are ≈ 5 mm, so 1 cm is a 2σ goal here: the
    GNSS noise, not the matching, sets the limit."""
    cfg = survey_config("uav", seed=seed, density=0.2, vegetation=0.0, directions="cross", range_noise_m=0.03,
                        errors={"lever_arm_x": 0.05, "lever_arm_y": -0.05})
    res = simulate_survey(cfg)
    settings = StripSettings(threshold_m=1e-3 if method == "vgicp" else 2e-4, trajectory=UAV_TRAJECTORY)
    sol = calibrate(res.calibration_strips(), res.nominal, method=method, estimate="lever_arm_x,lever_arm_y,trajectory_bias",
                    settings=settings).solution
    truth = res.truth.parameters()
    for name in ("lever_arm_x", "lever_arm_y"):
        err = sol.values[name] - truth[name]
        assert abs(err) < 0.01 and abs(err) < 3 * sol.sigma[name], (name, err, sol.sigma[name])


@pytest.mark.slow
def test_same_direction_strips_warn_and_report_correlations():
    res = _simulate("airborne", "same", 0.3)
    sol = calibrate(res.calibration_strips(), res.nominal).solution
    assert any("boresight_pitch poorly determined: all overlapping strips are parallel and flown the same way" in w
               for w in sol.warnings)
    doc = sol.to_dict()
    assert doc["correlation"]["names"] == list(ANGLES)
    assert len(doc["correlation"]["matrix"]) == 3
    # pitch is the undetermined one: its σ dwarfs roll's (its error may exceed even that σ:
    # with nothing to determine it, systematic effects set its value)
    assert sol.sigma["boresight_pitch"] > 5 * sol.sigma["boresight_roll"]
    truth = res.truth.parameters()
    assert abs(sol.values["boresight_roll"] - truth["boresight_roll"]) < 3 * sol.sigma["boresight_roll"]


@pytest.mark.slow
def test_demo_step_adds_the_strip_section(tmp_path):
    from calidar.demo.boresight import boresight_step
    from calidar.demo.survey import simulation_step
    from calidar.report import Report

    report = Report("demo")
    simulation_step(report, tmp_path, 0)
    boresight_step(report, tmp_path, 0)
    sec = report.sections[-1]
    assert sec.title == "Boresight and lever arm from tie planes (calidar boresight)"
    html = sec.html("s1")
    assert "lever_arm_x" in html and "truth" in html and "RMSDz before" in html
